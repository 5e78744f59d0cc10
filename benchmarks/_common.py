"""Helpers the benchmark scripts share (not part of the installed package).

A script in ``benchmarks/GROUP/`` imports them with ``benchmarks/`` on its path::

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from _common import timed_run
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

__all__ = ["most", "timed_run"]


def timed_run(scene: str, out: Path, extra: list[str], checkout: Path | None = None) -> float:
    """Wall seconds of ``musclewrap run SCENE -o OUT *extra`` in a new process (must succeed).

    ``checkout``: another checkout's package runs it (its ``src`` first on ``PYTHONPATH``).
    """
    cmd = [sys.executable, "-m", "musclewrap.cli", "run", scene, "-o", str(out), *extra]
    env = None if checkout is None else {**os.environ, "PYTHONPATH": str(checkout / "src")}
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True, env=env)
    return time.perf_counter() - t0


def most(rows: list[dict[str, str]], key: str) -> float:
    """The largest of a report.csv column over ``rows`` (nan where the column is empty)."""
    vals = [float(x[key]) for x in rows if x.get(key) not in (None, "", "nan")]
    return max(vals) if vals else float("nan")
