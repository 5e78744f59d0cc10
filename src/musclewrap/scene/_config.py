"""Scene files (TOML): what to deform, driven by what, written where."""

from __future__ import annotations

import dataclasses
import os
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._typing import PathLike
from ..constants import UNITS, defaults
from ..errors import SceneError, suggest
from ..model import FEMUR_FITS, axes_rotation
from ._keys import SCENE_KEYS

__all__ = ["UNITS", "BoneSpec", "FibreSpec", "MuscleSpec", "Scene", "load_scene"]

# the keys each table may hold: one table with their meanings (`_keys.SCENE_KEYS`), which the
# documentation's scene reference is generated from
_TOP = set(SCENE_KEYS[""])
_UNITS = set(SCENE_KEYS["units"])
_REGISTRATION = set(SCENE_KEYS["registration"])
_MODEL = set(SCENE_KEYS["model"])
_LINES = set(SCENE_KEYS["lines"])
_OUTPUT = set(SCENE_KEYS["output"])
_MUSCLE = set(SCENE_KEYS["muscles.NAME"])
_COLLISIONS = set(SCENE_KEYS["collisions"])
_FIBRES = set(SCENE_KEYS["fibres"])
_BONE = set(SCENE_KEYS["bones.NAME"])
_LANDMARK = set(SCENE_KEYS["registration.landmark"])
#: how a landmark's point is found on its mesh (`musclewrap.model.landmark_point`)
LANDMARK_FITS = ("sphere", "centroid", *FEMUR_FITS)


@dataclass(frozen=True)
class Landmark:
    """A point found on a mesh (sphere centre or surface centroid) and its place on the model."""

    name: str
    mesh: Path
    fit: str
    body: str
    point: tuple[float, float, float]


@dataclass(frozen=True)
class Registration:
    """Meshes segmented from another subject, placed on the model by landmarks."""

    axes: tuple[str, str, str] | None
    landmarks: tuple[Landmark, ...]


@dataclass(frozen=True)
class MuscleSpec:
    """One muscle of a scene (docs/scenes.rst lists every key)."""

    name: str
    mesh: Path
    paths: tuple[str, ...]
    body: str
    reference: str | None
    cage_size: int
    cage_coarsening: str
    method: str
    max_iterations: int | None
    repair: bool
    frame: str
    bones: tuple[str, ...] | None = None
    # the fibres' attachment areas: input vertex indices, or landmark points (mesh frame)
    fibre_origin: tuple[int, ...] | tuple[tuple[float, float, float], ...] | None = None
    fibre_insertion: tuple[int, ...] | tuple[tuple[float, float, float], ...] | None = None


@dataclass(frozen=True)
class FibreSpec:
    """The ``[fibres]`` table: fibres per muscle, and the coordinates of their moment arms.

    ``step`` is the central difference's half-width: degrees for a rotational
    coordinate, millimetres for a translational one. ``landmark_radius`` (mesh units):
    a muscle's ``fibre_origin`` or ``fibre_insertion`` given as landmark points is the
    surface within this distance of them. ``attachments``: where a muscle's fibres
    attach where it gives no areas, ``"bones"`` (the default: where it lies on a bone of
    its ends' bodies, `musclewrap.fibres.areas_on_bones`; its end cap where the scene
    has no such bone) or ``"ends"`` (its end caps). ``moment_arm_contact``: the
    poses on either side of a frame are deformed with the bones' contact (False by
    default: the contact's cage step is not smooth in the pose, and its jumps over a
    step of 1 degree dominated the differences on the LHDL sweeps). ``attached``
    (True by default): the muscle's deformation holds its fibres' attachment areas to
    its paths' first and last points (`musclewrap.Deformer`'s ``attached``), for the
    surface and the fibres alike. ``output`` (not a key of the table): False where the
    fibres are not written (``--no-fibres``), while their areas are still held.
    """

    count: int = 100
    points: int = 15
    moment_arms: tuple[str, ...] = ()
    step: float = 1.0
    voxels: int = 60_000
    moment_arm_contact: bool = False
    landmark_radius: float = 10.0
    attachments: str = "bones"
    attached: bool = True
    output: bool = True


