"""``musclewrap init``: a scene from an OpenSim model and a folder of meshes.

Each mesh is classified (muscle, bone or landmark) by its file name (`musclewrap.model._names`) and its
shape (open, a thin shell, or a closed solid: a muscle is the last); each muscle is matched
to the model's paths by anatomical name, each bone to its body. Then the placement that
makes the paths run through their muscles at rest is chosen among: the meshes in their
bodies' frames (at the pose where the scene's bodies coincide, a model built in its scan's
frame, else the default pose), in the model's ground frame, or in another subject's frame
placed by the landmarks found (femoral head -> hip centre, distal femur -> knee; by name,
else by shape and place) with each of the 24 turns of the axes. Where names fail, the
place decides: a solid lying where a model bone lies is that bone, and the meshes whose
names say nothing (or whose named paths do not run along them) take the muscles whose
paths do, one muscle per mesh. Every guess is written into the scene as a comment with
how sure it is; what could not be placed is listed, never dropped silently.
"""

from __future__ import annotations

import itertools
import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .._typing import FloatArray, IntArray
from ..constants import defaults
from ..errors import SceneError
from ..mesh import (
    apply_transform,
    atomic_path,
    check_mesh,
    mean_thickness,
    read_mesh,
    tidy_mesh,
)
from ..model import (
    BONES,
    GROUPS,
    LANDMARKS,
    MUSCLES,
    LineFit,
    ModelGeometry,
    NameMatch,
    OpenSimModel,
    axes_rotation,
    body_meshes,
    cap_spread,
    femur_landmarks,
    fit_sphere,
    landmark_point,
    line_fits,
    match_bone,
    match_group,
    match_muscle,
    mesh_name_tokens,
    model_geometry,
    path_anatomy,
    read_motion,
    similarity,
    write_motion,
)
from ..scene import UNITS

__all__ = ["MESH_SUFFIXES", "InitResult", "MeshInfo", "init_scene", "survey"]

#: the mesh files a folder is searched for
MESH_SUFFIXES = (".stl", ".vtk", ".vtp", ".ply", ".obj", ".off")

_REGION_BODY = {
    "hip": ("pelvis",),
    "thigh": ("femur_{s}",),
    "shank": ("tibia_{s}",),
    "trunk": ("torso", "pelvis"),
}
_ANATOMY = {a.name: a for a in MUSCLES}
#: a group's parts; a muscle is a group of one
_PARTS = {**{a.name: (a.name,) for a in MUSCLES}, **{g.name: g.parts for g in GROUPS}}
_BONE_BODIES = {b.name: b.bodies for b in (*BONES, *LANDMARKS)}


@dataclass
class MeshInfo:
    """One mesh of the folder: what it was taken for, and why."""

    path: Path
    kind: str | None  # "muscle", "bone", "landmark" or None (not recognised)
    match: NameMatch | None
    side: str | None
    V: FloatArray
    F: IntArray
    closed: bool
    why: str = ""
    #: mean thickness (4 V / A; nan when open) and the second principal extent
    thickness: float = float("nan")
    width: float = float("nan")
    #: a tie of names (the entries the name fits alike): where its place may decide
    alike: tuple[str, ...] = ()
    #: the median mean thickness of the folder's closed meshes named as muscles (nan: none)
    muscles_thickness: float = float("nan")
    #: how its place compares with the model's bones (`_bones_by_place`), said where unplaced
    bone_said: str = ""
    #: what its name failed to say: "nothing" (no entry the tables know), "tie" (entries
    #: alike), "" (it named one, or was refused for another reason): where shape and place
    #: may decide instead
    name_failed: str = ""

    @property
    def stem(self) -> str:
        return self.path.name.rsplit(".", 1)[0]

    @property
    def shape(self) -> str:
        """Open, shell or solid.

        A shell is closed and thin: its mean thickness under ``defaults.init_shell`` of
        its width and (where the folder names muscles) under half the median named
        muscle's, so a flat muscle as thick as the others stays a solid.
        """
        if not self.closed:
            return "open"
        thin = self.thickness < defaults.init_shell * self.width
        if not np.isnan(self.muscles_thickness):
            thin = thin and self.thickness < 0.5 * self.muscles_thickness
        return "shell" if thin else "solid"

    def shape_said(self) -> str:
        return (
            f"its mean thickness (4 V / A) {self.thickness:.3g} is "
            f"{self.thickness / self.width:.2g} of its width {self.width:.3g}"
            + (
                f" and {self.thickness / self.muscles_thickness:.2g} of the median named muscle's"
                if not np.isnan(self.muscles_thickness)
                else ""
            )
        )


def survey(folder: Path) -> list[MeshInfo]:
    """Every mesh of ``folder`` (not its subfolders), read and classified."""
    if not folder.is_dir():
        raise SceneError(f"{folder}: no such folder of meshes")
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in MESH_SUFFIXES and p.is_file())
    if not files:
        raise SceneError(f"{folder}: no mesh files ({' '.join(MESH_SUFFIXES)}) in the folder")
    out = []
    for p in files:
        V, F, _ = tidy_mesh(*read_mesh(p))
        chk = check_mesh(V, F)
        closed = chk.boundary_edges == 0
        thick = float(mean_thickness(V, F)) if closed and len(F) else float("nan")
        X = V - V.mean(axis=0)
        width = (
            float(np.ptp(X @ np.linalg.svd(X, full_matrices=False)[2][1])) if len(V) > 2 else 0.0
        )
        stem = p.name.rsplit(".", 1)[0]
        words, side = mesh_name_tokens(stem)
        m, b, g = match_muscle(stem), match_bone(stem), match_group(stem)
        if g is not None and (m is None or _rank(g) > _rank(m)):
            m = g  # several muscles in one mesh (the iliopsoas)
        kind, match, why, failed = None, None, "", ""
        said_muscle, said_bone = "muscle" in words or "muscles" in words, "bone" in words
        if m is not None and (b is None or said_muscle or _rank(m) > _rank(b[0])):
            kind, match = "muscle", m
        elif b is not None:
            match = b[0]
            kind = "landmark" if b[1] else "bone"
        tied: tuple[str, ...] = ()
        if match is not None and match.others:
            # a tie (or a misspelling one letter from another entry): said, not chosen (a
            # muscle's place may choose: `_muscles_by_place`)
            tied = (match.name, *match.others) if kind == "muscle" else ()
            alike = " or the ".join(o.replace("_", " ") for o in match.others)
            kind, match, why, failed = (
                None,
                None,
                (
                    f"its name ('{match.run}') fits the {match.name.replace('_', ' ')} "
                    f"or the {alike} alike: rename it"
                ),
                "tie",
            )
        elif kind is None:
            failed = "nothing"
            why = (
                "its name says muscle but names no muscle the table knows (musclewrap.subject.MUSCLES)"
                if said_muscle
                else "its name says bone but names no bone the table knows"
                if said_bone
                else "its name names no muscle, bone or cartilage the table knows"
            )
        if kind == "muscle" and not closed:
            kind, why = (
                None,
                f"named like a muscle ({m.name}) but not closed ({chk.boundary_edges} boundary edges)",
            )
        out.append(
            MeshInfo(
                p, kind, match, side, V, F, closed, why, thick, width, tied, name_failed=failed
            )
        )
    named = [mi.thickness for mi in out if mi.kind == "muscle"]
    for mi in out:
        mi.muscles_thickness = float(np.median(named)) if named else float("nan")
        if mi.kind == "muscle" and mi.shape == "shell":
            # the shape decides: a muscle is no thin shell (a cartilage, a fascia's sheet)
            assert mi.match is not None
            mi.kind, mi.why = (
                None,
                f"named like a muscle ({mi.match.name}) but by its shape a thin shell, as a "
                f"cartilage is: {mi.shape_said()} (a muscle's is more than "
                f"{defaults.init_shell:g} of its width or half the median's)",
            )
        elif mi.kind is None and mi.shape == "shell" and not mi.alike:
            mi.why += f"; by its shape a thin shell ({mi.shape_said()}): a cartilage? name it"
    _caps_by_shape(out)
    return out


