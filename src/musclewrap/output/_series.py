"""Per-frame outputs: ParaView collections, CSV reports and plots."""

from __future__ import annotations

import csv
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np
import numpy.typing as npt

from .._typing import PathLike
from ..constants import UNITS
from ..mesh import atomic_path

__all__ = [
    "plot_convergence",
    "plot_moment_arms",
    "plot_volume_error",
    "write_csv",
    "write_pvd",
]


def write_pvd(path: PathLike, entries: Sequence[tuple[float, str]]) -> Path:
    """Write a ParaView ``.pvd`` collection (one dataset per time value).

    Parameters
    ----------
    path : str or os.PathLike
        Destination ``.pvd`` file.
    entries : sequence of (float, str)
        Time value and file name relative to the collection's folder. Several
        files may share a time value (they become parts of that time step).

    Returns
    -------
    pathlib.Path
    """
    parts: dict[float, int] = {}
    lines = ['<?xml version="1.0"?>', '<VTKFile type="Collection" version="0.1">', "  <Collection>"]
    for t, name in entries:
        part = parts.get(t, 0)
        parts[t] = part + 1
        lines.append(
            f'    <DataSet timestep={quoteattr(repr(float(t)))} part="{part}" file={quoteattr(name)}/>'
        )
    lines += ["  </Collection>", "</VTKFile>", ""]
    p = Path(path)
    with atomic_path(p) as tmp:
        tmp.write_text("\n".join(lines), encoding="utf-8")
    return p


def write_csv(path: PathLike, rows: Sequence[Mapping[str, object]], fields: Sequence[str]) -> Path:
    """Write dict rows as CSV with the given column order (atomically)."""
    p = Path(path)
    with atomic_path(p) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=list(fields), extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow(r)
    return p


def _log_axis(ax: Any) -> None:
    """Log y axis with at most eight labelled decades and no minor ticks.

    Histories span up to 30 decades; matplotlib's default minor ticks on such
    an axis made one figure take seconds to draw.
    """
    from matplotlib.ticker import LogLocator, NullLocator

    ax.yaxis.set_major_locator(LogLocator(numticks=8))
    ax.yaxis.set_minor_locator(NullLocator())
    ax.grid(True, which="major", alpha=0.3)


def _save_png(fig: Any, path: PathLike, *, tight: bool = True) -> Path:
    """Lay out (``tight``), write atomically and close a matplotlib figure."""
    import matplotlib.pyplot as plt

    if tight:
        fig.tight_layout()
    p = Path(path)
    with atomic_path(p) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return p