@dataclass(frozen=True)
class BoneSpec:
    """One bone carried rigidly by a body (display, penetration and contact)."""

    name: str
    mesh: Path
    body: str
    frame: str
    #: the file's vertices are multiplied by these (a model's mesh: its scale factors
    #: times the model-to-mesh unit factor)
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    #: where it came from, where not a mesh of the scene's own (the run's notes say so)
    source: str = ""
    #: "shaft": fitted to the muscles at rest (`musclewrap.model.fit_shaft`); "": as placed
    fit: str = ""


@dataclass(frozen=True)
class Scene:
    """A parsed, validated scene file (paths resolved against its folder)."""

    path: Path
    name: str
    mesh_unit: str
    model_unit: str
    osim: Path | None
    motions: tuple[Path, ...]
    rest_pose: dict[str, float]
    angle_unit: str
    coordinates: tuple[str, ...] | None
    output_frame: str
    lines_csv: Path | None
    rest_frame: int
    muscles: tuple[MuscleSpec, ...]
    bones: tuple[BoneSpec, ...]
    bone_display_faces: int
    paper_frames: int
    gif: bool
    gif_every: int
    image_size: tuple[int, int]
    cache_dir: Path | None
    registration: Registration | None = None
    collisions: bool = True
    margin: float = 0.0
    rest_overlap: str = "resolve"
    fibres: FibreSpec | None = None
    muscle_collisions: bool = False
    muscle_pairs: tuple[tuple[str, str], ...] | None = None
    muscle_together: bool = field(default_factory=lambda: defaults.muscle_joint)
    #: each action-line sample the line's mean over this many sample spacings either side
    line_window: float = field(default_factory=lambda: defaults.line_window)
    extra: dict[str, Any] = field(default_factory=dict)
    #: with a line CSV: the bodies' poses per frame (``[lines] bodies``)
    bodies_csv: Path | None = None
    #: how the pictures colour the muscles: "muscle" or "stretch"
    colour: str = "muscle"
    #: the pictures' camera turned from the side view: azimuth, elevation (degrees)
    view: tuple[float, float] = (0.0, 0.0)

    @property
    def motion(self) -> Path | None:
        """The (first) motion file, or None for a line-CSV scene."""
        return self.motions[0] if self.motions else None

    @property
    def scale(self) -> float:
        """Factor from model units to mesh units (1000 for a model in m and meshes in mm)."""
        return UNITS[self.model_unit] / UNITS[self.mesh_unit]


def _table(d: Any, where: str, src: Path) -> dict[str, Any]:
    if not isinstance(d, Mapping):
        raise SceneError(f"{src}: [{where}] must be a table, got {type(d).__name__}")
    return dict(d)


def _keys(d: Mapping[str, Any], allowed: set[str], where: str, src: Path) -> None:
    for k in d:
        if k not in allowed:
            raise SceneError(f"{src}: unknown key '{k}' in {where}; " + suggest(k, sorted(allowed)))


def _get(
    d: Mapping[str, Any], key: str, kind: type | tuple[type, ...], where: str, src: Path
) -> Any:
    v = d[key]
    if kind is float and isinstance(v, int) and not isinstance(v, bool):
        v = float(v)
    if not isinstance(v, kind) or (isinstance(v, bool) and kind in (int, float)):
        name = kind.__name__ if isinstance(kind, type) else " or ".join(k.__name__ for k in kind)
        raise SceneError(f"{src}: {where}.{key} must be {name}, got {v!r}")
    return v


def _line_window(raw: Mapping[str, Any], src: Path) -> float:
    """The scene's ``line_window`` (default ``defaults.line_window``), finite and not negative."""
    if "line_window" not in raw:
        return defaults.line_window
    w = raw["line_window"]
    if isinstance(w, bool) or not isinstance(w, int | float) or not (np.isfinite(w) and w >= 0):
        raise SceneError(f"{src}: line_window must be 0 or a positive number of sample "
                         f"spacings, got {w!r}")  # fmt: skip
    return float(w)


