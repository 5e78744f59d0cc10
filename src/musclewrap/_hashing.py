"""SHA-256 hashes of inputs and arrays: cache keys and integrity checks of stored arrays."""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Mapping
from pathlib import Path

import numpy as np

__all__ = ["code_digest", "digest", "digest_arrays"]


def digest(*parts: bytes | str | np.ndarray) -> str:
    """SHA-256 (hex) of byte strings, strings and arrays (their raw bytes) in order."""
    h = hashlib.sha256()
    for p in parts:
        if isinstance(p, np.ndarray):
            # the array's own buffer (the same bytes as ``tobytes()``, without the copy)
            h.update(np.ascontiguousarray(p).data)
        elif isinstance(p, str):
            h.update(p.encode())
        else:
            h.update(p)
        h.update(b"|")
    return h.hexdigest()


def digest_arrays(arrays: Mapping[str, np.ndarray]) -> str:
    """SHA-256 (hex) of named arrays: names, dtypes, shapes and bytes, in name order.

    What a stored preparation (`musclewrap.Muscle.save`) and a cache file keep to
    find damage.
    """
    h = hashlib.sha256()
    for k in sorted(arrays):
        a = np.ascontiguousarray(arrays[k])
        h.update(k.encode())
        h.update(str(a.dtype).encode() + str(a.shape).encode())
        h.update(a.data)  # the same bytes as a.tobytes(), not copied
    return h.hexdigest()


@functools.cache
def code_digest() -> str:
    """SHA-256 (hex) of this package's own source files: the code, beyond its version number.

    Its Python files by their paths inside the package, in path order: what a run's
    key holds, so that a run interrupted under one code is not resumed under another
    of the same version (a checkout between releases).
    """
    root = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(path.relative_to(root).as_posix().encode() + b"|")
        h.update(path.read_bytes())
        h.update(b"|")
    return h.hexdigest()
