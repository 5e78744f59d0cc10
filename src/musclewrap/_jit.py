"""Whether the compiled kernels are in Numba's cache yet (a first run compiles them)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TextIO

#: what compiling the kernels of a pose took on a first run (BENCHMARKS.md, issue 15)
FIRST_RUN_SECONDS = "10-15 s"


def kernels_cached() -> bool:
    """True when the solver's kernels were compiled and cached by an earlier run.

    Looks for Numba's index of the main solver kernel next to its source (newer
    than the source: Numba recompiles a kernel whose source changed). Anything
    unexpected about Numba's cache counts as cached: then nothing is said.
    """
    try:
        from .solver._proxy import _plain_iterations

        index = Path(_plain_iterations._cache._cache_file._index_path)
        source = Path(_plain_iterations.py_func.__code__.co_filename)
        return index.is_file() and index.stat().st_mtime >= source.stat().st_mtime
    except (AttributeError, OSError):
        return True


def say_if_compiling(stream: TextIO | None = None) -> bool:
    """Say once, before the first pose, that the kernels are compiled now; True if so."""
    if kernels_cached():
        return False
    print(
        f"compiling kernels, once: about {FIRST_RUN_SECONDS} on this first run "
        "(kept in Numba's cache; later runs start at once)",
        file=stream or sys.stderr,
        flush=True,
    )
    return True