def _file(base: Path, value: Any, where: str, src: Path, kind: str = "file") -> Path:
    """``value`` resolved against the scene's folder: an existing file (or ``kind`` folder)."""
    if not isinstance(value, str) or not value:
        raise SceneError(f"{src}: {where} must be a {kind} path (string), got {value!r}")
    p = Path(value).expanduser()
    p = Path(os.path.normpath(p if p.is_absolute() else base / p))
    if not (p.is_dir() if kind == "folder" else p.is_file()):
        raise SceneError(f"{src}: {where} = '{value}': no such {kind} ({p})")
    return p


def _name(k: str, where: str, src: Path) -> str:
    if not k or any(c in k for c in '/\\:*?"<>|') or k.startswith("."):
        raise SceneError(f"{src}: {where} name '{k}' cannot be used as a folder name")
    return k


def load_scene(path: PathLike) -> Scene:
    """Read and validate a scene file.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.toml`` scene. Relative paths inside it are relative to its folder.

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        For a missing file, TOML syntax errors (with line), unknown keys (with
        the nearest valid key), wrong types, missing files named in the scene,
        or an inconsistent combination (e.g. neither a model nor a line CSV).
    """
    src = Path(path)
    raw = _read_toml(src)
    base = src.resolve().parent
    _keys(raw, _TOP, "the scene's top level", src)
    mesh_unit, model_unit = _units(raw, src)
    model = _table(raw.get("model", {}), "model", src)
    _keys(model, _MODEL, "[model]", src)
    lines = _table(raw.get("lines", {}), "lines", src)
    _keys(lines, _LINES, "[lines]", src)
    drive = _model_fields(model, lines, base, src)
    osim = drive["osim"]
    mesh_frame = model.get("mesh_frame", "body")  # checked by _model_fields
    registration = _registration(raw, base, src, osim) if "registration" in raw else None
    if mesh_frame == "registration" and registration is None:
        raise SceneError(f"{src}: [model] mesh_frame = 'registration' needs a [registration] table")
    drive.update(_lines_fields(lines, base, src))
    output = _output_fields(raw, src)
    geometry = (
        _file(base, model["geometry"], "[model] geometry", src, "folder")
        if "geometry" in model
        else None
    )
    reading = _Reading(
        src, base, osim, "csv" in lines, drive["bodies_csv"], mesh_frame, geometry,
        UNITS[model_unit] / UNITS[mesh_unit],
    )  # fmt: skip
    bones = _bones(raw, reading)
    bone_names = {b.name for b in bones}
    coll = _table(raw.get("collisions", {}), "collisions", src)
    _keys(coll, _COLLISIONS, "[collisions]", src)
    collisions, margin, against, rest_overlap = _collision_settings(coll, src)
    muscles = _muscles(raw, reading, bone_names)
    clash = bone_names & {m.name for m in muscles}
    if clash:
        raise SceneError(f"{src}: the names {sorted(clash)} are used for both a muscle and a bone")
    cache = raw.get("cache_dir")
    cache_dir = None if cache is None else (base / Path(cache).expanduser())
    return Scene(
        path=src,
        name=str(raw.get("name", src.stem)),
        mesh_unit=mesh_unit,
        model_unit=model_unit,
        **drive,
        **output,
        muscles=tuple(muscles),
        bones=tuple(bones),
        cache_dir=cache_dir,
        registration=registration,
        collisions=collisions and bool(bones),
        margin=margin,
        rest_overlap=rest_overlap,
        fibres=_fibres(raw, src, osim),
        muscle_collisions=collisions and against and len(muscles) > 1,
        muscle_pairs=_pairs(coll, [m.name for m in muscles], src),
        muscle_together=(
            _get(coll, "together", bool, "[collisions]", src)
            if "together" in coll
            else defaults.muscle_joint
        ),
        line_window=_line_window(raw, src),
    )


@dataclass(frozen=True)
class _Reading:
    """What the bones' and muscles' tables are read against: the file, its model and frames."""

    src: Path
    base: Path
    osim: Path | None
    line_csv: bool  # the lines come from a CSV ([lines] csv)
    bodies_csv: Path | None
    mesh_frame: str
    geometry: Path | None  # [model] geometry: the model's mesh files
    scale: float  # model units to mesh units


