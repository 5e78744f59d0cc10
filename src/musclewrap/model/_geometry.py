"""The model's own bone surfaces: the meshes an OpenSim model attaches to its bodies.

An ``.osim`` file lists, per body, the geometry drawn with it (``<attached_geometry>``:
``<Mesh>`` elements with a ``<mesh_file>`` and ``<scale_factors>``), in the body's frame
and the model's length unit. A scene whose segmentation lacks a bone (a thigh without its
femur, a hip without its pelvis) can take the model's (`model_geometry`); OpenSim looks
for the files next to the model, in its ``Geometry`` folder, and in the installation's,
so the scene may name the folder (``[model] geometry``).
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

__all__ = ["ModelGeometry", "body_meshes", "geometry_folders", "model_geometry"]


@dataclass(frozen=True)
class ModelGeometry:
    """One mesh a model attaches to a body: its file and scale factors (body frame)."""

    body: str
    mesh_file: str
    path: Path
    scale: tuple[float, float, float]


def geometry_folders(osim: Path, folder: Path | None = None) -> list[Path]:
    """Where a model's mesh files are looked for, in order.

    ``folder`` if given; else the model's folder, its ``Geometry`` folder and the
    ``Geometry`` folder beside it.
    """
    if folder is not None:
        return [folder]
    here = osim.resolve().parent
    return [here, here / "Geometry", here.parent / "Geometry"]


def body_meshes(osim: Path, body: str) -> list[tuple[str, tuple[float, float, float]]]:
    """The ``(mesh_file, scale_factors)`` a model attaches to ``body`` (empty: none)."""
    try:
        st = Path(osim).stat()
        listed = _listed_meshes(str(osim), st.st_mtime_ns, st.st_size)
    except (ET.ParseError, OSError) as exc:
        raise ValueError(f"{osim}: not a readable OpenSim model ({exc})") from None
    out = []
    for b, file, text in listed:
        if b == body:
            try:
                s = tuple(float(x) for x in text)
            except ValueError:
                raise ValueError(
                    f"{osim}: body '{body}', mesh '{file}': scale_factors {text} are not numbers"
                ) from None
            if file and len(s) == 3:
                out.append((file, (s[0], s[1], s[2])))
    return out


@functools.lru_cache(maxsize=8)
def _listed_meshes(osim: str, mtime_ns: int, size: int) -> tuple[tuple[str, str, list[str]], ...]:
    """Every ``(body, mesh_file, scale_factors' words)`` of a model file, parsed once per state.

    ``init`` asks for each of a model's bodies in turn: one parse of the file, not one each
    (``mtime_ns`` and ``size`` key the file's state: an edited model is parsed again).
    """
    out = []
    for b in ET.parse(osim).getroot().iter("Body"):
        for mesh in b.iter("Mesh"):
            file = (mesh.findtext("mesh_file") or "").strip()
            text = (mesh.findtext("scale_factors") or "1 1 1").split()
            out.append((str(b.get("name")), file, text))
    return tuple(out)


def model_geometry(
    osim: Path, body: str, mesh_file: str, folder: Path | None = None
) -> ModelGeometry:
    """The mesh ``mesh_file`` that the model ``osim`` attaches to ``body``, found on disk.

    Raises
    ------
    ValueError
        Naming the model and the body: where the body attaches no such mesh (with the
        ones it does attach), or where the file is in none of `geometry_folders`.
    """
    meshes = body_meshes(osim, body)
    found = [s for f, s in meshes if f == mesh_file or Path(f).name == mesh_file]
    if not found:
        have = ", ".join(sorted({f for f, _ in meshes})) or "none"
        raise ValueError(
            f"{osim}: the body '{body}' attaches no mesh '{mesh_file}' (it attaches: {have})"
        )
    places = geometry_folders(osim, folder)
    for p in places:
        if (p / mesh_file).is_file():
            return ModelGeometry(body, mesh_file, p / mesh_file, found[0])
    raise ValueError(
        f"{osim}: the body '{body}''s mesh '{mesh_file}' is in none of "
        + ", ".join(str(p) for p in places)
        + " (name the folder: [model] geometry)"
    )