def _caps_by_shape(meshes: list[MeshInfo]) -> None:
    """Where no name gives the hip's cartilage, the roundest cap among the unnamed meshes.

    A mesh whose name says nothing is taken for the femoral head's cartilage when it is
    a cap of a sphere: rms distance from its fitted sphere under
    ``defaults.init_cap_rms`` of the radius and its vertices facing every way (the least
    second moment of their directions from the centre at least 0.15: a band or a sheet
    is not a cap). The femoral head's and the acetabulum's cartilages (concentric, both
    the hip) are caps; a distal femur's cartilage, a patella, a tibia and every VHF
    muscle are not.
    """
    named = any(
        mi.kind == "landmark" and mi.match is not None
        and mi.match.name in ("femoral_head", "acetabulum")
        for mi in meshes
    )  # fmt: skip
    if named:
        return
    best: tuple[float, MeshInfo, float, float] | None = None
    for mi in meshes:
        if mi.kind is not None or mi.name_failed != "nothing":
            continue  # placed, or named (an open muscle, a tie): shape does not overrule names
        if len(mi.V) < 20:
            continue
        c, r, rms = fit_sphere(mi.V)
        if rms < defaults.init_cap_rms * r and cap_spread(mi.V, c) >= 0.15:
            if best is None or rms / r < best[0]:
                best = (rms / r, mi, r, rms)
    if best is None:
        return
    _, mi, r, rms = best
    mi.kind, mi.why = "landmark", ""
    mi.match = NameMatch(
        "femoral_head",
        round(1.0 - rms / r, 3),
        f"by its shape: a spherical cap of radius {r:.3g} (rms {rms:.2g}), the roundest mesh "
        "no name placed, taken for the hip's cartilage",
    )


def _unrecognised(meshes: list[MeshInfo]) -> list[str]:
    """What the scene lists as not placed for the meshes taken for nothing, and why."""
    return [f"{mi.path.name}: {mi.why}" for mi in meshes if mi.kind is None]


def _rank(match: NameMatch) -> tuple[bool, int]:
    """How strongly a name names it: a full spelling before an abbreviation, then its length."""
    return not match.how.startswith("abbreviation"), len(match.run)


@dataclass
class _Muscle:
    info: MeshInfo
    name: str
    side: str
    paths: list[str]
    body: str
    fit: LineFit | None = None


@dataclass
class InitResult:
    """What `init_scene` wrote and what it could not place."""

    scene: Path
    text: str
    muscles: dict[str, tuple[str, ...]]
    bones: dict[str, str]
    unplaced: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    motion_written: Path | None = None


def _rel(p: Path, base: Path) -> str:
    return Path(os.path.relpath(os.path.abspath(p), os.path.abspath(base))).as_posix()


def _q(s: str) -> str:
    return json.dumps(s)


def _paths_by_anatomy(model) -> dict[tuple[str, str | None], list[str]]:  # noqa: ANN001
    out: dict[tuple[str, str | None], list[str]] = {}
    for p in model.path_names:
        a = path_anatomy(p)
        if a is not None:
            out.setdefault((a[0].name, a[1]), []).append(p)
    return out


def _first_body(model, options: Sequence[str], side: str) -> str | None:  # noqa: ANN001
    for o in options:
        b = o.format(s=side)
        if b in model.body_names:
            return b
    return None


def init_scene(
    osim: Path,
    mesh_dir: Path,
    out: Path,
    *,
    motion: Path | None = None,
    model_bones: bool = False,
    log: Callable[[str], None] | None = None,
) -> InitResult:
    """Write a scene for the meshes of ``mesh_dir`` on the model ``osim`` (see module doc).

    Parameters
    ----------
    osim : pathlib.Path
        The OpenSim model.
    mesh_dir : pathlib.Path
        A folder of muscle, bone and cartilage meshes (STL, VTK, VTP, PLY, OBJ, OFF).
    out : pathlib.Path
        The scene file to write (``.toml``).
    motion : pathlib.Path, optional
        The motion to drive the scene with. Without one, a sweep of each driven
        coordinate over its range is written beside the scene
        (``<scene>_sweep.mot``).
    model_bones : bool, optional
        Where no bone of the folder is carried by a body that carries muscles, take
        the model's own meshes of that body (``[bones.NAME] model``), said in the
        scene's comment.
    log : callable, optional
        Receives one line per step.

    Returns
    -------
    InitResult

    Raises
    ------
    SceneError
        If the model cannot be read, the folder holds no mesh, or no muscle of it
        could be matched to the model.
    """
    say = log or (lambda s: None)
    out = Path(out)
    model = OpenSimModel(osim)
    meshes = survey(Path(mesh_dir))
    unmatched: list[str] = []  # recognised, but with no path or body in the model
    sides = [mi.side for mi in meshes if mi.kind == "muscle" and mi.side]
    main_side = max(set(sides), key=sides.count) if sides else "r"
    found_notes: list[str] = []
    muscles = _muscles_to_paths(model, meshes, main_side, unmatched, mesh_dir, found_notes)
    bones = _bones_to_bodies(model, meshes, main_side, unmatched)
    mesh_unit, s, units_note = _mesh_unit(model, muscles, say)
    driven = _driven(model, muscles, bones, motion)
    best, place_note = _placement(model, meshes, muscles, driven, s, main_side, mesh_unit, say)
    # the knee's shell its shape and place gave (`_placement`): a landmark surface too
    listed = [mi for mi, _, _ in bones]
    shaped = [mi for _, mi, _, _ in best.landmarks if not any(mi is b for b in listed)]
    bones += _bones_to_bodies(model, shaped, main_side, unmatched)
    for mi, name, body in _bones_by_place(model, meshes, best, s, main_side):
        while name in {n for _, n, _ in bones}:
            name += "_2"  # a bone the folder has under its name too
        bones.append((mi, name, body))
    if _muscles_by_place(model, meshes, muscles, best, s, main_side, mesh_unit, say):
        driven = _driven(model, muscles, bones, motion)  # new muscles, perhaps new bodies
    unplaced = _unrecognised(meshes) + unmatched
    _refuse_mixed(best, {m.info.path.name: m.fit for m in muscles}, mesh_unit)  # type: ignore[misc]
    from_model = _model_bones(model, muscles, bones, main_side, found_notes) if model_bones else []
    coords = driven.coords
    written = None
    if motion is None:
        written = out.with_name(out.stem + "_sweep.mot")
        _write_sweep(model, coords, best.rest, written)
        motion = written
        say(f"no motion given: a sweep of {', '.join(coords)} written to {written}")

    text = _scene_text(
        out,
        model,
        muscles,
        bones,
        coords,
        driven.locked,
        driven.lacking,
        best,
        mesh_unit,
        motion,
        driven.output_frame,
        unplaced,
        [units_note, place_note, *found_notes],
        written is not None,
        from_model,
    )
    with atomic_path(out) as part:
        part.write_text(text, encoding="utf-8")
    return InitResult(
        out,
        text,
        {m.name: tuple(m.paths) for m in muscles},
        {**{n: b for _, n, b in bones}, **{n: b for n, _, b in from_model}},
        unplaced,
        [units_note, place_note, *found_notes],
        written,
    )