def _read_toml(src: Path) -> dict[str, Any]:
    """The scene file parsed, or an error that names the file and the problem."""
    if not src.is_file():
        raise SceneError(f"{src}: no such scene file")
    try:
        return tomllib.loads(src.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{src}: not valid TOML: {exc}") from None
    except UnicodeDecodeError:
        raise SceneError(f"{src}: not a text file (TOML must be UTF-8)") from None


def _units(raw: Mapping[str, Any], src: Path) -> tuple[str, str]:
    """``[units]``: the meshes' and the model's length units."""
    units = _table(raw.get("units", {}), "units", src)
    _keys(units, _UNITS, "[units]", src)
    mesh_unit, model_unit = units.get("mesh", "mm"), units.get("model", "m")
    for k, u in (("mesh", mesh_unit), ("model", model_unit)):
        if u not in UNITS:
            raise SceneError(f"{src}: units.{k} = {u!r}; use one of {', '.join(UNITS)}")
    return mesh_unit, model_unit


def _model_fields(
    model: Mapping[str, Any], lines: Mapping[str, Any], base: Path, src: Path
) -> dict[str, Any]:
    """``[model]`` (with ``[lines]``'s choice against it): the `Scene` fields it sets."""
    if "csv" in lines and "motion" in model:
        raise SceneError(f"{src}: give either [model] motion or [lines] csv, not both")
    if "csv" not in lines and not ("osim" in model and "motion" in model):
        raise SceneError(
            f"{src}: the scene needs [model] osim and motion (an OpenSim model and motion), "
            "or [lines] csv (per-frame action lines)"
        )
    osim = _file(base, model["osim"], "[model] osim", src) if "osim" in model else None
    motions: tuple[Path, ...] = ()
    if "motion" in model:
        mv = model["motion"]
        items = mv if isinstance(mv, list) else [mv]
        if not items:
            raise SceneError(f"{src}: [model] motion is an empty list")
        motions = tuple(_file(base, m, "[model] motion", src) for m in items)
    rest_pose: dict[str, float] = {}
    for k, v in _table(model.get("rest_pose", {}), "model.rest_pose", src).items():
        rest_pose[k] = _get({k: v}, k, float, "[model] rest_pose", src)
    angle_unit = model.get("angle_unit", "header")
    if angle_unit not in ("header", "deg", "rad"):
        raise SceneError(
            f"{src}: [model] angle_unit = {angle_unit!r}; use 'header', 'deg' or 'rad'"
        )
    coords = None
    if "coordinates" in model:
        c = model["coordinates"]
        if not isinstance(c, list) or not all(isinstance(x, str) for x in c) or not c:
            raise SceneError(f"{src}: [model] coordinates must be a non-empty list of names")
        coords = tuple(c)
    mesh_frame = model.get("mesh_frame", "body")
    if not isinstance(mesh_frame, str):
        raise SceneError(f"{src}: [model] mesh_frame must be 'body', 'ground' or a body name")
    output_frame = model.get("output_frame", "ground")
    if not isinstance(output_frame, str):
        raise SceneError(f"{src}: [model] output_frame must be a body name or 'ground'")
    if osim is None and output_frame != "ground":
        raise SceneError(f"{src}: [model] output_frame needs an OpenSim model ([model] osim)")
    return {
        "osim": osim,
        "motions": motions,
        "rest_pose": rest_pose,
        "angle_unit": angle_unit,
        "coordinates": coords,
        "output_frame": output_frame,
    }


def _lines_fields(lines: Mapping[str, Any], base: Path, src: Path) -> dict[str, Any]:
    """``[lines]``: the action lines' and the bodies' CSV files, the rest frame."""
    lines_csv = _file(base, lines["csv"], "[lines] csv", src) if "csv" in lines else None
    rest_frame = _get(lines, "rest_frame", int, "[lines]", src) if "rest_frame" in lines else 0
    bodies_csv = _file(base, lines["bodies"], "[lines] bodies", src) if "bodies" in lines else None
    if bodies_csv is not None and lines_csv is None:
        raise SceneError(f"{src}: [lines] bodies needs [lines] csv (the action lines per frame)")
    return {"lines_csv": lines_csv, "rest_frame": rest_frame, "bodies_csv": bodies_csv}


def _output_fields(raw: Mapping[str, Any], src: Path) -> dict[str, Any]:
    """``[output]``: the pictures and plots of a run."""
    out = _table(raw.get("output", {}), "output", src)
    _keys(out, _OUTPUT, "[output]", src)
    bone_faces = (
        _get(out, "bone_display_faces", int, "[output]", src)
        if "bone_display_faces" in out
        else 10000
    )
    paper_frames = _get(out, "paper_frames", int, "[output]", src) if "paper_frames" in out else 2
    gif = _get(out, "gif", bool, "[output]", src) if "gif" in out else True
    gif_every = _get(out, "gif_every", int, "[output]", src) if "gif_every" in out else 1
    view = out.get("view", [0, 0])
    if not (
        isinstance(view, list)
        and len(view) == 2
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in view)
        and all(np.isfinite(v) and abs(v) <= 360 for v in view)
    ):
        raise SceneError(
            f"{src}: [output] view must be [azimuth, elevation] in degrees, e.g. [30, 15]"
        )
    colour = out.get("colour", "muscle")
    if colour not in ("muscle", "stretch"):
        raise SceneError(
            f"{src}: [output] colour = {colour!r}; use 'muscle' (one colour each) or "
            "'stretch' (the surface's local stretch)"
        )
    size = out.get("image_size", [800, 600])
    if not (
        isinstance(size, list)
        and len(size) == 2
        and all(isinstance(s, int) and 16 <= s <= 4096 for s in size)
    ):
        raise SceneError(f"{src}: [output] image_size must be [width, height] in pixels")
    if paper_frames < 0 or gif_every < 1 or bone_faces < 0:
        raise SceneError(
            f"{src}: [output] paper_frames, bone_display_faces must be >= 0 and gif_every >= 1"
        )
    return {
        "colour": colour,
        "view": (float(view[0]), float(view[1])),
        "bone_display_faces": bone_faces,
        "paper_frames": paper_frames,
        "gif": gif,
        "gif_every": gif_every,
        "image_size": (size[0], size[1]),
    }


