"""Reading and writing triangle meshes (STL, OBJ, PLY, OFF, legacy VTK, VTK XML PolyData).

Every writer goes through a temporary file in the destination folder and an
atomic rename, so an interrupted run never leaves a partly written file.
Coordinates are written as float64 wherever the format allows it (VTP, VTK,
PLY, OBJ and OFF as 17 significant digits); STL stores float32 only.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from .._typing import FloatArray, IntArray, PathLike
from ._checks import MeshError

__all__ = ["FORMATS", "atomic_path", "read_mesh", "write_mesh"]

FORMATS = (".stl", ".obj", ".ply", ".off", ".vtk", ".vtp")


_UMASK = os.umask(0)
os.umask(_UMASK)


@contextlib.contextmanager
def atomic_path(path: PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` and rename it onto ``path`` on success.

    Parameters
    ----------
    path : str or os.PathLike
        Final destination.

    Yields
    ------
    pathlib.Path
        Where to write. Removed if the block raises.
    """
    dest = Path(path)
    dest.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(
        prefix=f".{dest.name}.", suffix=".part" + dest.suffix, dir=dest.parent
    )
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        os.chmod(tmp_path, 0o666 & ~_UMASK)  # mkstemp makes 0600; outputs are ordinary files
        os.replace(tmp_path, dest)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp_path.unlink()
        raise


def _vtk_read(path: Path) -> tuple[FloatArray, IntArray]:
    """VTK's readers; the legacy one in a child process.

    VTK's legacy reader crashed the process (SIGSEGV) on 11 of 44 damaged .vtk
    files in a fuzz run (tools/fuzz.py): it runs in a child, whose death
    becomes a clear error. The XML reader held up and runs here.
    """
    from . import _vtk_reader

    if path.suffix.lower() == ".vtp":
        try:
            return _vtk_reader.read(path)
        except ValueError as exc:
            raise MeshError(str(exc)) from None
    with tempfile.TemporaryDirectory(prefix="musclewrap-vtk-") as tmp:
        out = Path(tmp) / "mesh.npz"
        try:
            r = subprocess.run(
                [sys.executable, _vtk_reader.__file__, str(path), str(out)],
                capture_output=True,
                text=True,
                timeout=600,
            )
        except subprocess.TimeoutExpired:
            raise MeshError(f"{path}: VTK's reader did not finish in 10 minutes") from None
        if r.returncode == 2:
            raise MeshError(r.stderr.strip().splitlines()[-1])
        if r.returncode != 0 or not out.is_file():
            raise MeshError(
                f"{path}: VTK's reader crashed on this file (exit status {r.returncode}): it is "
                "damaged, or not a legacy VTK POLYDATA file; check it in ParaView, or export "
                "it again"
            )
        with np.load(out) as z:
            return z["V"], z["F"]


def _trimesh_read(path: Path) -> tuple[FloatArray, IntArray]:
    import trimesh

    try:
        mesh = trimesh.load_mesh(str(path), process=False, force="mesh")
    except Exception as exc:  # noqa: BLE001 - any parser failure becomes one clear message
        raise MeshError(
            f"{path}: could not be parsed as {path.suffix.upper()[1:]}: {exc}"
        ) from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise MeshError(f"{path}: no triangles found (empty or not a surface mesh)")
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)


def read_mesh(path: PathLike) -> tuple[FloatArray, IntArray]:
    """Read a triangle surface mesh; polygons are triangulated.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.stl``, ``.obj``, ``.ply``, ``.off``, ``.vtk`` (legacy POLYDATA) or
        ``.vtp`` file.

    Returns
    -------
    V : (n, 3) float64 array
    F : (m, 3) int64 array

    Raises
    ------
    MeshError
        If the file is missing, of an unknown format, unreadable, empty, or
        holds non-finite coordinates.
    """
    p = Path(path)
    if not p.is_file():
        raise MeshError(f"{p}: no such mesh file")
    ext = p.suffix.lower()
    if ext not in FORMATS:
        raise MeshError(f"{p}: unknown mesh format '{ext}'; use one of {', '.join(FORMATS)}")
    if p.stat().st_size == 0:
        raise MeshError(f"{p}: the file is empty")
    V, F = _vtk_read(p) if ext in (".vtk", ".vtp") else _trimesh_read(p)
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
        raise MeshError(
            f"{p}: vertices or faces have the wrong shape ({V.shape}, {F.shape}): the file "
            "is damaged or not a triangle surface mesh"
        )
    if len(F) == 0:
        raise MeshError(f"{p}: no triangles found")
    if not np.isfinite(V).all():
        bad = int((~np.isfinite(V).all(axis=1)).sum())
        raise MeshError(f"{p}: {bad} vertex coordinate row(s) are NaN or infinite")
    if F.min() < 0 or F.max() >= len(V):
        raise MeshError(f"{p}: face indices refer to vertices that do not exist")
    return V, F