def _muscles_to_paths(
    model: OpenSimModel,
    meshes: list[MeshInfo],
    main_side: str,
    unplaced: list[str],
    mesh_dir: Path,
    notes: list[str],
) -> list[_Muscle]:
    """Each muscle mesh matched to the model's paths of its anatomy (both sides if unsaid).

    What cannot be placed goes to ``unplaced``, what the scene should say (a group of
    muscles in one mesh, a muscle in several) to ``notes``; none placed at all is an error.
    """
    by_anatomy = _paths_by_anatomy(model)
    muscles: list[_Muscle] = []
    for mi in meshes:
        if mi.kind != "muscle":
            continue
        assert mi.match is not None
        parts = _PARTS[mi.match.name]
        a = _ANATOMY[parts[0]]  # a group is carried where its first muscle is
        options = [mi.side] if mi.side else [main_side, "l" if main_side == "r" else "r"]
        # a group follows every path of its muscles
        found = [(s, [p for n in parts for p in by_anatomy.get((n, s), [])]) for s in options]
        found = [(s, p) for s, p in found if p]
        what = mi.match.name.replace("_", " ")
        if not found:
            unplaced.append(
                f"{mi.path.name}: taken for the {what} ({mi.match.how}), "
                f"but {model.path.name} has no path for it"
                + (f" on the {'right' if mi.side == 'r' else 'left'} side" if mi.side else "")
            )
            continue
        side, paths = found[0]
        body = _first_body(model, _REGION_BODY[a.region], side) or "pelvis"
        muscles.append(_Muscle(mi, mi.match.name, side, paths, body))
        if len(found) > 1:
            muscles[-1].paths = [p for _, ps in found for p in ps]  # both sides: resolved by fit
        if len(parts) > 1:
            notes.append(
                f"{mi.path.name}: several muscles in one mesh, the {what} ("
                + ", ".join(n.replace("_", " ") for n in parts)
                + f"): it follows the paths of all of them ({', '.join(paths)})"
            )
    if not muscles:
        unplaced = _unrecognised(meshes) + unplaced
        raise SceneError(
            f"{mesh_dir}: no mesh of the folder could be matched to a muscle path of "
            f"{model.path.name}, so no scene was written"
            + ("" if not unplaced else "; " + "; ".join(unplaced[:5]))
            + (f"; and {len(unplaced) - 5} more" if len(unplaced) > 5 else "")
            + ". Name each mesh by its muscle, bone or cartilage (any prefix, case or "
            "separators: S07_R_gracilis.stl, Subject12_Right_VL.stl, femur-R.stl; the "
            "spellings: musclewrap.subject.MUSCLES), or write the scene by hand "
            "(docs: Scenes)."
        )
    # a muscle named on the other side than most keeps its side in its name
    for m in muscles:
        if m.info.side and m.info.side != main_side:
            m.name = f"{m.name}_{'left' if m.side == 'l' else 'right'}"
    # one muscle in several meshes (its parts segmented apart): each its own scene muscle on
    # the muscle's paths, said
    seen: dict[str, list[_Muscle]] = {}
    for m in muscles:
        seen.setdefault(m.name, []).append(m)
    for name, same in seen.items():
        if len(same) < 2:
            continue
        for i, m in enumerate(same[1:], 2):
            m.name = f"{name}_{i}"
        notes.append(
            f"the {name.replace('_', ' ')} is in {len(same)} meshes ("
            + ", ".join(m.info.path.name for m in same)
            + f"): each follows all of its paths, as {', '.join(m.name for m in same)}; "
            "join them into one mesh where they are one muscle"
        )
    return muscles


def _side_geometry(
    model: OpenSimModel, body: str, main_side: str
) -> list[tuple[str, ModelGeometry | ValueError]]:
    """The model's meshes of ``body`` on ``main_side`` or no side: each found, or why not.

    ``(mesh file, its ModelGeometry or the ValueError that says why it is not on disk)``,
    less the other side's half of a body (``l_pelvis.vtp``). Raises ValueError where the
    model file cannot be read.
    """
    out: list[tuple[str, ModelGeometry | ValueError]] = []
    for file, _ in body_meshes(model.path, body):
        if mesh_name_tokens(Path(file).stem)[1] not in (None, main_side):
            continue
        try:
            out.append((file, model_geometry(model.path, body, file)))
        except ValueError as exc:
            out.append((file, exc))
    return out


def _model_bones(
    model: OpenSimModel,
    muscles: list[_Muscle],
    bones: list[tuple[MeshInfo, str, str]],
    main_side: str,
    notes: list[str],
) -> list[tuple[str, str, str]]:
    """The model's own meshes of the bodies that carry muscles but no bone of the folder.

    ``(scene name, mesh file, body)`` for each mesh the model attaches to such a body
    and that is on disk (`musclewrap.model.geometry_folders`), less those named for the
    other side; what was taken, and what could not be, goes to ``notes``.
    """
    have = {body for mi, _, body in bones if mi.kind == "bone"}
    names = {n for _, n, _ in bones} | {m.name for m in muscles}
    out: list[tuple[str, str, str]] = []
    for body in sorted({m.body for m in muscles} - have):
        for file, g in _side_geometry(model, body, main_side):
            if isinstance(g, ValueError):
                notes.append(f"the model's {file} of {body} not taken: {g}")
                continue
            stem = Path(file).stem
            found = match_bone(stem)
            name = found[0].name if found is not None else stem.lower()
            while name in names:
                name += "_model"
            names.add(name)
            out.append((name, file, body))
    if out:
        notes.append(
            "bones from the model (init --model-bones), where the folder has none for a body "
            "that carries muscles: "
            + ", ".join(f"{n} ({f} of {b})" for n, f, b in out)
            + "; generic meshes: a muscle of this subject may lie into them at rest "
            "(musclewrap check says how far, and at which rest pose of the joints between "
            "they lie clearest of a registration's meshes)"
        )
    return out


def _bones_to_bodies(
    model: OpenSimModel, meshes: list[MeshInfo], main_side: str, unplaced: list[str]
) -> list[tuple[MeshInfo, str, str]]:
    """Each bone or landmark mesh with its scene name and the model's body it is on."""
    bones: list[tuple[MeshInfo, str, str]] = []
    for mi in meshes:
        if mi.kind not in ("bone", "landmark"):
            continue
        assert mi.match is not None
        side = mi.side or main_side
        body = _first_body(model, _BONE_BODIES[mi.match.name], side)
        if body is None:
            unplaced.append(
                f"{mi.path.name}: taken for the {mi.match.name.replace('_', ' ')}, but "
                f"{model.path.name} has no body for it ({', '.join(b.format(s=side) for b in _BONE_BODIES[mi.match.name])})"
            )
            continue
        name = mi.match.name + (
            "" if side == main_side or mi.side is None else f"_{'left' if side == 'l' else 'right'}"
        )
        bones.append((mi, name, body))
    names = [n for _, n, _ in bones]
    for i, (mi, n, b) in enumerate(bones):
        if names.count(n) > 1:  # two files for the same bone: keep both, by file name
            bones[i] = (mi, mi.stem.lower().replace("-", "_").replace(" ", "_"), b)
    return bones