def _bones(raw: Mapping[str, Any], r: _Reading) -> list[BoneSpec]:
    """``[bones.NAME]``: each bone's mesh, body and frame."""
    src, base, osim, bodies_csv, mesh_frame = r.src, r.base, r.osim, r.bodies_csv, r.mesh_frame
    bones = []
    for bname, b in _table(raw.get("bones", {}), "bones", src).items():
        b = _table(b, f"bones.{bname}", src)
        _keys(b, _BONE, f"[bones.{bname}]", src)
        body = b.get("body", "ground")
        if not isinstance(body, str):
            raise SceneError(f"{src}: [bones.{bname}] body must be a body's name")
        fit = b.get("fit", "")
        if fit not in ("", "shaft"):
            raise SceneError(
                f"{src}: [bones.{bname}] fit = {fit!r}; use 'shaft' (a long bone moved across "
                "its axis out of the muscles at rest) or leave it out"
            )
        if "model" in b:
            bones.append(dataclasses.replace(_model_bone(bname, b, body, r), fit=fit))
            continue
        if "mesh" not in b:
            raise SceneError(f"{src}: [bones.{bname}] needs 'mesh' (or 'model': the model's own)")
        if osim is None and bodies_csv is None and body != "ground":
            raise SceneError(
                f"{src}: [bones.{bname}] body needs an OpenSim model ([model] osim) or the "
                "bodies' poses per frame ([lines] bodies)"
            )
        frame = b.get("frame", mesh_frame)
        bones.append(
            BoneSpec(
                _name(bname, "bone", src),
                _file(base, b["mesh"], f"[bones.{bname}] mesh", src),
                body,
                body if frame == "body" else frame,
                fit=fit,
            )
        )
    return bones


