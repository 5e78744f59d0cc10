"""A finished run's series (``scene.pvd``), frame by frame, for the viewer's playback."""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._typing import FloatArray, IntArray
from ..output import frame_view, label_files, muscles_box

__all__ = ["Series", "read_polydata"]


def read_polydata(path: Path) -> dict[str, np.ndarray]:
    """A VTP file's points, triangles, line segments and point arrays (as numpy)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

    if not path.is_file():
        raise FileNotFoundError(f"{path}: a file the series names is missing")
    r = vtkXMLPolyDataReader()
    r.SetFileName(str(path))
    r.Update()
    pd = r.GetOutput()
    if pd is None or pd.GetPoints() is None:
        raise ValueError(f"{path}: not a readable VTK PolyData file")
    out: dict[str, np.ndarray] = {
        "points": vtk_to_numpy(pd.GetPoints().GetData()).astype(np.float64)
    }
    for kind, cells in (("polys", pd.GetPolys()), ("lines", pd.GetLines())):
        if cells.GetNumberOfCells():
            off = vtk_to_numpy(cells.GetOffsetsArray())
            con = vtk_to_numpy(cells.GetConnectivityArray())
            out[kind + "_offsets"], out[kind] = off.astype(np.int64), con.astype(np.int64)
    pdata = pd.GetPointData()
    for i in range(pdata.GetNumberOfArrays()):
        a = pdata.GetArray(i)
        if a is not None and a.GetName():
            out["point:" + a.GetName()] = vtk_to_numpy(a)
    return out


@dataclass
class Series:
    """A run's ``scene.pvd``: per time step, its muscles', bones', lines' and fibres' files.

    ``parts[name]`` is each part's kind (``muscle``, ``bone``, ``lines``, ``fibres``);
    ``files[k][name]`` the file of part ``name`` at step ``k``.
    """

    folder: Path
    times: FloatArray
    files: list[dict[str, Path]]
    parts: dict[str, str]
    _kept: OrderedDict[tuple[int, str], dict[str, np.ndarray]] = field(
        default_factory=OrderedDict, repr=False
    )

    @classmethod
    def open(cls, folder: str | os.PathLike[str]) -> Series:
        """Read ``folder/scene.pvd`` (a run's output folder)."""
        folder = Path(folder)
        pvd = folder / "scene.pvd"
        if not pvd.is_file():
            raise FileNotFoundError(
                f"{folder}: no scene.pvd (give a scene .toml, or the output folder of a run)"
            )
        try:
            root = ET.parse(pvd).getroot()
        except ET.ParseError as exc:
            raise ValueError(f"{pvd}: not a ParaView collection ({exc})") from None
        steps: dict[float, dict[str, Path]] = {}
        parts: dict[str, str] = {}
        for ds in root.iter("DataSet"):
            try:
                t = float(ds.attrib["timestep"])
                name = ds.attrib["file"]
            except (KeyError, ValueError):
                raise ValueError(f"{pvd}: a DataSet without a timestep or file") from None
            rel = Path(name)
            stem = rel.stem
            owner = rel.parts[0] if len(rel.parts) > 1 else stem
            if "_lines_" in stem:
                key, kind = owner + " lines", "lines"
            elif "_fibres_" in stem:
                key, kind = owner + " fibres", "fibres"
            else:
                key, kind = owner, "unknown"
            parts.setdefault(key, kind)
            steps.setdefault(t, {})[key] = folder / rel
        if not steps:
            raise ValueError(f"{pvd}: the collection names no files")
        times = np.array(sorted(steps))
        files = [steps[t] for t in times.tolist()]
        s = cls(folder, times, files, parts)
        # a muscle's file has its area stretch; a bone's has none
        for key, kind in list(parts.items()):
            if kind == "unknown":
                first = next(f[key] for f in files if key in f)
                s.parts[key] = "muscle" if "point:area_stretch" in read_polydata(first) else "bone"
        return s

    def __len__(self) -> int:
        return len(self.times)

    def view(self, size: tuple[int, int] = (800, 600), steps: int = 9) -> Any:
        """A camera on the muscles: as `musclewrap.output.render_series` frames a series.

        The box round the muscles of ``steps`` time steps spread through the series
        (its first and last among them; the GIF's camera takes every step drawn), seen
        from the side, not turned (a run's ``[output] view`` is not in its folder).
        """
        bones = tuple(n for n, kind in self.parts.items() if kind == "bone")
        picked = np.unique(np.linspace(0, len(self) - 1, steps).round().astype(int))
        shown = [
            (
                float(self.times[k]),
                label_files(
                    [str(f.relative_to(self.folder)) for f in self.files[k].values()], bones, {}
                ),
            )
            for k in picked
        ]
        return frame_view(*muscles_box(self.folder, shown), (0.0, 0.0), size)

    def part(self, k: int, name: str) -> dict[str, np.ndarray] | None:
        """Part ``name`` at step ``k`` (None where it has no file there); the last few kept."""
        f = self.files[k].get(name)
        if f is None:
            return None
        key = (k, str(f))
        if key in self._kept:
            self._kept.move_to_end(key)
            return self._kept[key]
        got = read_polydata(f)
        self._kept[key] = got
        while len(self._kept) > 64 * max(1, len(self.parts)):
            self._kept.popitem(last=False)
        return got


def triangles(d: dict[str, np.ndarray]) -> IntArray:
    """A read file's triangles (k, 3)."""
    if "polys" not in d:
        return np.zeros((0, 3), dtype=np.int64)
    return d["polys"].reshape(-1, 3)


def segments(d: dict[str, np.ndarray]) -> IntArray:
    """A read file's line cells as point-index segments (k, 2)."""
    if "lines" not in d:
        return np.zeros((0, 2), dtype=np.int64)
    off, con = d["lines_offsets"], d["lines"]
    segs = [np.column_stack([con[a : b - 1], con[a + 1 : b]]) for a, b in zip(off[:-1], off[1:])]
    return np.vstack(segs) if segs else np.zeros((0, 2), dtype=np.int64)