def _mesh_unit(
    model: OpenSimModel, muscles: list[_Muscle], say: Callable[[str], None]
) -> tuple[str, float, str]:
    """The meshes' unit from how far the muscles span against their paths.

    Returns the unit, the scale from model (m) to mesh units, and the scene's note.
    """
    model.set_pose(model.default_pose())
    path_pts = np.vstack([model.path_points(p, "ground") for m in muscles for p in m.paths])
    mesh_pts = np.vstack([m.info.V for m in muscles])
    ratio = float(
        np.linalg.norm(np.ptp(mesh_pts, axis=0)) / np.linalg.norm(np.ptp(path_pts, axis=0))
    )
    mesh_unit = min(UNITS, key=lambda u: abs(np.log(ratio * UNITS[u])))
    s = 1.0 / UNITS[mesh_unit]  # model (m) to mesh units
    say(f"units: the muscles span {ratio:.3g} times their paths: meshes in {mesh_unit}")
    units_note = (
        f"the muscle meshes span {np.linalg.norm(np.ptp(mesh_pts, axis=0)):.4g} (corner to "
        f"corner), their paths {np.linalg.norm(np.ptp(path_pts, axis=0)):.4g} m at the default pose: "
        f"ratio {ratio:.4g}, nearest {s:g} ({mesh_unit})"
    )
    return mesh_unit, s, units_note


class _Driven(NamedTuple):
    """What moves the scene: its coordinates (those the motion has), the locked ones."""

    output_frame: str
    used: set[str]  # the bodies the muscles, bones and paths are on
    coords: list[str]
    locked: list[str]
    lacking: list[str]  # coordinates that move the scene but the motion lacks


def _driven(
    model: OpenSimModel,
    muscles: list[_Muscle],
    bones: list[tuple[MeshInfo, str, str]],
    motion: Path | None,
) -> _Driven:
    """The coordinates between the scene's bodies and its output frame."""
    output_frame = "pelvis" if "pelvis" in model.body_names else "ground"
    used = {m.body for m in muscles} | {b for _, _, b in bones}
    used |= model.path_bodies([p for m in muscles for p in m.paths])
    coords, locked = model.coordinates_between(sorted(used), output_frame)
    lacking: list[str] = []
    if motion is not None:
        mot = read_motion(motion)
        lacking = [c for c in coords if c not in mot.columns]
        coords = [c for c in coords if c in mot.columns]
        if not coords:
            raise SceneError(
                f"{motion}: the motion has none of the coordinates that move the scene "
                f"({', '.join(lacking)})"
            )
    return _Driven(output_frame, used, coords, locked, lacking)


def _placement(
    model: OpenSimModel,
    meshes: list[MeshInfo],
    muscles: list[_Muscle],
    driven: _Driven,
    s: float,
    main_side: str,
    mesh_unit: str,
    say: Callable[[str], None],
) -> tuple[_Placement, str]:
    """Where the meshes are: the candidate placement whose muscles sit best on their paths.

    Also settles the side of each muscle its name did not say (the side whose paths fit)
    and keeps each muscle's fit. Returns the placement and the scene's note on it.
    """
    coords, used, output_frame = driven.coords, driven.used, driven.output_frame
    default = model.default_pose()
    coincident = _coincident_pose(model, sorted(used - {"ground"}), output_frame, coords)
    candidates = _candidates(model, meshes, muscles, coords, default, coincident, s, main_side)
    scores = []
    per_muscle = {m.info.path.name: _fits_in(model, candidates, m, s) for m in muscles}
    fits_by: list[dict[str, LineFit]] = [
        {name: fits[i] for name, fits in per_muscle.items()} for i in range(len(candidates))
    ]
    for fits in fits_by:
        # the part of each path nearest its muscle first (tendons running on past a
        # muscle weigh nothing), the mean gap to break ties
        near = float(np.median([f.near for f in fits.values()]))
        scores.append(near + 0.1 * float(np.median([f.mean for f in fits.values()])))
    k, alike, other = _choose(candidates, scores)
    best, best_fits = candidates[k], fits_by[k]
    say(f"placement: {best.describe()} (score {scores[k]:.3g} {mesh_unit})")
    tried = {id(mi) for c in candidates for _, mi, *_ in c.landmarks if mi.kind is None}
    for _, mi, _, _ in best.landmarks:
        if mi.kind is None:  # the knee's shell that no name placed: its shape and place
            mi.kind, mi.why = "landmark", ""
            mi.match = NameMatch(
                "femur_distal",
                1.0,
                f"by its shape and place: a thin shell ({mi.shape_said()}) that no name "
                "placed, as far from the hip as the model's knee; its centroid, taken for the "
                f"knee, puts the muscles on their paths best of the {len(tried)} such shells",
            )
    _refuse_far(meshes, candidates, fits_by, k, mesh_unit)
    place_note = (
        f"placement: {best.describe()}: the median muscle's paths come within "
        f"{np.median([f.near for f in best_fits.values()]):.3g} {mesh_unit} of it for a quarter of "
        f"their length and run {np.median([f.mean for f in best_fits.values()]):.3g} {mesh_unit} "
        "outside it on average"
        + (
            f"; {alike} other turns of the axes end within {defaults.init_alike_deg:g} deg of it after the "
            f"landmarks' correction; this one needs the least ({best.correction:.1f} deg)"
            if alike
            else ""
        )
        + (
            f"; the next best, {candidates[other].describe()}, scores {scores[other]:.3g} against "
            f"{scores[k]:.3g} {mesh_unit}"
            if other is not None
            else ""
        )
    )
    # sides not given by a name: the side whose paths fit
    for m in muscles:
        fit = best_fits[m.info.path.name]
        if m.info.side is None and len({path_anatomy(p)[1] for p in m.paths}) > 1:  # type: ignore[index]
            per = {}
            for sd in ("r", "l"):
                ps = [p for p in m.paths if path_anatomy(p)[1] == sd]  # type: ignore[index]
                per[sd] = (_fit_in(model, best, _Muscle(m.info, m.name, sd, ps, m.body), s), ps)
            sd = min(per, key=lambda k: per[k][0].near)
            m.side, m.paths = sd, per[sd][1]
            region = _ANATOMY[_PARTS[m.info.match.name][0]].region  # type: ignore[union-attr]
            m.body = _first_body(model, _REGION_BODY[region], sd) or m.body
            fit = per[sd][0]
        m.fit = fit
    return best, place_note


def _refuse_far(
    meshes: list[MeshInfo],
    candidates: list[_Placement],
    fits_by: list[dict[str, LineFit]],
    k: int,
    mesh_unit: str,
) -> None:
    """Stop where no placement puts the muscles on their paths (``defaults.init_far``).

    A scene would put them a body's length off: the error says what was found and what
    a registration needs.
    """
    fits = fits_by[k]
    near = float(np.median([f.near for f in fits.values()]))
    extent = float(np.median([f.extent for f in fits.values()]))
    if not near > defaults.init_far * extent:
        return
    marks = sorted(
        f"{mi.path.name} ({mi.match.name.replace('_', ' ')})"
        for mi in meshes
        if mi.kind == "landmark" and mi.match is not None
    )
    unknown = sorted(mi.path.name for mi in meshes if mi.kind is None)
    tried = "; ".join(
        f"{c.describe()}: {float(np.median([f.near for f in fb.values()])):.3g} {mesh_unit}"
        for c, fb in zip(candidates, fits_by, strict=True)
        if c.kind != "registration"
    )
    raise SceneError(
        "init: no placement puts the muscles on their paths, so no scene was written. The "
        f"best, {candidates[k].describe()}, leaves the median muscle's paths {near:.3g} "
        f"{mesh_unit} from it ({near / extent:.2g} of its length; "
        f"{defaults.init_far:g} is the most taken). Tried: {tried}. "
        + (
            f"Landmark surfaces found: {', '.join(marks)}. "
            if marks
            else "No landmark surface found. "
        )
        + "The meshes look like another subject's, in its own frame: a registration needs "
        "the femoral head's cartilage (or the acetabulum's) for the hip centre and the distal "
        "femur's cartilage for the knee, named so (e.g. R_FemoralHead_Cartilage.stl, "
        "R_FemurDistal_Cartilage.stl) or, unnamed, a thin shell as far from the hip as the "
        "knee, or a whole femur named so"
        + (f"; not recognised by name: {', '.join(unknown)}" if unknown else "")
        + "."
    )