def _model_bone(bname: str, b: Mapping[str, Any], body: str, r: _Reading) -> BoneSpec:
    """``[bones.NAME] model = FILE``: the model's own mesh of ``body``, as the model places it."""
    from ..model import model_geometry

    src, where = r.src, f"[bones.{bname}]"
    for k in ("mesh", "frame"):
        if k in b:
            raise SceneError(
                f"{src}: {where} gives both 'model' and '{k}': the model's mesh is placed in its "
                "body's frame as the model places it; give one of 'mesh' and 'model'"
            )
    if r.osim is None:
        raise SceneError(f"{src}: {where} model needs an OpenSim model ([model] osim)")
    if body == "ground":
        raise SceneError(f"{src}: {where} model needs 'body': the body the model attaches it to")
    file = _get(b, "model", str, where, src)
    try:
        g = model_geometry(r.osim, body, file, r.geometry)
    except ValueError as exc:
        raise SceneError(f"{src}: {where} model: {exc}") from None
    scale = tuple(float(f) * r.scale for f in g.scale)
    factors = " ".join(f"{f:g}" for f in g.scale)
    return BoneSpec(
        _name(bname, "bone", src), g.path, body, body, (scale[0], scale[1], scale[2]),
        f"the model's {g.mesh_file} of {body} (scale factors {factors}, {g.path})",
    )  # fmt: skip


def _collision_settings(coll: Mapping[str, Any], src: Path) -> tuple[bool, float, bool, str]:
    """``[collisions]``: on, the margin, the muscles against each other, the rest overlap."""
    collisions = _get(coll, "enabled", bool, "[collisions]", src) if "enabled" in coll else True
    margin = _get(coll, "margin", float, "[collisions]", src) if "margin" in coll else 0.0
    if not (np.isfinite(margin) and margin >= 0):
        raise SceneError(f"{src}: [collisions] margin must be >= 0 (mesh units), got {margin}")
    against = _get(coll, "muscles", bool, "[collisions]", src) if "muscles" in coll else True
    rest_overlap = coll.get("rest_overlap", "resolve")
    if rest_overlap not in ("resolve", "keep"):
        raise SceneError(
            f"{src}: [collisions] rest_overlap = {rest_overlap!r}; use 'resolve' (push the "
            "muscles out of the bones once, at preparation) or 'keep' (prevent new penetration only)"
        )
    return collisions, margin, against, rest_overlap


def _muscles(raw: Mapping[str, Any], r: _Reading, bone_names: set[str]) -> list[MuscleSpec]:
    """``[muscles.NAME]``: each muscle's mesh, paths, body, cage and solver settings."""
    src, base, osim, mesh_frame = r.src, r.base, r.osim, r.mesh_frame
    muscles = []
    table = _table(raw.get("muscles", {}), "muscles", src)
    if not table:
        raise SceneError(f"{src}: the scene names no muscles ([muscles.NAME] tables)")
    for mname, m in table.items():
        where = f"[muscles.{mname}]"
        m = _table(m, f"muscles.{mname}", src)
        _keys(m, _MUSCLE, where, src)
        if "mesh" not in m:
            raise SceneError(f"{src}: {where} needs 'mesh'")
        paths = m.get("paths", [])
        if osim is not None and not r.line_csv:
            if (
                not isinstance(paths, list)
                or not paths
                or not all(isinstance(p, str) for p in paths)
            ):
                raise SceneError(
                    f"{src}: {where} paths must list the OpenSim muscle path(s), e.g. ['glut_max1_r']"
                )
        ref = m.get("reference")
        if ref is not None and not isinstance(ref, str):
            raise SceneError(f"{src}: {where} reference must be a bone or body name")
        if ref is not None and osim is None and ref not in bone_names:
            raise SceneError(
                f"{src}: {where} reference '{ref}' is not a bone of the scene; "
                + suggest(ref, sorted(bone_names))
            )
        method = m.get("method", "sqp")
        if method not in ("sqp", "exact", "paper"):
            raise SceneError(f"{src}: {where} method = {method!r}; use 'sqp', 'exact' or 'paper'")
        coarsening = m.get("cage_coarsening", "uniform")
        if coarsening not in ("uniform", "quadric"):
            raise SceneError(f"{src}: {where} cage_coarsening must be 'uniform' or 'quadric'")
        cage = _get(m, "cage_size", int, where, src) if "cage_size" in m else defaults.cage_size
        if cage < 20:
            raise SceneError(f"{src}: {where} cage_size must be at least 20")
        its = _get(m, "max_iterations", int, where, src) if "max_iterations" in m else None
        body = m.get("body", "ground")
        if osim is None and body != "ground":
            raise SceneError(f"{src}: {where} body needs an OpenSim model ([model] osim)")
        mbones = m.get("bones")
        if mbones is not None:
            if not isinstance(mbones, list) or not all(isinstance(b, str) for b in mbones):
                raise SceneError(f"{src}: {where} bones must be a list of bone names")
            for b in mbones:
                if b not in bone_names:
                    raise SceneError(
                        f"{src}: {where} bones: '{b}' is not a bone of the scene; "
                        + suggest(b, sorted(bone_names))
                    )
            mbones = tuple(mbones)
        areas = {k: _attachment(m, k, where, src) for k in ("fibre_origin", "fibre_insertion")}
        muscles.append(
            MuscleSpec(
                name=_name(mname, "muscle", src),
                mesh=_file(base, m["mesh"], f"{where} mesh", src),
                paths=tuple(paths),
                body=body,
                reference=ref,
                cage_size=cage,
                cage_coarsening=coarsening,
                method=method,
                max_iterations=its,
                repair=_get(m, "repair", bool, where, src) if "repair" in m else True,
                frame=body if m.get("frame", mesh_frame) == "body" else m.get("frame", mesh_frame),
                bones=mbones,
                **areas,
            )
        )
    return muscles