def _write_vtk(
    path: Path,
    V: FloatArray,
    F: IntArray,
    point_data: Mapping[str, np.ndarray],
    lines: IntArray | None,
    cell_data: Mapping[str, np.ndarray],
) -> None:
    from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
    from vtkmodules.vtkIOLegacy import vtkPolyDataWriter

    poly = vtkPolyData()
    pts = vtkPoints()
    pts.SetData(numpy_to_vtk(np.ascontiguousarray(V, dtype=np.float64), deep=True))
    poly.SetPoints(pts)

    def cells(conn: IntArray, k: int) -> vtkCellArray:
        ca = vtkCellArray()
        offsets = np.arange(0, conn.size + 1, k, dtype=np.int64)
        ca.SetData(
            numpy_to_vtkIdTypeArray(offsets, deep=True),
            numpy_to_vtkIdTypeArray(np.ascontiguousarray(conn.ravel(), dtype=np.int64), deep=True),
        )
        return ca

    if len(F):
        poly.SetPolys(cells(F, 3))
    if lines is not None and len(lines):
        poly.SetLines(cells(lines, lines.shape[1]))
    for data, arrays in ((poly.GetPointData(), point_data), (poly.GetCellData(), cell_data)):
        for name, values in arrays.items():
            arr = numpy_to_vtk(np.ascontiguousarray(values), deep=True)
            arr.SetName(name)
            data.AddArray(arr)
    w = vtkPolyDataWriter()  # legacy .vtk; .vtp goes through _write_vtp
    w.SetFileTypeToBinary()
    w.SetInputData(poly)
    w.SetFileName(str(path))
    if w.Write() != 1:
        raise OSError(f"{path}: VTK failed to write the file")


_VTK_TYPES = {
    np.dtype("<f8"): "Float64",
    np.dtype("<f4"): "Float32",
    np.dtype("<i8"): "Int64",
    np.dtype("<i4"): "Int32",
    np.dtype("u1"): "UInt8",
}


def _write_vtp(
    path: Path,
    V: FloatArray,
    F: IntArray,
    point_data: Mapping[str, np.ndarray],
    lines: IntArray | None,
    cell_data: Mapping[str, np.ndarray],
) -> None:
    """VTK XML PolyData, raw appended binary, no compression (the VTK file format 1.0).

    Written directly: a frame of a series is three arrays, and going through a
    vtkPolyData and vtkXMLPolyDataWriter took most of a run's writing time.
    Files read back with VTK's own reader in the tests.
    """
    blocks: list[np.ndarray] = []
    offset = 0

    def array(values: np.ndarray, name: str, components: int = 1) -> str:
        nonlocal offset
        a = np.ascontiguousarray(values)
        a = a.astype(a.dtype.newbyteorder("<"), copy=False)
        kind = _VTK_TYPES.get(a.dtype)
        if kind is None:
            a, kind = a.astype("<f8"), "Float64"
        blocks.append(a)
        tag = (
            f'<DataArray type="{kind}" Name={quoteattr(name)} NumberOfComponents="{components}" '
            f'format="appended" offset="{offset}"/>'
        )
        offset += 8 + a.nbytes
        return tag

    def cells(conn: IntArray, k: int) -> str:
        small = conn.size < 2**31 - 1
        idx = np.int32 if small else np.int64
        return array(conn.astype(idx).ravel(), "connectivity") + array(
            np.arange(k, conn.size + 1, k, dtype=idx), "offsets"
        )

    n_lines = 0 if lines is None else len(lines)
    xml = ['<?xml version="1.0"?>']
    xml.append(
        '<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" header_type="UInt64">'
    )
    xml.append("<PolyData>")
    xml.append(
        f'<Piece NumberOfPoints="{len(V)}" NumberOfVerts="0" NumberOfLines="{n_lines}" '
        f'NumberOfStrips="0" NumberOfPolys="{len(F)}">'
    )
    for tag, arrays in (("PointData", point_data), ("CellData", cell_data)):
        if arrays:
            xml.append(f"<{tag}>")
            for name, values in arrays.items():
                v = np.asarray(values)
                xml.append(array(v, name, 1 if v.ndim == 1 else int(np.prod(v.shape[1:]))))
            xml.append(f"</{tag}>")
    xml.append("<Points>" + array(V.astype("<f8"), "Points", 3) + "</Points>")
    if n_lines:
        xml.append("<Lines>" + cells(lines, lines.shape[1]) + "</Lines>")
    if len(F):
        xml.append("<Polys>" + cells(F, 3) + "</Polys>")
    xml.append('</Piece>\n</PolyData>\n<AppendedData encoding="raw">\n_')
    with open(path, "wb") as fh:
        fh.write("\n".join(xml).encode("utf-8"))
        for a in blocks:
            fh.write(np.uint64(a.nbytes).tobytes())
            fh.write(memoryview(a).cast("B"))
        fh.write(b"\n</AppendedData>\n</VTKFile>\n")