def _refuse_mixed(best: _Placement, fits: dict[str, LineFit], mesh_unit: str) -> None:
    """Stop where the placement puts most muscles on their paths and some far off them.

    Meshes of two subjects (or two frames) in one folder: no one placement holds for
    all, and a scene would put some a body's length off their paths.
    """
    far = {n: f for n, f in fits.items() if f.near > defaults.init_far * f.extent}
    if not far or len(far) == len(fits):
        return
    good = [f for n, f in fits.items() if n not in far]
    raise SceneError(
        f"init: the meshes are not in one frame, so no scene was written: placed as "
        f"{best.describe()}, {len(good)} muscles lie on their paths (within "
        f"{max(f.near for f in good):.3g} {mesh_unit}) and {len(far)} far off them: "
        + ", ".join(f"{n} ({f.near:.3g} {mesh_unit})" for n, f in sorted(far.items()))
        + ". A folder of two subjects' meshes, or of meshes exported in two frames? Give init "
        "one subject's meshes in one frame (a folder each), or move the others out."
    )


def _bones_by_place(
    model: OpenSimModel, meshes: list[MeshInfo], best: _Placement, s: float, main_side: str
) -> list[tuple[MeshInfo, str, str]]:
    """Closed solids no name places that lie where a bone of the model lies: that bone.

    Each is compared with the model's own meshes of each body (`body_meshes`; the main
    side's bodies and those of no side), placed as ``best`` places the meshes: the mean
    distance from its vertices to the body's and from the body's to its, the larger,
    over its diagonal. Under ``defaults.init_bone_place`` it is that body's bone, unless
    another body's is too (then it is said, not chosen). ``(mesh, scene name, body)``
    for each; nothing where the model's meshes are not on disk.
    """
    weighed = [
        mi
        for mi in meshes
        if mi.kind is None and mi.shape == "solid" and mi.name_failed == "nothing"
    ]
    if not weighed:
        return []
    points = _model_bone_points(model, best, s, main_side)
    out = []
    limit = defaults.init_bone_place
    for mi in weighed:
        score = _bone_scores(mi, points)
        near = sorted(score, key=score.__getitem__)
        if not near:
            mi.bone_said = "the model's bone meshes were not found to compare it with"
            continue
        if score[near[0]] >= limit:
            mi.bone_said = (
                f"no model bone lies where it lies (the nearest, {points[near[0]][1]} of "
                f"{near[0]}, {score[near[0]]:.2g} of its size away on average; {limit:g} taken)"
            )
            continue
        if len(near) > 1 and score[near[1]] < limit:
            mi.why += (
                f"; by its place the model's bone of {near[0]} or of {near[1]} alike "
                f"({score[near[0]]:.2g}, {score[near[1]]:.2g} of its size apart): name it"
            )
            continue
        body, file = near[0], points[near[0]][1]
        found = match_bone(file) or match_bone(body)
        name = found[0].name if found is not None else body
        mi.kind, mi.why = "bone", ""
        mi.match = NameMatch(
            name,
            round(1.0 - score[body] / limit, 3),
            f"by its shape and place: a closed solid ({mi.shape_said()}) that no name placed, "
            f"lying where the model's {file} of {body} lies (the two {score[body]:.2g} of its "
            f"size apart on average, the next body's {score[near[1]]:.2g})"
            if len(near) > 1
            else f"by its shape and place: lying where the model's {file} of {body} lies",
        )
        out.append((mi, name, body))
    return out


def _model_bone_points(
    model: OpenSimModel, best: _Placement, s: float, main_side: str
) -> dict[str, tuple[FloatArray, str]]:
    """The model's own meshes' vertices per body, where ``best`` puts the folder's meshes.

    ``body -> (points in mesh coordinates, its first mesh's file stem)`` for the main
    side's bodies and those of no side; empty where the model's meshes are not on disk
    or its file is one only OpenSim reads.
    """
    model.set_pose(best.rest)
    points: dict[str, tuple[FloatArray, str]] = {}
    for body in model.body_names:
        if mesh_name_tokens(body)[1] not in (None, main_side):
            continue
        parts, first = [], ""
        try:
            files = _side_geometry(model, body, main_side)
        except ValueError:
            return {}
        for file, g in files:
            if isinstance(g, ValueError):
                continue
            try:
                parts.append(read_mesh(g.path)[0] * np.asarray(g.scale))
            except (ValueError, SceneError):
                continue
            first = first or Path(file).stem
        if not parts:
            continue
        P = np.vstack(parts)
        if best.kind != "body":
            P = apply_transform(model.transform(body, "ground"), P)
        P = P * s
        if best.T is not None:
            P = apply_transform(np.linalg.inv(best.T), P)
        points[body] = (P, first)
    return points


def _bone_scores(mi: MeshInfo, points: dict[str, tuple[FloatArray, str]]) -> dict[str, float]:
    """Per body, how far the mesh and the model's bone lie apart, over the mesh's diagonal.

    The mean distance from the mesh's vertices to the bone's and from the bone's to its,
    the larger: small only where the two are the same bone.
    """
    from scipy.spatial import cKDTree

    tree, diag = cKDTree(mi.V), float(np.linalg.norm(np.ptp(mi.V, axis=0)))
    out = {}
    for body, (P, _) in points.items():
        d1 = float(cKDTree(P).query(mi.V)[0].mean())
        d2 = float(tree.query(P)[0].mean())
        out[body] = max(d1, d2) / diag
    return out