def _pairs(
    coll: Mapping[str, Any], names: list[str], src: Path
) -> tuple[tuple[str, str], ...] | None:
    """``[collisions] pairs``: the pairs of muscles kept apart (None: every pair)."""
    if "pairs" not in coll:
        return None
    raw = coll["pairs"]
    form = "a list of pairs of muscle names, e.g. [['psoas', 'iliacus']]"
    if not isinstance(raw, list):
        raise SceneError(f"{src}: [collisions] pairs must be {form}, got {raw!r}")
    out = set()
    for p in raw:
        if not (isinstance(p, list) and len(p) == 2 and all(isinstance(x, str) for x in p)):
            raise SceneError(f"{src}: [collisions] pairs must be {form}; {p!r} is not a pair")
        for x in p:
            if x not in names:
                raise SceneError(
                    f"{src}: [collisions] pairs names '{x}', not a muscle of the scene; "
                    + suggest(x, sorted(names))
                )
        if p[0] == p[1]:
            raise SceneError(f"{src}: [collisions] pairs: '{p[0]}' paired with itself")
        out.add((min(p), max(p)))
    return tuple(sorted(out))


def _attachment(m: Mapping[str, Any], key: str, where: str, src: Path) -> tuple[Any, ...] | None:
    """A muscle's ``fibre_origin``/``fibre_insertion``: vertex indices or landmark points."""
    if key not in m:
        return None
    v = m[key]
    if isinstance(v, list) and v and all(isinstance(i, int) and not isinstance(i, bool) for i in v):
        if min(v) < 0:
            raise SceneError(f"{src}: {where} {key}: vertex indices start at 0, got {min(v)}")
        return tuple(v)
    if (
        isinstance(v, list)
        and v
        and all(
            isinstance(p, list)
            and len(p) == 3
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in p)
            for p in v
        )
    ):
        return tuple((float(p[0]), float(p[1]), float(p[2])) for p in v)
    raise SceneError(
        f"{src}: {where} {key} must list vertex indices of the mesh (e.g. [12, 13, 40]) or "
        "landmark points in its coordinates (e.g. [[10.0, 4.5, -300.0]])"
    )


