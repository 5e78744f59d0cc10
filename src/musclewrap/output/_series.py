"""Per-frame outputs: ParaView collections, CSV reports and plots."""

from __future__ import annotations

import csv
from collections.abc import Mapping, Sequence
from pathlib import Path
from xml.sax.saxutils import quoteattr

from .._typing import PathLike
from ..mesh import atomic_path

__all__ = ["plot_volume_error", "write_csv", "write_pvd"]


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


def plot_volume_error(
    path: PathLike, series: Mapping[str, tuple[Sequence[float], Sequence[float]]], *, title: str
) -> Path:
    """Plot |relative volume error| per frame on a log scale, one curve per label.

    Parameters
    ----------
    path : str or os.PathLike
        Destination PNG.
    series : mapping of str to (frames, errors)
        Curves to draw.
    title : str
        Plot title.

    Returns
    -------
    pathlib.Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4), dpi=110)
    for label, (x, y) in series.items():
        ax.semilogy(list(x), [max(abs(v), 1e-17) for v in y], marker=".", label=label)
    ax.axhline(1e-9, color="k", ls="--", lw=0.8, label="target 1e-9")
    ax.set_xlabel("frame")
    ax.set_ylabel("|relative volume error|")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    p = Path(path)
    with atomic_path(p) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return p