def _muscles_by_place(
    model: OpenSimModel,
    meshes: list[MeshInfo],
    muscles: list[_Muscle],
    best: _Placement,
    s: float,
    main_side: str,
    mesh_unit: str,
    say: Callable[[str], None],
) -> bool:
    """Where names fail, the muscle whose paths run along the mesh: its place decides.

    The meshes weighed: those no name places (the name says nothing, or fits two
    muscles alike) that are closed solids and no bone (`_bones_by_place`), and the named
    muscles whose paths do not run along them (further than
    ``defaults.check_far_thicknesses`` of their mean thickness, what `musclewrap check`
    refuses). A mesh may take any muscle of the model that no other mesh took by name,
    if that muscle's paths come within ``defaults.check_far_thicknesses`` of its mean
    thickness (4 V / A) for a quarter of their length; it costs that distance plus a
    tenth of the paths' mean distance outside it (the placement's score), in its
    thicknesses, and taking none costs one. The meshes get the muscles of the least
    total (a one-to-one assignment: a neighbour's path that passes through a muscle goes
    to its own muscle). A mesh is taken for its muscle unless the best assignment that
    gives it another costs less than ``defaults.init_place_tie`` more (then it fits two
    alike, and is placed nowhere); the scene's comment says the next best either way.
    Updates ``meshes`` and ``muscles``; True when anything changed.
    """
    from scipy.optimize import linear_sum_assignment

    by_anatomy = _paths_by_anatomy(model)
    far = defaults.check_far_thicknesses
    single = [m for m in muscles if m.info.match is not None and m.info.match.name in _ANATOMY]
    contested = [m for m in single if m.fit is not None and m.fit.near > far * m.info.thickness]
    # the named muscles whose paths run along a contested mesh: the names that may move
    anyside = {(n, m.side) for m in contested for n in _ANATOMY if (n, m.side) in by_anatomy}
    along = _feasible(model, best, s, contested, anyside, by_anatomy)
    holders = [
        m for m in single
        if m not in contested and any((m.info.match.name, m.side) in a for a in along.values())  # type: ignore[union-attr]
    ]  # fmt: skip
    moving = contested + holders
    taken = {n for m in muscles if m not in moving for n in _PARTS[m.info.match.name]}  # type: ignore[union-attr]
    released = {(m.info.match.name, m.side) for m in contested}  # type: ignore[union-attr]
    weighed = [
        mi
        for mi in meshes
        if mi.kind is None and mi.shape == "solid" and (mi.alike or mi.name_failed == "nothing")
    ] + [m.info for m in moving]

    def options(mi: MeshInfo) -> list[tuple[str, str]]:
        held = next((m for m in holders if m.info is mi), None)
        if held is not None:  # its own name, or one a contested mesh gave up
            return sorted({(held.info.match.name, held.side)} | released)  # type: ignore[union-attr]
        sd = mi.side or main_side
        names = [n for n in mi.alike if n in _ANATOMY] if mi.alike else sorted(_ANATOMY)
        return [(n, sd) for n in names if n not in taken and (n, sd) in by_anatomy]

    cols = sorted({o for mi in weighed for o in options(mi)})
    if not weighed or not cols:
        return False
    n, big = len(cols), 1e6
    # a column per muscle, then one per mesh for "none of them" (cost 1; a named mesh
    # whose paths run along it keeps a muscle: its own, or one a contested mesh gave up)
    cost = np.full((len(weighed), n + len(weighed)), big)
    for i, mi in enumerate(weighed):
        cost[i, n + i] = big if any(m.info is mi for m in holders) else 1.0
    fits: dict[tuple[int, int], LineFit] = {}
    for i, mi in enumerate(weighed):
        opts = options(mi)
        lines = [
            _lines_in(model, best, _muscle_on(model, mi, a, sd, by_anatomy), s) for a, sd in opts
        ]
        for o, f in zip(opts, line_fits(mi.V, mi.F, lines), strict=True):
            j = cols.index(o)
            fits[i, j] = f
            if f.near <= far * mi.thickness:
                cost[i, j] = (f.near + 0.1 * f.mean) / mi.thickness
    rows, picked = linear_sum_assignment(cost)
    total = float(cost[rows, picked].sum())
    changed = False
    for i, j in zip(rows.tolist(), picked.tolist(), strict=True):
        mi = weighed[i]
        named = next((m for m in moving if m.info is mi), None)
        if j >= n:  # none: no free path runs along it
            if named is None and any(k[0] == i for k in fits):
                k0, f0 = min(
                    ((k, f) for k, f in fits.items() if k[0] == i), key=lambda kf: kf[1].near
                )
                went = [weighed[r] for r, c in zip(rows, picked, strict=True) if c == k0[1]]
                mi.why += (
                    f"; by its shape a closed solid ({mi.shape_said()}); "
                    + (mi.bone_said or "the model's bone meshes were not found to compare it with")
                    + "; along it runs no path of the model that no other mesh took "
                    f"(the nearest, the {cols[k0[1]][0].replace('_', ' ')}'s, come within "
                    f"{f0.near:.3g} {mesh_unit} for a quarter of their length, "
                    f"{f0.near / mi.thickness:.2g} of its mean thickness; {far:g} taken"
                    + (f"; they run along {went[0].path.name} better" if went else "")
                    + "): a muscle the model lacks, or a bone? name it"
                )
            continue
        name, sd = cols[j]
        what = name.replace("_", " ")
        if named is not None and named.info.match.name == name:  # type: ignore[union-attr]
            continue  # its place agrees with its name after all
        banned = cost.copy()
        banned[i, j] = big
        r2, c2 = linear_sum_assignment(banned)
        margin = float(banned[r2, c2].sum()) - total
        k2 = int(c2[list(r2).index(i)])
        other = f"the {cols[k2][0].replace('_', ' ')}" if k2 < n else None
        nxt = f"it {other}" if other else "it placed nowhere"
        if margin < defaults.init_place_tie:
            if named is None:
                mi.why += (
                    f"; by its place it fits the {what} "
                    + (f"or {other} alike" if other else "barely (as well as no muscle)")
                    + f" (the next best assignment costs {margin:.2g} of its mean thickness "
                    "more): name it"
                )
            continue
        fit = fits[i, j]
        how = (
            f"by its place, not its name: its paths' nearest quarter within "
            f"{fit.near / mi.thickness:.2g} of its mean thickness; the next best assignment, "
            f"{nxt}, costs {margin:.2g} thicknesses more (name the file to be sure)"
        )
        if named is not None:
            gap = named.fit.near / mi.thickness  # type: ignore[union-attr]
            how = (
                f"named the {named.info.match.name.replace('_', ' ')} ({named.info.match.how})"  # type: ignore[union-attr]
                + (
                    f", whose paths run {gap:.2g} of its mean thickness from it at best,"
                    if gap > far
                    else " (a mesh whose name its place rejects takes that muscle),"
                )
                + f" but {how}"
            )
            muscles.remove(named)
        mi.kind, mi.why = "muscle", ""
        mi.match = NameMatch(name, round(max(0.0, 1.0 - float(cost[i, j])), 3), how, "")
        m = _muscle_on(model, mi, name, sd, by_anatomy)
        m.fit = fit
        if sd != main_side:
            m.name = f"{name}_{'left' if sd == 'l' else 'right'}"
        muscles.append(m)
        say(f"{mi.path.name}: the {what}, {how}")
        changed = True
    return changed


def _feasible(
    model: OpenSimModel,
    best: _Placement,
    s: float,
    muscles: list[_Muscle],
    anatomies: set[tuple[str, str]],
    by_anatomy: dict,
) -> dict[str, set[tuple[str, str]]]:
    """Per muscle's mesh, the muscles of ``anatomies`` whose paths run along it.

    Along: within ``defaults.check_far_thicknesses`` of its mean thickness for a quarter
    of their length.
    """
    out: dict[str, set[tuple[str, str]]] = {}
    opts = sorted(anatomies)
    for m in muscles:
        mi = m.info
        lines = [
            _lines_in(model, best, _muscle_on(model, mi, a, sd, by_anatomy), s) for a, sd in opts
        ]
        fits = line_fits(mi.V, mi.F, lines) if lines else []
        out[mi.path.name] = {
            o for o, f in zip(opts, fits, strict=True)
            if f.near <= defaults.check_far_thicknesses * mi.thickness
        }  # fmt: skip
    return out


def _muscle_on(
    model: OpenSimModel, mi: MeshInfo, name: str, side: str, by_anatomy: dict
) -> _Muscle:
    """The scene muscle ``mi`` makes as the ``name`` of ``side`` (its paths, its region's body)."""
    body = _first_body(model, _REGION_BODY[_ANATOMY[name].region], side) or "pelvis"
    return _Muscle(mi, name, side, list(by_anatomy[(name, side)]), body)