def _fibres(raw: dict[str, Any], src: Path, osim: Path | None) -> FibreSpec | None:
    if "fibres" not in raw:
        return None
    t = _table(raw["fibres"], "fibres", src)
    _keys(t, _FIBRES, "[fibres]", src)
    kw: dict[str, Any] = {}
    for key, kind, least in (("count", int, 1), ("points", int, 2), ("voxels", int, 1000)):
        if key in t:
            kw[key] = _get(t, key, kind, "[fibres]", src)
            if kw[key] < least:
                raise SceneError(f"{src}: [fibres] {key} must be >= {least}, got {kw[key]}")
    if "step" in t:
        kw["step"] = _get(t, "step", float, "[fibres]", src)
        if not 0 < kw["step"] <= 10:
            raise SceneError(f"{src}: [fibres] step must lie in (0, 10], got {kw['step']}")
    if "landmark_radius" in t:
        kw["landmark_radius"] = _get(t, "landmark_radius", float, "[fibres]", src)
        if not kw["landmark_radius"] > 0:
            raise SceneError(f"{src}: [fibres] landmark_radius must be > 0 (mesh units)")
    for key in ("moment_arm_contact", "attached"):
        if key in t:
            kw[key] = _get(t, key, bool, "[fibres]", src)
    if "attachments" in t:
        kw["attachments"] = _get(t, "attachments", str, "[fibres]", src)
        if kw["attachments"] not in ("ends", "bones"):
            raise SceneError(
                f"{src}: [fibres] attachments must be 'ends' or 'bones', got {kw['attachments']!r}"
            )
    if "moment_arms" in t:
        ma = t["moment_arms"]
        if not (isinstance(ma, list) and all(isinstance(c, str) and c for c in ma)):
            raise SceneError(f"{src}: [fibres] moment_arms must be a list of coordinate names")
        if len(set(ma)) != len(ma):
            raise SceneError(f"{src}: [fibres] moment_arms names a coordinate twice")
        if ma and osim is None:
            raise SceneError(f"{src}: [fibres] moment_arms need an OpenSim model ([model] osim)")
        kw["moment_arms"] = tuple(ma)
    return FibreSpec(**kw)


def _registration(raw: dict[str, Any], base: Path, src: Path, osim: Path | None) -> Registration:
    reg = _table(raw["registration"], "registration", src)
    _keys(reg, _REGISTRATION, "[registration]", src)
    if osim is None:
        raise SceneError(f"{src}: [registration] needs an OpenSim model ([model] osim)")
    axes = reg.get("axes")
    if axes is not None:
        ok = (
            isinstance(axes, list)
            and len(axes) == 3
            and all(isinstance(a, str) and a.lstrip("+-") in ("x", "y", "z") for a in axes)
            and sorted(a.lstrip("+-") for a in axes) == ["x", "y", "z"]
        )
        if ok:
            ok = bool(np.isclose(np.linalg.det(axes_rotation(axes)), 1.0))
        if not ok:
            raise SceneError(
                f"{src}: [registration] axes must name the mesh axes that become the model's "
                "x, y and z, each once, as a rotation (e.g. ['y', 'z', 'x'] or ['-x', 'z', 'y'])"
            )
    items = reg.get("landmark", [])
    if not isinstance(items, list) or len(items) < 2:
        raise SceneError(
            f"{src}: [registration] needs two or more [[registration.landmark]] tables"
        )
    if len(items) == 2 and axes is None:
        raise SceneError(
            f"{src}: [registration] with two landmarks needs axes (they fix the turn about "
            "the line through the landmarks)"
        )
    marks = []
    for i, item in enumerate(items):
        where = f"[[registration.landmark]] number {i + 1}"
        lm = _table(item, "registration.landmark", src)
        _keys(lm, _LANDMARK, where, src)
        for k in ("mesh", "body"):
            if k not in lm:
                raise SceneError(f"{src}: {where} needs '{k}'")
        fit = lm.get("fit", "centroid")
        if fit not in LANDMARK_FITS:
            raise SceneError(
                f"{src}: {where} fit = {fit!r}; use one of {', '.join(map(repr, LANDMARK_FITS))}"
            )
        point = lm.get("point", [0.0, 0.0, 0.0])
        if not (
            isinstance(point, list)
            and len(point) == 3
            and all(isinstance(v, (int, float)) for v in point)
        ):
            raise SceneError(f"{src}: {where} point must be [x, y, z] in the body, model units")
        marks.append(
            Landmark(
                name=str(lm.get("name", f"landmark {i + 1}")),
                mesh=_file(base, lm["mesh"], f"{where} mesh", src),
                fit=fit,
                body=_get(lm, "body", str, where, src),
                point=(float(point[0]), float(point[1]), float(point[2])),
            )
        )
    return Registration(
        axes=None if axes is None else (axes[0], axes[1], axes[2]), landmarks=tuple(marks)
    )