def _write_ply(path: Path, V: FloatArray, F: IntArray) -> None:
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment musclewrap float64 coordinates\n"
        f"element vertex {len(V)}\nproperty double x\nproperty double y\nproperty double z\n"
        f"element face {len(F)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    faces = np.empty(len(F), dtype=[("n", "u1"), ("idx", "<i4", (3,))])
    faces["n"] = 3
    faces["idx"] = F
    with open(path, "wb") as fh:
        fh.write(header.encode("ascii"))
        fh.write(np.ascontiguousarray(V, dtype="<f8").tobytes())
        fh.write(faces.tobytes())


def _write_obj(path: Path, V: FloatArray, F: IntArray) -> None:
    with open(path, "w", encoding="ascii") as fh:
        fh.write("# musclewrap\n")
        np.savetxt(fh, V, fmt="v %.17g %.17g %.17g")
        np.savetxt(fh, F + 1, fmt="f %d %d %d")


def _write_off(path: Path, V: FloatArray, F: IntArray) -> None:
    with open(path, "w", encoding="ascii") as fh:
        fh.write(f"OFF\n{len(V)} {len(F)} 0\n")
        np.savetxt(fh, V, fmt="%.17g %.17g %.17g")
        np.savetxt(fh, F, fmt="3 %d %d %d")


def _write_trimesh(path: Path, V: FloatArray, F: IntArray, file_type: str) -> None:
    import trimesh

    data = trimesh.Trimesh(V, F, process=False).export(file_type=file_type)
    with open(path, "wb") as fh:
        fh.write(data if isinstance(data, bytes) else data.encode("ascii"))


def write_mesh(
    path: PathLike,
    V: FloatArray,
    F: IntArray,
    *,
    point_data: Mapping[str, np.ndarray] | None = None,
    lines: IntArray | None = None,
    cell_data: Mapping[str, np.ndarray] | None = None,
) -> Path:
    """Write a triangle mesh atomically, format chosen by the extension.

    Parameters
    ----------
    path : str or os.PathLike
        Destination ending in ``.vtp``, ``.vtk``, ``.ply``, ``.obj``, ``.off``
        or ``.stl``.
    V : (n, 3) float64 array
        Vertex positions (written as float64 except in STL, which holds
        float32 only).
    F : (m, 3) int array
        Triangles (may be empty when only ``lines`` are written to VTK).
    point_data : mapping of str to array, optional
        Per-vertex arrays (VTK formats only).
    lines : (k, j) int array, optional
        Poly-lines of ``j >= 2`` points each (VTK formats only): segments of
        action lines, or fibres.
    cell_data : mapping of str to array, optional
        Per-cell arrays (VTK formats only), lines first, then triangles.

    Returns
    -------
    pathlib.Path
        The written path.

    Raises
    ------
    ValueError
        If the extension is unknown or the coordinates are not finite.
    """
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in FORMATS:
        raise ValueError(f"{p}: unknown output format '{ext}'; use one of {', '.join(FORMATS)}")
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    if not np.isfinite(V).all():
        raise ValueError(f"{p}: refusing to write non-finite coordinates")
    if lines is not None:
        lines = np.asarray(lines, dtype=np.int64)
        if lines.ndim != 2 or (len(lines) and lines.shape[1] < 2):
            raise ValueError(f"{p}: lines must be (k, j) vertex indices with j >= 2")
    n_cells = len(F) + (0 if lines is None else len(lines))
    for name, values in (cell_data or {}).items():
        if len(values) != n_cells:
            raise ValueError(
                f"{p}: cell array '{name}' has {len(values)} values for {n_cells} cells"
            )
    with atomic_path(p) as tmp:
        if ext == ".vtp":
            _write_vtp(tmp, V, F, point_data or {}, lines, cell_data or {})
        elif ext == ".vtk":
            _write_vtk(tmp, V, F, point_data or {}, lines, cell_data or {})
        elif ext == ".ply":
            _write_ply(tmp, V, F)
        elif ext == ".obj":
            _write_obj(tmp, V, F)
        elif ext == ".off":
            _write_off(tmp, V, F)
        else:
            _write_trimesh(tmp, V, F, ext[1:])
    return p