# ------------------------------------------------------------------------ placements
@dataclass
class _Placement:
    kind: str  # "body", "ground" or "registration"
    rest: dict[str, float]  # model units
    why_rest: str
    T: FloatArray | None = None  # registration: mesh -> ground (mesh units)
    axes: tuple[str, str, str] | None = None
    correction: float = 0.0  # registration: degrees the landmarks turn the axes' rotation by
    landmarks: list[tuple[str, MeshInfo, str, str]] = field(default_factory=list)

    def describe(self) -> str:
        if self.kind == "registration":
            return f"meshes in another subject's frame, registered by {' and '.join(n for n, *_ in self.landmarks)} with axes {list(self.axes or ())}"
        if self.kind == "body":
            return f"meshes in their bodies' frames at {self.why_rest}"
        return f"meshes in the model's ground frame at {self.why_rest}"


def _rotation(T: FloatArray) -> FloatArray:
    """The rotation of a similarity (its scale divided out)."""
    return T[:3, :3] / np.cbrt(np.linalg.det(T[:3, :3]))


def _turn(R: FloatArray) -> float:
    """A rotation's angle, degrees."""
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1.0, 1.0))))


def _choose(cands: list[_Placement], scores: list[float]) -> tuple[int, int, int | None]:
    """The placement to take, how many others are the same one, and the next best distinct one.

    Turns of the axes that the landmarks correct onto the same rotation (within
    ``defaults.init_alike_deg``) are one placement: the fit picks the placement (two landmarks leave
    the turn about the line through them open), and of its turns of the axes the one
    the landmarks turn least, the frame's own axes (the fit's differences among them,
    a few degrees apart, depend on which muscles the folder holds). The order of
    ``cands`` breaks ties.
    """
    order = sorted(range(len(cands)), key=lambda i: scores[i])
    best = order[0]

    def same(i: int, j: int) -> bool:
        a, b = cands[i], cands[j]
        if a.kind != b.kind or a.rest != b.rest:
            return False
        if [mi.path for _, mi, *_ in a.landmarks] != [mi.path for _, mi, *_ in b.landmarks]:
            return False
        if a.T is None or b.T is None:
            return a.T is None and b.T is None
        return _turn(_rotation(a.T) @ _rotation(b.T).T) < defaults.init_alike_deg

    group = [i for i in order if same(i, best)]
    pick = min(group, key=lambda i: (cands[i].correction, order.index(i)))
    other = next((i for i in order if not same(i, best)), None)
    return pick, len(group) - 1, other


def _coincident_pose(
    model, bodies: list[str], root: str, coords: list[str]
) -> tuple[dict[str, float], float] | None:  # noqa: ANN001
    """The pose where every body of ``bodies`` coincides with ``root``, if there is one.

    A model built in its scan's frame (the LHDL hip model) has one: the scanned pose.
    Returns the pose and the largest residual (rotation entries and metres).
    """
    from scipy.optimize import least_squares

    others = [b for b in bodies if b != root]
    if not others or not coords:
        return None
    base = model.default_pose()

    def residual(q: FloatArray) -> FloatArray:
        model.set_pose({**base, **dict(zip(coords, q, strict=True))})
        out = []
        for b in others:
            T = model.transform(b, root)
            out += [(T[:3, :3] - np.eye(3)).ravel(), T[:3, 3]]
        return np.concatenate(out)

    q0 = np.array([base[c] for c in coords])
    sol = least_squares(residual, q0, xtol=1e-12, ftol=1e-12, gtol=1e-12)
    model.set_pose(base)
    # within 1e-4 (rad, m): the bodies' frames meet; the LHDL model's meet to 1e-6
    miss = float(np.abs(sol.fun).max())
    if miss > 1e-4:
        return None
    return {**base, **dict(zip(coords, sol.x.tolist(), strict=True))}, miss


def _candidates(
    model,
    meshes: list[MeshInfo],
    muscles: list[_Muscle],
    coords: list[str],  # noqa: ANN001
    default: dict[str, float],
    coincident: tuple[dict[str, float], float] | None,
    s: float,
    side: str,
) -> list[_Placement]:
    out = [
        _Placement("body", default, "the default pose"),
        _Placement("ground", default, "the default pose"),
    ]
    if coincident is not None:
        pose, miss = coincident
        why = f"the pose where the scene's bodies coincide (to {miss:.2g} rad and m)"
        out.insert(0, _Placement("body", pose, why))
    for marks in _landmark_sets(model, meshes, side, s):
        model.set_pose(default)
        P = np.array([point for _, _, point, _, _ in marks])
        Q = np.array([model.transform(b, "ground")[:3, 3] * s for _, _, _, b, _ in marks])
        for axes in _proper_axes():
            R0 = axes_rotation(axes)
            T = similarity(P, Q, R0)
            out.append(
                _Placement(
                    "registration",
                    default,
                    "the default pose",
                    T,
                    axes,
                    _turn(_rotation(T) @ R0.T),
                    [(n, mi, fit, b) for n, mi, _, b, fit in marks],
                )
            )
    return out


def _landmark_sets(
    model, meshes: list[MeshInfo], side: str, s: float
) -> list[list[tuple[str, MeshInfo, FloatArray, str, str]]]:  # noqa: ANN001
    """The sets of hip and knee landmarks a registration may be built from.

    The landmarks the names (or the hip's cap's shape) give; where they give the hip
    and no knee, one set per thin shell no name placed whose centroid lies as far from
    the hip as the model's knee from its hip (0.5-1.5 times, in mesh units: subjects
    differ by less) as that knee: the distal femur's cartilage by its shape and place.
    The placement's fit chooses among them.
    """
    found = _landmarks(model, meshes, side)
    if len(found) != 1 or found[0][0] != "hip" or f"tibia_{side}" not in model.body_names:
        return [found] if len(found) >= 2 else []
    model.set_pose(model.default_pose())
    femur = model.transform(f"femur_{side}", "ground")[:3, 3]
    expect = float(np.linalg.norm(model.transform(f"tibia_{side}", "ground")[:3, 3] - femur)) * s
    hip = found[0][2]
    sets = []
    for mi in meshes:
        if mi.kind is not None or mi.shape != "shell" or not mi.name_failed:
            continue
        point, _ = landmark_point(mi.V, mi.F, "centroid", "knee", mi.path)
        if 0.5 * expect <= float(np.linalg.norm(point - hip)) <= 1.5 * expect:
            sets.append([found[0], ("knee", mi, point, f"tibia_{side}", "centroid")])
    return sets


def _landmarks(
    model, meshes: list[MeshInfo], side: str
) -> list[tuple[str, MeshInfo, FloatArray, str, str]]:  # noqa: ANN001
    """The hip and knee landmarks found among the meshes: (name, mesh, point, body, fit)."""
    # landmark surface -> (landmark, fit, the body whose origin it marks)
    marks = {
        "femoral_head": ("hip", "sphere", "femur"),
        "acetabulum": ("hip", "sphere", "femur"),
        "femur_distal": ("knee", "centroid", "tibia"),
    }
    found: dict[str, tuple[str, MeshInfo, FloatArray, str, str]] = {}
    for mi in meshes:
        if mi.kind != "landmark" or (mi.side or side) != side or mi.match is None:
            continue
        if mi.match.name not in marks:
            continue
        name, fit, bone = marks[mi.match.name]
        body = f"{bone}_{side}"
        # the femoral head before the acetabulum; a surface that is no sphere is no hip
        if body not in model.body_names or (name in found and mi.match.name == "acetabulum"):
            continue
        try:
            point, _ = landmark_point(mi.V, mi.F, fit, name, mi.path)
        except SceneError:
            continue
        found[name] = (name, mi, point, body, fit)
    if len(found) < 2:
        # no cartilage for one of them: a whole femur's head (the hip) and condyles (the knee)
        for mi in meshes:
            if mi.kind != "bone" or mi.match is None or mi.match.name != "femur":
                continue
            if (mi.side or side) != side or f"tibia_{side}" not in model.body_names:
                continue
            try:
                hip, knee, _ = femur_landmarks(mi.V, mi.F, mi.path)
            except SceneError:
                continue
            found.setdefault("hip", ("hip", mi, hip, f"femur_{side}", "femoral_head"))
            found.setdefault("knee", ("knee", mi, knee, f"tibia_{side}", "femur_distal"))
            break
    return [found[k] for k in ("hip", "knee") if k in found]


