"""Read a VTK polygon mesh (legacy .vtk or XML .vtp) into arrays; also runs as a script.

Kept free of package imports: `musclewrap.mesh` runs it as a child process for legacy files
(``python _vtk_reader.py IN OUT.npz``), so that a crash of VTK's reader on a damaged file
ends the child, not the run. Exit status 2 with the message on stderr for a refused file.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np


class _Errors:
    """Collects VTK error messages instead of letting them go to stderr."""

    def __init__(self) -> None:
        self.messages: list[str] = []

    def __call__(self, obj: object, event: str) -> None:  # pragma: no cover - VTK callback
        self.messages.append(event)


def read(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Points (float64) and triangles (int64) of a VTK polygon mesh; ValueError if unreadable."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonCore import vtkCommand, vtkLogger, vtkOutputWindow
    from vtkmodules.vtkFiltersCore import vtkTriangleFilter
    from vtkmodules.vtkIOLegacy import vtkPolyDataReader
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

    # never print to the user's terminal: the output window, and VTK's own logger (the XML
    # parser reports damaged data through it)
    vtkOutputWindow.GetInstance().SetDisplayMode(0)
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_OFF)
    errors = _Errors()
    if path.suffix.lower() == ".vtp":
        reader = vtkXMLPolyDataReader()
    else:
        reader = vtkPolyDataReader()
        reader.ReadAllScalarsOn()
    reader.AddObserver(vtkCommand.ErrorEvent, errors)
    reader.SetFileName(str(path))
    reader.Update()
    if path.suffix.lower() == ".vtk" and not reader.IsFilePolyData():
        raise ValueError(f"{path}: not a legacy VTK POLYDATA file (or unreadable)")
    poly = reader.GetOutput()
    if errors.messages or poly is None or poly.GetNumberOfPoints() == 0:
        raise ValueError(
            f"{path}: VTK could not read a polygon mesh from this file (empty or corrupted)"
        )
    n = poly.GetNumberOfPoints()
    polys = poly.GetPolys()
    if polys.GetNumberOfCells() == 0:
        raise ValueError(f"{path}: the file holds points but no polygons")
    conn = vtk_to_numpy(polys.GetConnectivityArray())
    if conn.size and (conn.min() < 0 or conn.max() >= n):  # checked before any filter uses it
        raise ValueError(f"{path}: polygons refer to points that do not exist")
    tri = vtkTriangleFilter()
    tri.PassLinesOff()
    tri.PassVertsOff()
    tri.SetInputData(poly)
    tri.Update()
    out = tri.GetOutput()
    V = vtk_to_numpy(out.GetPoints().GetData()).astype(np.float64)
    polys = out.GetPolys()
    conn = vtk_to_numpy(polys.GetConnectivityArray()).astype(np.int64)
    offs = vtk_to_numpy(polys.GetOffsetsArray()).astype(np.int64)
    if not np.all(np.diff(offs) == 3):
        raise ValueError(f"{path}: polygons could not be triangulated")
    return V, conn.reshape(-1, 3)


def _main(argv: list[str]) -> int:
    try:
        V, F = read(Path(argv[0]))
    except ValueError as exc:
        print(str(exc), file=sys.stderr)
        return 2
    with open(argv[1], "wb") as fh:
        np.savez(fh, V=V, F=F)
    return 0


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
