"""OpenSim motion files (.mot / .sto): coordinate values per frame."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._typing import FloatArray, PathLike
from ..errors import SceneError
from ..mesh import atomic_path

__all__ = ["Motion", "random_motion", "read_motion", "write_motion"]


@dataclass(frozen=True)
class Motion:
    """Coordinate values per frame, as stored in an OpenSim motion file.

    Attributes
    ----------
    path : pathlib.Path
        The file read.
    time : (k,) float64 array
        Time of each frame (s).
    columns : dict of str to (k,) float64 array
        Values per column label, in the file's units.
    in_degrees : bool
        Whether rotational values are in degrees (the header's ``inDegrees``).
    degrees_declared : bool
        Whether the header has an ``inDegrees`` line at all.
    repeated : frozenset of str
        Column labels that occur more than once (not in `columns`).
    """

    path: Path
    time: FloatArray
    columns: dict[str, FloatArray]
    in_degrees: bool
    degrees_declared: bool = True
    repeated: frozenset[str] = frozenset()

    @property
    def n_frames(self) -> int:
        """Number of frames (rows)."""
        return len(self.time)


def read_motion(path: PathLike) -> Motion:
    """Read an OpenSim ``.mot`` or ``.sto`` file (header up to ``endheader``, then a table).

    Parameters
    ----------
    path : str or os.PathLike
        Tab- or space-separated table with a ``time`` column.

    Returns
    -------
    Motion

    Raises
    ------
    SceneError
        If the file is missing, has no ``endheader``, no (or two) ``time`` columns, rows
        of the wrong length, non-numeric or non-finite values, or times that
        do not increase.

    Notes
    -----
    Angles are in degrees when the header says ``inDegrees=yes`` (OpenSim's
    convention for IK results and the LHDL sweeps). For a file without that
    line (old SIMM headers) `degrees_declared` is False and the scene decides
    (see `musclewrap.scene.angle_unit`).
    """
    p = Path(path)
    if not p.is_file():
        raise SceneError(f"{p}: no such motion file")
    try:
        text = p.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise SceneError(f"{p}: cannot read the motion file ({exc.strerror})") from None
    lines = text.splitlines()
    end = next((i for i, ln in enumerate(lines) if ln.strip().lower() == "endheader"), None)
    if end is None:
        raise SceneError(f"{p}: not an OpenSim motion file (no 'endheader' line)")
    in_degrees, declared = False, False
    for ln in lines[:end]:
        key, _, value = ln.partition("=")
        if key.strip().lower() == "indegrees":
            in_degrees = value.strip().lower() in ("yes", "true", "1")
            declared = True
    body = [ln for ln in lines[end + 1 :] if ln.strip()]
    if not body:
        raise SceneError(f"{p}: no column labels after 'endheader'")
    labels = body[0].split("\t") if "\t" in body[0] else body[0].split()
    labels = [lb.strip() for lb in labels]
    if "time" not in labels:
        raise SceneError(f"{p}: no 'time' column (labels: {', '.join(labels[:8])}...)")
    if labels.count("time") > 1:
        raise SceneError(f"{p}: more than one 'time' column")
    rows = []
    for k, ln in enumerate(body[1:], start=1):
        fields = ln.split()
        if len(fields) != len(labels):
            raise SceneError(
                f"{p}: data row {k} has {len(fields)} values, the header has {len(labels)} labels"
            )
        try:
            rows.append([float(v) for v in fields])
        except ValueError:
            raise SceneError(f"{p}: data row {k} has a non-numeric value") from None
    if not rows:
        raise SceneError(f"{p}: the motion has no frames")
    table = np.array(rows, dtype=np.float64)
    if not np.isfinite(table).all():
        r = int(np.argwhere(~np.isfinite(table))[0, 0]) + 1
        raise SceneError(f"{p}: data row {r} has a NaN or infinite value")
    time = table[:, labels.index("time")]
    if len(time) > 1 and not (np.diff(time) > 0).all():
        raise SceneError(f"{p}: time values do not increase")
    # Columns whose label repeats (e.g. ground forces of both feet) are ambiguous: kept aside
    # and refused only if a scene asks for one of them.
    repeated = frozenset(lb for lb in labels if labels.count(lb) > 1)
    cols = {
        lb: table[:, i].copy() for i, lb in enumerate(labels) if lb != "time" and lb not in repeated
    }
    return Motion(
        path=p,
        time=time.copy(),
        columns=cols,
        in_degrees=in_degrees,
        degrees_declared=declared,
        repeated=repeated,
    )


def write_motion(
    path: PathLike, time: FloatArray, columns: dict[str, FloatArray], *, in_degrees: bool = True
) -> Path:
    """Write coordinate values per frame as an OpenSim ``.mot`` file (`read_motion` reads it).

    Every value is written to the last bit: read back, the motion is the same floats.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write (whole or not at all).
    time : (k,) float array
        Increasing times (s).
    columns : dict of str to (k,) float array
        Values per coordinate (degrees for rotations when ``in_degrees``).
    in_degrees : bool, optional
        The header's ``inDegrees``.

    Returns
    -------
    pathlib.Path
    """
    t = np.asarray(time, dtype=np.float64)
    if t.ndim != 1 or not len(t) or (len(t) > 1 and not (np.diff(t) > 0).all()):
        raise ValueError("time must be a non-empty increasing sequence")
    cols = {k: np.asarray(v, dtype=np.float64) for k, v in columns.items()}
    for k, v in cols.items():
        if v.shape != t.shape or not np.isfinite(v).all():
            raise ValueError(f"column {k!r} must have one finite value per time")
    head = [
        "Coordinates", "version=1", f"nRows={len(t)}", f"nColumns={len(cols) + 1}",
        f"inDegrees={'yes' if in_degrees else 'no'}", "endheader",
        "\t".join(["time", *cols]),
    ]  # fmt: skip
    table = np.column_stack([t, *cols.values()])
    # each value's shortest text that reads back as the same float: a pose written and run
    # is the pose asked for (ten decimals moved a viewer's pose by 5e-11 deg, and where the
    # contact turns on a threshold there the run's iliacus lay 0.04 mm from the viewer's)
    body = ["\t".join(repr(float(x)) for x in row) for row in table]
    p = Path(path)
    with atomic_path(p) as tmp:
        Path(tmp).write_text("\n".join(head + body) + "\n", encoding="utf-8")
    return p


def random_motion(
    ranges: dict[str, tuple[float, float]],
    *,
    seconds: float = 4.0,
    rate: float = 50.0,
    knots_per_second: float = 1.5,
    seed: int = 0,
) -> tuple[FloatArray, dict[str, FloatArray]]:
    """A seeded random smooth motion inside given ranges: for trying a scene on motions of its own.

    Each coordinate passes through values drawn uniformly in its range at
    ``knots_per_second`` evenly spaced times, joined by monotone cubic (PCHIP)
    interpolation: smooth (continuous first derivative), never outside the
    range, and as fast as the knots make it (a swing over the whole range in
    ``1 / knots_per_second`` seconds at most). The first knot of every coordinate
    is drawn like the others (a motion need not start at the rest pose).

    Parameters
    ----------
    ranges : dict of str to (low, high)
        Each coordinate's range (e.g. `OpenSimModel.coordinate_range`, in the
        units the motion is written in).
    seconds, rate : float, optional
        Duration (s) and frames per second.
    knots_per_second : float, optional
        How often a new value is drawn.
    seed : int, optional
        The same seed gives the same motion.

    Returns
    -------
    time : (k,) float64 array
    columns : dict of str to (k,) float64 array
    """
    from scipy.interpolate import PchipInterpolator

    if seconds <= 0 or rate <= 0 or knots_per_second <= 0:
        raise ValueError("seconds, rate and knots_per_second must be positive")
    rng = np.random.default_rng(seed)
    n = int(round(seconds * rate)) + 1
    time = np.arange(n) / rate
    k = max(int(np.ceil(seconds * knots_per_second)) + 1, 2)
    knots = np.linspace(0.0, time[-1], k)
    columns = {}
    for name, (lo, hi) in ranges.items():
        if not hi >= lo:
            raise ValueError(f"range of {name!r} is empty: ({lo}, {hi})")
        values = rng.uniform(lo, hi, size=k)
        columns[name] = np.clip(PchipInterpolator(knots, values)(time), lo, hi)
    return time, columns
