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

__all__ = ["most", "negated_motion", "timed_run"]


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


def negated_motion(motion: str | Path, negate: list[str], folder: Path) -> Path:
    """The motion file with the columns ``negate`` negated, written into ``folder``.

    For a motion recorded on a model whose sign for those coordinates is the other
    (OpenCap's knee_angle_r is flexion positive, gait2392's negative).
    """
    import numpy as np

    from musclewrap.scene import read_motion, write_motion

    mot = read_motion(motion)
    cols = {k: (-v if k in negate else v) for k, v in mot.columns.items()}
    path = Path(folder) / Path(motion).name
    # a header without inDegrees (OpenSim's gait2392 walk) is read by its values
    # (`musclewrap.scene`: over 2 pi, degrees): written with the same reading
    deg = (
        mot.in_degrees
        if mot.degrees_declared
        else bool(max(float(np.abs(v).max()) for v in cols.values()) > 2 * np.pi)
    )
    write_motion(path, mot.time, cols, in_degrees=deg)
    return path