def _styles(n: int) -> list[tuple[Any, str]]:
    """A colour and a marker for each of ``n`` muscles, all told apart.

    Up to 10: matplotlib's own cycle (C0-C9). Up to 20: its ten hues dark, then the same
    ten light (``tab20``); beyond, the twenty again with other markers.
    """
    if n <= 10:
        return [(f"C{i}", ".") for i in range(n)]
    import matplotlib

    tab20 = matplotlib.colormaps["tab20"].colors
    marks = (".", "x", "+", "^")
    return [(tab20[2 * (i % 10) + (i // 10) % 2], marks[(i // 20) % 4]) for i in range(n)]


#: the legend's rows that fit beside a panel, per inch of its height (fontsize "small")
_LEGEND_ROWS_PER_INCH = 5.5
#: the width a legend's column takes beside the panels, inches (labels of about 24 letters)
_LEGEND_COLUMN_INCHES = 2.3


def _legend_columns(entries: int, height: float) -> int:
    """How many columns a legend of ``entries`` rows needs beside panels ``height`` inches tall."""
    rows = max(1, int(height * _LEGEND_ROWS_PER_INCH))
    return -(-entries // rows)


def _legend(ax: Any, columns: int, ncol: int) -> None:
    """The legend: beside the panels in ``columns`` columns, or over them in ``ncol``.

    ``columns`` from `_legend_columns`; 0 where no room is set aside beside them.
    """
    if columns:
        ax.legend(fontsize="small", ncol=columns, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                  borderaxespad=0.0)  # fmt: skip
    else:
        ax.legend(fontsize="small", ncol=ncol)


def _wrapped(title: str, width: float) -> str:
    """``title`` broken into lines that fit a figure ``width`` inches wide (fontsize "medium")."""
    import textwrap

    return "\n".join(textwrap.wrap(title, max(20, int(width * 11))))


def plot_volume_error(
    path: PathLike,
    series: Mapping[str, tuple[Sequence[float], Sequence[float]]],
    *,
    title: str,
    markers: Mapping[str, tuple[Sequence[float], Sequence[float]]] | None = None,
    line_label: str | None = None,
    marker_label: str | None = None,
) -> Path:
    """Plot |relative volume error| per frame on a log scale, one curve per label.

    Parameters
    ----------
    path : str or os.PathLike
        Destination PNG.
    series : mapping of str to (frames, errors)
        Curves to draw (a muscle's each).
    title : str
        Plot title.
    markers : mapping of str to (frames, errors), optional
        Values on a few frames only (e.g. the paper's iteration), drawn as open
        squares without lines, in the colour of the curve of the same label.
    line_label, marker_label : str, optional
        What the curves and the squares are (e.g. ``"sqp"`` and ``"paper, eq. 11"``),
        said once each in the legend.

    Returns
    -------
    pathlib.Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    markers = markers or {}
    labels = list(series) + [m for m in markers if m not in series]
    style = dict(zip(labels, _styles(len(labels)), strict=True))
    entries = len(labels) + bool(markers) + bool(line_label) + 1  # and the target's line
    # many muscles: the legend beside the panel, not over it
    columns = _legend_columns(entries, 4.0 - 0.95) if entries > 8 else 0
    width = 7.0 + columns * _LEGEND_COLUMN_INCHES
    title = _wrapped(title, 7.0)
    top = 0.4 + 0.2 * title.count("\n")
    height = 3.6 + top
    fig, ax = plt.subplots(figsize=(width, height), dpi=110)
    # fixed margins in inches: tight_layout took a fifth of the figure's time (0.13 s against 0.10)
    fig.subplots_adjust(
        left=0.95 / width, right=1 - (0.15 + columns * _LEGEND_COLUMN_INCHES) / width,
        bottom=0.55 / height, top=1 - top / height,
    )  # fmt: skip
    for label, (x, y) in series.items():
        colour, mark = style[label]
        ax.semilogy(
            list(x), [max(abs(v), 1e-17) for v in y], marker=mark, color=colour, label=label
        )
    for label, (x, y) in markers.items():
        colour, _ = style[label]
        ax.semilogy(
            list(x), [max(abs(v), 1e-17) for v in y], ls="none", marker="s", mfc="none",
            color=colour, label=None if label in series else label,
        )  # fmt: skip
    if line_label:
        ax.semilogy([], [], color="0.4", marker=".", label=f"lines: {line_label}")
    if markers and marker_label:
        ax.semilogy([], [], ls="none", marker="s", mfc="none", color="0.4",
                    label=f"squares: {marker_label}")  # fmt: skip
    ax.axhline(1e-9, color="k", ls="--", lw=0.8, label="target 1e-9")
    ax.set_xlabel("frame")
    ax.set_ylabel("|relative volume error|")
    ax.set_title(title)
    _log_axis(ax)
    _legend(ax, columns, 2 if entries > 4 else 1)
    return _save_png(fig, path, tight=False)


#: the most muscles (panel pairs) in a row of the convergence plot
_CONVERGENCE_COLUMNS = 6


def plot_convergence(
    path: PathLike,
    runs: Mapping[str, tuple[int | None, Mapping[str, Sequence[tuple[float, float]]]]],
    *,
    title: str,
) -> Path:
    """Energy and |volume error| against iteration, one panel pair per muscle (paper's Fig. 6).

    The pairs side by side, at most six a row (rows of pairs below).

    Parameters
    ----------
    path : str or os.PathLike
        Destination PNG.
    runs : mapping of str to (frame, {method: [(energy, volume error), ...]})
        Iteration histories per muscle and method (e.g. ``"exact"`` and ``"paper"``).
    title : str
        Figure title.

    Returns
    -------
    pathlib.Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(runs)
    # a panel pair per muscle, at most six pairs a row: 18 muscles in three rows, not a strip
    # 6,400 pixels wide
    cols = min(n, _CONVERGENCE_COLUMNS)
    rows = -(-n // cols)
    width, height = 3.2 * cols + 1, 5.4 * rows + 0.1 - 0.4 * (rows - 1)
    fig = plt.figure(figsize=(width, height), dpi=110)
    # fixed margins in inches (the labels, the panels' titles and the figure's): tight_layout
    # took half of this figure's time, 1.1 of 2.3 s with 18 muscles' panels; a thin empty
    # row between rows of pairs for the pair below's titles
    grid = fig.add_gridspec(
        3 * rows - 1, cols, height_ratios=[1.0, 1.0, 0.02] * (rows - 1) + [1.0, 1.0],
        left=0.9 / width, right=1 - 0.15 / width, bottom=0.55 / height, top=1 - 0.75 / height,
        wspace=0.35, hspace=0.3,
    )  # fmt: skip
    axes = np.empty((2 * rows, cols), dtype=object)
    for j in range(n):
        r, c = divmod(j, cols)
        axes[2 * r, c] = fig.add_subplot(grid[3 * r, c])
        axes[2 * r + 1, c] = fig.add_subplot(grid[3 * r + 1, c])
    for j, (muscle, (frame, hist)) in enumerate(runs.items()):
        top, bottom = axes[2 * (j // cols), j % cols], axes[2 * (j // cols) + 1, j % cols]
        for method, h in hist.items():
            if not h:
                continue
            it = range(1, len(h) + 1)
            top.semilogy(it, [max(e, 1e-30) for e, _ in h], marker=".", label=method)
            bottom.semilogy(it, [max(abs(v), 1e-17) for _, v in h], marker=".", label=method)
        top.set_title(f"{muscle}, frame {frame}", fontsize="small")
        bottom.axhline(1e-9, color="k", ls="--", lw=0.8)
        bottom.set_xlabel("iteration")
        for ax in (top, bottom):
            _log_axis(ax)
    for r in range(rows):
        axes[2 * r, 0].set_ylabel("energy")
        axes[2 * r + 1, 0].set_ylabel("|relative volume error|")
    axes[0, 0].legend(fontsize="small")
    fig.suptitle(title, fontsize="medium")
    return _save_png(fig, path, tight=False)


def plot_penetration(
    path: PathLike,
    after: Mapping[str, tuple[Sequence[float], Sequence[float]]],
    *,
    title: str,
    before: Mapping[str, tuple[Sequence[float], Sequence[float]]] | None = None,
    bone_inside: Mapping[str, tuple[Sequence[float], Sequence[float]]] | None = None,
    line_inside: Mapping[str, tuple[Sequence[float], Sequence[float]]] | None = None,
    limit: float | None = None,
    unit: str = "mm",
    muscle_inside: Mapping[str, tuple[Sequence[float], Sequence[float]]] | None = None,
) -> Path:
    """Plot per frame how deep muscles and bones lie in each other, one colour per muscle.

    Above, the deepest muscle vertex inside a bone; below (with ``bone_inside``),
    the deepest bone vertex inside the muscle; last (with ``muscle_inside``), the
    deepest vertex of the muscle inside another muscle.

    Parameters
    ----------
    path : str or os.PathLike
        Destination PNG.
    after : mapping of str to (frames, depths)
        Deepest muscle vertex inside a bone per frame in the written meshes (after
        the contact finish).
    title : str
        Plot title.
    before : mapping of str to (frames, depths), optional
        The same before the contact finish (what the solve alone gave), drawn
        thin and dashed in the muscle's colour.
    bone_inside : mapping of str to (frames, depths), optional
        Deepest bone vertex inside the muscle per frame (a second panel).
    line_inside : mapping of str to (frames, depths), optional
        How deep the muscle's action line runs inside a bone, drawn dotted in the
        first panel where it is not zero (there the muscle cannot follow it).
    limit : float, optional
        A horizontal line: the depth a target allows.
    unit : str, optional
        Mesh unit, for the axis label.
    muscle_inside : mapping of str to (frames, depths), optional
        Deepest vertex of the muscle inside another muscle per frame (a last panel).

    Returns
    -------
    pathlib.Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = 1 + bool(bone_inside) + bool(muscle_inside)
    labels = list(dict.fromkeys([*after, *(bone_inside or {}), *(muscle_inside or {})]))
    style = dict(zip(labels, _styles(len(labels)), strict=True))
    lines_shown = bool(line_inside) and any(
        any(v > 0 for v in ly) for lab, (_, ly) in line_inside.items() if lab in after
    )
    entries = len(after) + bool(before) + lines_shown + (limit is not None)
    # many muscles: the legend beside the panels, not over them
    columns = _legend_columns(entries, 3.2 * panels - 0.5) if entries > 8 else 0
    width = 7.0 + columns * _LEGEND_COLUMN_INCHES
    title = _wrapped(title, 7.0)
    top = 0.4 + 0.2 * title.count("\n")
    height = 3.2 * panels + 0.55 + top
    fig, axes = plt.subplots(
        panels, 1, figsize=(width, height), dpi=110, sharex=True, squeeze=False
    )
    # fixed margins in inches: tight_layout took a fifth of the figure's time (0.36 s against 0.29)
    fig.subplots_adjust(
        left=0.85 / width, right=1 - (0.15 + columns * _LEGEND_COLUMN_INCHES) / width,
        bottom=0.55 / height, top=1 - top / height, hspace=0.1,
    )  # fmt: skip
    ax = axes[0, 0]
    for label, (x, y) in after.items():
        colour, mark = style[label]
        ax.plot(list(x), list(y), marker=mark, ms=3, color=colour, label=label)
        if before and label in before:
            bx, by = before[label]
            ax.plot(list(bx), list(by), ls="--", lw=0.8, color=colour, alpha=0.7)
        if line_inside and label in line_inside:
            lx, ly = line_inside[label]
            if any(v > 0 for v in ly):
                ax.plot(list(lx), list(ly), ls=":", lw=1.0, color=colour, alpha=0.9)
    if before:
        ax.plot([], [], ls="--", lw=0.8, color="0.4", label="before contact (dashed)")
    if lines_shown:
        ax.plot([], [], ls=":", lw=1.0, color="0.4", label="action line in a bone (dotted)")
    if limit is not None:
        ax.axhline(limit, color="k", ls=":", lw=0.8, label=f"target {limit:g} {unit}")
    ax.set_ylabel(f"muscle vertex in bone ({unit})")
    ax.set_ylim(bottom=0.0)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    _legend(ax, columns, 2 if len(after) > 4 else 1)
    if bone_inside:
        ax2 = axes[1, 0]
        for label, (x, y) in bone_inside.items():
            colour, mark = style[label]
            ax2.plot(list(x), list(y), marker=mark, ms=3, color=colour, label=label)
        ax2.set_ylabel(f"bone vertex in muscle ({unit})")
        ax2.set_ylim(bottom=0.0)
        ax2.grid(True, alpha=0.3)
    if muscle_inside:
        ax3 = axes[-1, 0]
        for label, (x, y) in muscle_inside.items():
            colour, mark = style[label]
            ax3.plot(list(x), list(y), marker=mark, ms=3, color=colour, label=label)
        ax3.set_ylabel(f"vertex in another muscle ({unit})")
        ax3.set_ylim(bottom=0.0)
        ax3.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("frame")
    return _save_png(fig, path, tight=False)


def plot_moment_arms(
    path: PathLike,
    rows: Sequence[Mapping[str, Any]],
    coordinates: Sequence[str],
    per_q: npt.ArrayLike,
    *,
    swept: str | None = None,
    swept_values: Mapping[int, float] | None = None,
    swept_unit: str = "deg",
    unit: str = "mm",
) -> Path:
    """Per muscle (row) and coordinate (column): the fibres' range and mean over the motion.

    Beside them the action line's moment arm (by differences of its length) and
    OpenSim's ``computeMomentArm``. Against the swept coordinate (``swept_values``:
    frame to its value in ``swept_unit``) where the motion sweeps one, against time
    otherwise; lengths in mm (from the meshes' ``unit``).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    per_q = np.asarray(per_q, dtype=np.float64)
    to_mm = UNITS[unit] * 1e3
    names = list(dict.fromkeys(r["muscle"] for r in rows))
    nr, nc = max(1, len(names)), max(1, len(coordinates))
    fig, axes = plt.subplots(
        nr, nc, figsize=(3.2 * nc + 0.8, 2.3 * nr + 0.6), squeeze=False, sharex=True
    )
    # fixed margins: tight_layout took half of this figure's time
    fig.subplots_adjust(left=0.09, right=0.98, bottom=0.07, top=0.93, wspace=0.25, hspace=0.15)
    against = swept is not None and swept_values is not None
    for i, name in enumerate(names):
        for j, c in enumerate(coordinates):
            ax = axes[i, j]
            sel = [r for r in rows if r["muscle"] == name and r["coordinate"] == c]
            x = np.array(
                [swept_values[int(r["frame"])] if against else r["time"] for r in sel],  # type: ignore[index]
                dtype=np.float64,
            )
            # a length per radian is mm; a translational coordinate's is without units
            f = to_mm if per_q[j] == 1.0 else 1.0
            lo, mean, hi, line, osim = (
                f * np.array([r[key] for r in sel], dtype=np.float64)
                for key in (
                    "fibre_min",
                    "fibre_mean",
                    "fibre_max",
                    "line_moment_arm",
                    "opensim_moment_arm",
                )
            )
            ax.fill_between(x, lo, hi, color="tab:red", alpha=0.25, lw=0, label="fibres (range)")
            ax.plot(x, mean, color="tab:red", lw=1.5, label="fibres (mean)")
            ax.plot(x, osim, color="tab:blue", lw=3.0, alpha=0.45, label="OpenSim")
            ax.plot(x, line, color="black", lw=1.0, ls="--", label="action line")
            ax.axhline(0.0, color="0.6", lw=0.5)
            ax.grid(True, alpha=0.3)
            if i == 0:
                ax.set_title(f"about {c}", fontsize=9)
            if j == 0:
                what = "moment arm (mm)" if per_q[j] == 1.0 else "moment arm (-)"
                ax.set_ylabel(f"{name}\n{what}", fontsize=8)
            if i == nr - 1:
                ax.set_xlabel(f"{swept} ({swept_unit})" if against else "time (s)", fontsize=8)
            ax.tick_params(labelsize=7)
    axes[0, 0].legend(fontsize=6, loc="best")
    fig.suptitle(
        "moment arms -dL/dq" + (f" through the {swept} sweep" if against else " over the motion"),
        fontsize=9,
    )
    return _save_png(fig, path, tight=False)