def _proper_axes() -> list[tuple[str, str, str]]:
    """The 24 turns of the axes onto each other (signed permutations of det +1)."""
    out = []
    for perm in itertools.permutations("xyz"):
        for signs in itertools.product(("", "-"), repeat=3):
            axes = tuple(sg + a for sg, a in zip(signs, perm, strict=True))
            if np.isclose(np.linalg.det(axes_rotation(axes)), 1.0):
                out.append(axes)  # type: ignore[arg-type]
    return out  # type: ignore[return-value]


def _lines_in(model, cand: _Placement, m: _Muscle, s: float) -> dict[str, FloatArray]:  # noqa: ANN001
    """The muscle's rest paths in its mesh's coordinates under a placement."""
    model.set_pose(cand.rest)
    lines = {}
    for p in m.paths:
        if cand.kind == "body":
            P = model.path_points(p, m.body) * s
        else:
            P = model.path_points(p, "ground") * s
            if cand.T is not None:
                Ti = np.linalg.inv(cand.T)
                P = apply_transform(Ti, P)
        lines[p] = P
    return lines


def _fits_in(model, cands: list[_Placement], m: _Muscle, s: float) -> list[LineFit]:  # noqa: ANN001
    """The muscle's paths against its mesh under each placement."""
    return line_fits(m.info.V, m.info.F, [_lines_in(model, c, m, s) for c in cands])


def _fit_in(model, cand: _Placement, m: _Muscle, s: float) -> LineFit:  # noqa: ANN001
    return _fits_in(model, [cand], m, s)[0]


# ------------------------------------------------------------------------ writing
def _write_sweep(model, coords: list[str], rest: dict[str, float], path: Path) -> None:  # noqa: ANN001
    """Each coordinate from its rest value to the ends of its range and back, in turn."""
    rows = []
    n = 21
    for c in coords:
        lo, hi = model.coordinate_range(c)
        r0 = rest[c]
        go = np.concatenate([
            np.linspace(r0, hi, n // 2 + 1), np.linspace(hi, lo, n)[1:], np.linspace(lo, r0, n // 2 + 1)[1:]
        ])  # fmt: skip
        for v in go:
            rows.append({**{k: rest[k] for k in coords}, c: v})
    values = {
        c: np.array([np.degrees(r[c]) if model.is_rotational(c) else r[c] for r in rows])
        for c in coords
    }
    times = np.arange(len(rows)) / 30.0
    write_motion(path, times, values, in_degrees=True)


def _num(x: float) -> str:
    return repr(round(float(x), 3) + 0.0)


def _scene_text(
    out: Path,
    model,
    muscles: list[_Muscle],
    bones: list[tuple[MeshInfo, str, str]],  # noqa: ANN001
    coords: list[str],
    locked: list[str],
    lacking: list[str],
    place: _Placement,
    mesh_unit: str,
    motion: Path,
    output_frame: str,
    unplaced: list[str],
    notes: list[str],
    swept: bool,
    from_model: list[tuple[str, str, str]] = (),  # type: ignore[assignment]
) -> str:
    base = Path(os.path.abspath(out)).parent
    unit = mesh_unit
    L = [
        f"# Written by `musclewrap init {model.path.name} ...`: every guess below says how sure it is.",
        "# Check it with `musclewrap check " + out.name + "` before a run.",
    ]
    for n in notes:
        L.append("# " + n)
    if unplaced:
        L.append(f"# NOT PLACED ({len(unplaced)}): these files are not in the scene:")
        L += [f"#   {u}" for u in unplaced]
    L += [f"name = {_q(out.stem)}", "", "[units]", f"mesh = {_q(mesh_unit)}", 'model = "m"', ""]
    L += ["[model]", f"osim = {_q(_rel(model.path, base))}", f"motion = {_q(_rel(motion, base))}"]
    if swept:
        L.append("# (no motion was given: each coordinate swept over its range, written by init)")
    L.append(f"coordinates = [{', '.join(_q(c) for c in coords)}]")
    if locked:
        L.append(f"# locked in the model, held still: {', '.join(locked)}")
    if lacking:
        L.append(f"# NOT DRIVEN: the motion lacks {', '.join(lacking)} (held at the rest pose)")
    deg = {
        c: (np.degrees(place.rest[c]) if model.is_rotational(c) else place.rest[c]) for c in coords
    }
    L.append(f"# the rest pose (degrees): {place.why_rest}")
    L.append("rest_pose = { " + ", ".join(f"{c} = {_num(v)}" for c, v in deg.items()) + " }")
    L.append(f"output_frame = {_q(output_frame)}")
    if place.kind != "body":
        L.append(f"mesh_frame = {_q(place.kind)}")
    L.append("")
    if place.kind == "registration":
        L += ["[registration]", f"axes = [{', '.join(_q(a) for a in place.axes or ())}]"]
        for name, mi, fit, body in place.landmarks:
            L += [
                "",
                "[[registration.landmark]]",
                f"name = {_q(name)}",
                f"mesh = {_q(_rel(mi.path, base))}",
                f"fit = {_q(fit)}",
                f"body = {_q(body)}               # its origin",
            ]
        L.append("")
    for m in muscles:
        f = m.fit
        assert f is not None and m.info.match is not None
        L.append(
            f"# {m.info.path.name}: the {m.name.replace('_', ' ')} "
            + (
                m.info.match.how
                if m.info.match.how.startswith(("by its place", "named the "))
                else f"by name ({m.info.match.how})"
            )
            + "; "
            f"at rest its paths run {100 * f.inside:.0f} % inside it, a quarter of their length "
            f"within {f.near:.3g} {unit}, the farthest point {f.far:.3g} {unit} out; paths "
            f"{f.length:.4g} {unit} long, the muscle {f.extent:.4g}"
        )
        L += [
            f"[muscles.{m.name}]",
            f"mesh = {_q(_rel(m.info.path, base))}",
            f"paths = [{', '.join(_q(p) for p in m.paths)}]",
            f"body = {_q(m.body)}",
            "",
        ]
    for mi, name, body in bones:
        assert mi.match is not None
        what = "landmark surface" if mi.kind == "landmark" else "bone"
        L.append(
            f"# {mi.path.name}: a {what}, the {mi.match.name.replace('_', ' ')} "
            + (
                mi.match.how
                if mi.match.how.startswith(("by its shape", "by its place"))
                else f"by name ({mi.match.how})"
            )
            + f", carried by {body}"
        )
        L += [f"[bones.{name}]", f"mesh = {_q(_rel(mi.path, base))}", f"body = {_q(body)}", ""]
    for name, file, body in from_model:
        L.append(
            f"# the model's own {file} of {body} (init --model-bones): the folder has no bone for it"
        )
        L += [f"[bones.{name}]", f"model = {_q(file)}", f"body = {_q(body)}"]
        if name in _LONG_BONES:
            L.append('fit = "shaft"    # generic: its shaft moved out of these muscles at rest')
        L.append("")
    return "\n".join(L).rstrip() + "\n"


#: the model's bones `init --model-bones` fits along their shaft (`musclewrap.model.fit_shaft`)
_LONG_BONES = ("femur", "tibia", "fibula")
