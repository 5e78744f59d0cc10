"""Reading a scene's inputs: meshes (cleaned, cached), the motion, the rest overlap.

Everything here runs in the client (the process that reads the scene file); what it
gives (`Inputs`) is planned into tasks by `._plan`.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from .._cache import cached_arrays, digest
from .._hashing import cache_key, cache_version
from .._paths import overwrite_clash
from .._typing import FloatArray, IntArray
from ..conditions import placement_problem
from ..constants import defaults
from ..contact import (
    ContactReport,
    Obstacle,
    Placed,
    RestPair,
    anchors_at_rest,
    apart_at_rest,
    bone_surface,
    kept_allowance,
    rest_push_out,
)
from ..errors import SceneError
from ..mesh import (
    MeshError,
    WindingGrid,
    apply_transform,
    check_mesh,
    clean_mesh,
    drop_repeated_faces,
    invert_rigid,
    read_mesh,
    self_intersecting_faces,
    tidy_mesh,
    vertex_origins,
)
from ..model import ShaftFit, fit_shaft
from ..scene import BoneSpec, Drive, MuscleSpec, Scene, drive_scene
from ._execute import Node, Runner
from ._files import TOP_FILES
from ._records import BoneMesh
from ._work import ProbeBone, bone_probe

__all__ = ["Inputs", "default_cache_dir", "fit_bones", "read_inputs"]


@dataclass
class Inputs:
    """A scene read: meshes in their bodies' frames, the motion, the rest-pose outcome.

    ``contact`` is None without collisions, else per muscle the bones it is kept
    out of with each one's allowance; ``anchors`` per muscle its vertices held at
    the bone its body carries (see `_rest_overlap`); ``cage_around`` per muscle
    taken apart from others at rest, its positions before (`_apart_at_rest`).
    """

    scene: Scene
    drive: Drive
    muscles: dict[str, tuple[FloatArray, IntArray]]
    bones: dict[str, BoneMesh]
    input_ids: dict[str, IntArray]
    contact: dict[str, dict[str, FloatArray | None]] | None
    anchors: dict[str, IntArray] | None
    cache: Path | None
    key: str
    cage_around: dict[str, FloatArray] = dataclasses.field(default_factory=dict)


def read_inputs(
    scene: Scene,
    frames: str | None,
    cache: Path | None,
    collisions: bool,
    say: Callable[[str], None],
    notes: list[str],
    runner: Runner | None = None,
    muscles_apart: bool = False,
    keep_poser: bool = False,
) -> Inputs:
    """Read every mesh of ``scene``, drive it over ``frames``, settle the rest overlap.

    ``collisions``: the muscles kept out of their bones; ``muscles_apart``: out of each
    other (then muscles that cannot be are refused, `check_muscles_apart`, and those
    that overlap at rest are taken apart once, `_apart_at_rest`). The per-mesh work
    (cleaning or repairing a muscle, reading and closing a bone, each muscle's rest
    overlap) runs as tasks through ``runner`` (a
    `._execute.Runner`: on the run's workers, while they deform the scenes read
    before), or here when it is None; the motion is driven here. ``keep_poser``: the
    drive keeps the model, posable at any coordinates (`._drive.Poser`).
    """
    c = None if cache is None else str(cache)
    nodes = [
        Node(("read-muscle", str(m.mesh), m.repair, c), ReadMuscle(m, c)) for m in scene.muscles
    ]
    nodes += [
        Node(("read-bone", str(b.mesh), b.scale, collisions, c), ReadBone(b, c, collisions))
        for b in scene.bones
    ]
    done = gather(runner, nodes)
    muscles = {}
    input_ids: dict[str, IntArray] = {}
    for spec, node in zip(scene.muscles, nodes, strict=False):
        V, F, mnotes, input_ids[spec.name] = done[node.key]
        for n in mnotes:
            notes.append(f"{spec.name}: {n}")
            say(f"{spec.name}: {n}")
        muscles[spec.name] = (V, F)
    bones = {}
    for b, node in zip(scene.bones, nodes[len(scene.muscles) :], strict=True):
        V, F, bnotes = done[node.key]
        for n in bnotes:
            notes.append(n)
            say(n)
        bones[b.name] = (V, F)
    centroids = {n: V.mean(axis=0) for n, (V, _) in bones.items()}
    drive = drive_scene(scene, frames, centroids, waypoints=collisions, keep_poser=keep_poser)
    notes += drive.notes
    # every mesh in the frame of the body that carries it
    muscles = {m: (apply_transform(drive.to_body[m], V), F) for m, (V, F) in muscles.items()}
    _check_units(scene, drive, muscles)
    fits = fit_bones(scene, drive, muscles, cache, say, notes)
    meshes = {}
    for b, (V, F) in bones.items():
        Vb = apply_transform(drive.to_body[b], V)
        if b in fits:
            Vb = Vb + fits[b].move(Vb)
        meshes[b] = BoneMesh(b, Vb, F, Obstacle.cache_name(Vb, F))  # the probe's name, once
    contact = anchors = None
    if collisions:
        muscles, contact, anchors = _rest_overlap(
            scene, drive, muscles, meshes, cache, say, notes, runner
        )
    around = {}
    if muscles_apart:
        check_muscles_apart(scene, drive, muscles)
        apart = _apart_at_rest(scene, drive, muscles, say, notes, cache)
        # the cage of the mesh as segmented (and pushed out of its bones)
        around = {m: muscles[m][0] for m in muscles if apart[m][0] is not muscles[m][0]}
        muscles = apart
    return Inputs(
        scene,
        drive,
        muscles,
        meshes,
        input_ids,
        contact,
        anchors,
        cache,
        run_key(scene, drive, collisions),
        around,
    )


@dataclass(frozen=True)
class ReadMuscle:
    """A muscle's mesh read and cleaned (or repaired); cached by the file's bytes."""

    spec: MuscleSpec
    cache: str | None

    def cached(self) -> bool:
        """Read already (then reading it back here is cheaper than sending it out)."""
        cache = None if self.cache is None else Path(self.cache)
        f = _mesh_cache_file(self.spec.mesh, cache, f"muscle|{self.spec.repair}|{_MUSCLE_TAG}")
        return f is not None and f.is_file()

    def run(self) -> tuple[FloatArray, IntArray, list[str], IntArray]:
        return _read_muscle(self.spec, None if self.cache is None else Path(self.cache))


@dataclass(frozen=True)
class ReadBone:
    """A bone's mesh read, oriented outward and, for contact, closed; cached."""

    bone: BoneSpec
    cache: str | None
    closed: bool

    def cached(self) -> bool:
        """Read (and, for contact, closed) already."""
        cache = None if self.cache is None else Path(self.cache)
        read = _mesh_cache_file(self.bone.mesh, cache, _BONE_TAG)
        if read is None or not read.is_file():
            return False
        if not self.closed:
            return True
        closed = _mesh_cache_file(self.bone.mesh, cache, _closed_tag(self.bone))
        if closed is not None and closed.is_file():
            return True
        try:  # a closed bone needs no closing
            with np.load(read) as z:
                return int(z["boundary_edges"]) == 0
        except (OSError, KeyError, ValueError):
            return False

    def run(self) -> tuple[FloatArray, IntArray, list[str]]:
        b = self.bone
        cache = None if self.cache is None else Path(self.cache)
        V, F, said, open_edges = _read_bone(b, cache)
        notes = [f"{b.name}: {b.source}"] if b.source else []  # a model's mesh
        notes += [f"{b.name}: {n}" for n in said]
        if self.closed:
            V, F = _closed_bone(b, V, F, open_edges, cache, _silent, notes)
        return V, F, notes


def fit_bones(
    scene: Scene,
    drive: Drive,
    muscles: dict[str, tuple[FloatArray, IntArray]],
    cache: Path | None,
    say: Callable[[str], None],
    notes: list[str],
) -> dict[str, ShaftFit]:
    """The scene's bones with ``fit = "shaft"`` fitted to their muscles at rest; cached.

    Each bone is read as its file gives it (closed first if open, as contact closes it:
    the fit is the same whether contact is on or not, and `verify_run` fits it again the
    same way), in its body's frame; ``muscles`` are the cleaned meshes in their bodies' frames, before any
    push-out. The muscles it may touch (its ``bones`` name it, or name none) are placed
    in its body's frame at the rest pose; the points held are the vertices of the
    body's bones that are not fitted (the subject's own) and the centres of the joints
    near it (the origins of the scene's bodies within a tenth of its length). A fit
    that would make its faces cross is not used (said). Returns per fitted bone its
    `ShaftFit` (``move`` places any of its vertices).
    """
    fits: dict[str, ShaftFit] = {}
    todo = [b for b in scene.bones if b.fit == "shaft"]
    if not todo:
        return fits
    read = {}
    for b in scene.bones:
        V, F, _, open_edges = _read_bone(b, cache)
        if b.fit and open_edges:  # its sections need an inside: closed as contact closes it
            V, F = _closed_bone(b, V, F, open_edges, cache, _silent, [])
        read[b.name] = (apply_transform(drive.to_body[b.name], V), F)
    for b in todo:
        V, F = read[b.name]
        near = {
            m.name: (apply_transform(drive.rest_between(m.body, b.body), muscles[m.name][0]),
                     muscles[m.name][1])
            for m in scene.muscles
            if m.bones is None or b.name in m.bones
        }  # fmt: skip
        own = [read[o.name][0] for o in scene.bones if o.body == b.body and not o.fit]
        joints = np.array(
            [
                drive.rest_between(body, b.body)[:3, 3]
                for body in drive.rest_poses
                if body != "ground"
            ]
        ).reshape(-1, 3)
        length = float(np.ptp(V, axis=0).max())
        reach = np.array([np.linalg.norm(V - j, axis=1).min() for j in joints])
        held = np.vstack([*own, joints[reach < 0.1 * length]])
        key = cache_key(
            V, F, held, *(a for m in sorted(near) for a in near[m]),
            f"{sorted(near)}|shaft {_SHAFT_FORMAT}",
        )  # fmt: skip
        path = None if cache is None else cache / f"shaft-{key[:32]}.npz"

        def build(V: FloatArray = V, F: IntArray = F, near: dict = near, held: FloatArray = held):
            f = fit_shaft(V, F, near, held)
            crossed = self_intersecting_faces(f.V, F) - self_intersecting_faces(V, F)
            return {
                **{k: np.asarray(getattr(f, k)) for k in _SHAFT_ARRAYS},
                "moved": np.array(f.moved),
                "crossed": np.array(crossed),
                "overlaps": np.array(json.dumps([f.before, f.after])),
            }

        d = cached_arrays(path, build)
        before, after = json.loads(str(d["overlaps"]))
        fit = ShaftFit(
            **{k: d[k] for k in _SHAFT_ARRAYS},
            V=V,
            moved=float(d["moved"]),
            before={m: tuple(v) for m, v in before.items()},
            after={m: tuple(v) for m, v in after.items()},
        )
        fit = dataclasses.replace(fit, V=V + fit.move(V))  # as fit_shaft gives it: moved
        unit = scene.mesh_unit
        if not (~fit.held).any():
            n = (
                f"{b.name}: not fitted to its muscles (fit = 'shaft'): all {len(fit.held)} of "
                "its levels lie between the points held (the body's other bones, the joints' "
                "centres); 'shaft' is for a long bone; kept as placed"
            )
        elif int(d["crossed"]) > 0:
            n = (
                f"{b.name}: not fitted to its muscles (fit = 'shaft'): the fit would make "
                f"{int(d['crossed'])} of its faces cross others; kept as placed"
            )
        else:
            fits[b.name] = fit
            most = fit.offsets[np.argmax(np.linalg.norm(fit.offsets, axis=1))] @ fit.across
            said = ", ".join(
                f"{m} {before[m][0]} vertices {before[m][1]:.2f} {unit} deep -> "
                f"{after[m][0]} ({after[m][1]:.2f})"
                for m in before
            )
            n = (
                f"{b.name}: fitted to its muscles along its shaft (fit = 'shaft'): cross-sections "
                f"moved up to {fit.moved:.1f} {unit} (the most by "
                f"({most[0]:+.1f}, {most[1]:+.1f}, {most[2]:+.1f}) in {b.body}'s frame), "
                f"{int((~fit.held).sum())} of {len(fit.held)} levels free; the muscles in "
                f"it: {said or 'none'}"
            )
        notes.append(n)
        say(n)
    return fits


# of the cached shaft fits (2: the price summed directly, not by FFT)
_SHAFT_FORMAT = 2
_SHAFT_ARRAYS = ("centre", "axis", "across", "levels", "offsets", "held", "ends")


def default_cache_dir() -> Path:
    """``$MUSCLEWRAP_CACHE``, else ``$XDG_CACHE_HOME/musclewrap``, else ``~/.cache/musclewrap``."""
    env = os.environ.get("MUSCLEWRAP_CACHE")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return Path(xdg if xdg else Path.home() / ".cache") / "musclewrap"


def _cached_mesh(
    path: Path, cache: Path | None, tag: str, build: Callable[[], dict[str, np.ndarray]]
) -> dict[str, np.ndarray]:
    """Arrays `build` makes from a mesh file, cached by the file's bytes and ``tag``."""
    return cached_arrays(_mesh_cache_file(path, cache, tag), build)


def _mesh_cache_file(path: Path, cache: Path | None, tag: str) -> Path | None:
    if cache is None:
        return None
    key = cache_key(path.read_bytes(), f"{tag}|first-appearance order")
    return cache / f"mesh-{key[:32]}.npz"


_MUSCLE_TAG = "self-intersection, fans, orientation, input_id"
# of the cached taking apart at rest (2: a face of another muscle faces this one only
# where this one lies in front of it)
_APART_FORMAT = 2


def _read_muscle(
    spec: MuscleSpec, cache: Path | None
) -> tuple[FloatArray, IntArray, list[str], IntArray]:
    """Read and clean (or repair) a muscle mesh; cached.

    Returns the mesh, the notes, and each vertex's index in the file (``input_id``,
    `musclewrap.mesh.vertex_origins`).
    """

    def build() -> dict[str, np.ndarray]:
        V0, F0 = read_mesh(spec.mesh)
        V, F, notes = clean_mesh(V0, F0, source=str(spec.mesh), repair=spec.repair)
        ids = vertex_origins(V0, V)
        return {"V": V, "F": F, "notes": np.array(notes, dtype=str), "input_id": ids}

    d = _cached_mesh(
        spec.mesh,
        cache,
        f"muscle|{spec.repair}|{_MUSCLE_TAG}",
        build,
    )
    return d["V"], d["F"], [str(n) for n in d["notes"]], d["input_id"]


def _read_bone(b: BoneSpec, cache: Path | None) -> tuple[FloatArray, IntArray, list[str], int]:
    """Read, tidy and orient outward a bone's mesh (not required to be manifold); cached.

    Faces given twice (the same three vertices, either way round) are kept once where
    that leaves no edge shared by more than two faces and opens none
    (`musclewrap.mesh.drop_repeated_faces`): Rajagopal 2016's generic femur gives 5
    faces twice, 3 reversed, and a closest point on a reversed copy has its normal
    pointing into the bone (a muscle vertex 18.7 mm outside it was read as that deep
    inside). Edges still shared by more than two faces in a closed bone are said (an open
    one is repaired as contact closes it).

    Returns the vertices (times the bone's ``scale``: a model's mesh), the faces, what
    was changed or found (notes), and the number of boundary edges (an open bone:
    contact has to close it).
    """
    path = b.mesh

    def build() -> dict[str, np.ndarray]:
        V, F, _ = tidy_mesh(*read_mesh(path))
        check = check_mesh(V, F)
        said = []
        if check.nonmanifold_edges:
            once, dropped = drop_repeated_faces(F)
            after = check_mesh(V, once)
            if (
                dropped
                and not after.nonmanifold_edges
                and (after.boundary_edges <= check.boundary_edges)
            ):
                F, check = once, after
                said.append(f"{dropped} faces given twice (the same three vertices): kept once")
            elif not check.boundary_edges:  # an open bone is repaired as it is closed
                k = check.nonmanifold_edges
                said.append(
                    f"{k} edge{'s' if k > 1 else ''} shared by more than two faces: the side "
                    "of a point next to them may be wrong"
                )
        flip = check.volume < 0
        if flip:
            said.append("faces were oriented inward: flipped")
        return {
            "V": V,
            "F": F[:, ::-1].copy() if flip else F,
            "notes": np.array(said, dtype=str),
            "boundary_edges": np.array(check.boundary_edges),
        }

    d = _cached_mesh(path, cache, _BONE_TAG, build)
    V = d["V"] if b.scale == (1.0, 1.0, 1.0) else d["V"] * np.asarray(b.scale)
    return V, d["F"], [str(x) for x in d["notes"]], int(d["boundary_edges"])


#: the cache tag of a bone as read (`_read_bone`): changed where what it keeps changes
_BONE_TAG = "bone|boundary edges|faces once"


def _closed_tag(b: BoneSpec) -> str:
    """The cache tag of a bone's closed mesh (its scale in it: a model's mesh is scaled)."""
    return "bone-closed" if b.scale == (1.0, 1.0, 1.0) else f"bone-closed|scale {b.scale!r}"


def _closed_bone(
    b: Any,
    V: FloatArray,
    F: IntArray,
    boundary_edges: int,
    cache: Path | None,
    say: Callable[[str], None],
    notes: list[str],
) -> tuple[FloatArray, IntArray]:
    """A bone that contact can use: closed (an open one is repaired, or refused); cached.

    Contact needs an inside: a bone with holes is closed by PyMeshFix, as a muscle is, and
    the run says so; one that cannot be is refused, naming the file.
    """
    if not boundary_edges:
        return V, F

    def build() -> dict[str, np.ndarray]:
        try:
            RV, RF, rnotes = bone_surface(V, F, source=str(b.mesh), close=True)
        except MeshError as exc:
            raise SceneError(
                f"{b.mesh}: the bone '{b.name}' is open ({boundary_edges} boundary "
                f"edges) and could not be closed ({exc}); contact needs its inside: close it, "
                "leave it out of the muscles' bones, or set [collisions] enabled = false"
            ) from None
        return {"V": RV, "F": RF, "notes": np.array(rnotes, dtype=str)}

    d = _cached_mesh(b.mesh, cache, _closed_tag(b), build)
    for n in (str(x) for x in d["notes"]):
        notes.append(f"{b.name}: {n}")
        say(f"{b.name}: {n}")
    return d["V"], d["F"]


def _push_out_rest(
    V: FloatArray, F: IntArray, placed: list[Any], margin: float, cache: Path | None
) -> tuple[FloatArray | None, Any, str]:
    """`musclewrap.contact.rest_push_out`, cached by its inputs."""
    key = cache_key(
        V,
        F,
        *(np.asarray(pl.T) for pl in placed),
        "|".join(Obstacle.cache_name(pl.obstacle.V, pl.obstacle.F) for pl in placed),
        f"{margin}|rest-overlap",
    )
    path = None if cache is None else cache / f"rest-{key[:32]}.npz"

    def build() -> dict[str, np.ndarray]:
        P, rep, how = rest_push_out(V, F, placed, margin)
        return {
            "P": np.zeros((0, 3)) if P is None else P,
            "report": np.array(json.dumps(dataclasses.asdict(rep))),
            "how": np.array(how),
        }

    d = cached_arrays(path, build)
    try:
        rep = ContactReport(**json.loads(str(d["report"])))
    except (TypeError, ValueError):
        # written by a development version whose report had other fields: rebuilt
        if path is not None:
            path.unlink(missing_ok=True)
        d = cached_arrays(path, build)
        rep = ContactReport(**json.loads(str(d["report"])))
    how = str(d["how"])
    return (None if how == "none" else d["P"]), rep, how


def _rest_overlap(
    scene: Scene,
    drive: Drive,
    muscles: dict[str, tuple[FloatArray, IntArray]],
    bones: dict[str, BoneMesh],
    cache: Path | None,
    say: Callable[[str], None],
    notes: list[str],
    runner: Runner | None = None,
) -> tuple[
    dict[str, tuple[FloatArray, IntArray]],
    dict[str, dict[str, FloatArray | None]],
    dict[str, IntArray],
]:
    """Muscles out of their bones at the rest pose (or their overlap kept), once per run.

    Every mesh is in its body's frame. With ``rest_overlap = "resolve"`` each
    muscle's vertices inside (or within the margin of) a bone at the rest pose
    are pushed out, volume-exact (`musclewrap.contact.push_out`), and the pushed
    mesh is the one prepared; with ``"keep"`` each vertex may stay as deep as it
    was. A muscle with most of its vertices inside one bone is refused: its
    mesh, frame or units do not match the bone's.

    Returns the muscles; per muscle, the bones it is kept out of with each one's
    allowance (``"keep"``); and per muscle its anchors: the vertices within
    ``defaults.anchor_reach`` mean edge lengths of the margin of a bone that its
    own body carries, in patches near an end of its action lines (an origin,
    which moves with that bone: `Muscle.bind`'s anchors keep them in place, so
    the deformation does not drive the muscle into the bone it starts from;
    `musclewrap.contact.attachment_patches`). Each muscle's outcome is a task
    (`RestOutcome`, after its bones' probes), run by ``runner``'s executor where
    it is not cached yet, else here.
    """
    cache_str = None if cache is None else str(cache)
    body_of = {b.name: b.body for b in scene.bones}
    tasks: dict[str, RestOutcome] = {}
    for spec in scene.muscles:
        V, F = muscles[spec.name]
        names = tuple(spec.bones) if spec.bones is not None else tuple(bones)
        tasks[spec.name] = RestOutcome(
            scene,
            spec,
            V,
            F,
            {b: bones[b] for b in names},
            {b: drive.rest_between(spec.body, body_of[b]) for b in names},
            drive.rest_lines[spec.name],
            body_of,
            cache_str,
        )
    # probes are built (or read back) only where a muscle's outcome is not cached
    todo = {m: t for m, t in tasks.items() if t.path is None or not t.path.is_file()}
    probe_keys = {}
    nodes = []
    for b in sorted({b for t in todo.values() for b in t.bones}):
        probe_keys[b] = ("probe", cache_str, bones[b].probe)
        nodes.append(Node(probe_keys[b], ProbeBone(bones[b], cache_str)))
    for m, t in todo.items():
        nodes.append(Node(("rest", t.key, m), t, tuple(probe_keys[b] for b in t.bones)))
    done = gather(runner, nodes)
    out_muscles = dict(muscles)
    contact: dict[str, dict[str, FloatArray | None]] = {}
    anchors: dict[str, IntArray] = {}
    for spec in scene.muscles:
        t = tasks[spec.name]
        d = done[("rest", t.key, spec.name)] if spec.name in todo else t.run()
        for n in (str(x) for x in d["notes"]):
            notes.append(n)
            say(n)
        contact[spec.name] = {b: d.get(f"allowance {b}") for b in t.bones}
        out_muscles[spec.name] = (np.asarray(d["V"], dtype=np.float64), t.F)
        anchors[spec.name] = np.asarray(d["anchors"], dtype=np.int64)
    return out_muscles, contact, anchors


def _apart_at_rest(
    scene: Scene,
    drive: Drive,
    muscles: dict[str, tuple[FloatArray, IntArray]],
    say: Callable[[str], None],
    notes: list[str],
    cache: Path | None = None,
) -> dict[str, tuple[FloatArray, IntArray]]:
    """Segmented muscles that overlap at rest taken apart once (`musclewrap.contact.apart_at_rest`).

    Both sides of each pair in ``[collisions] pairs`` (default every pair) move,
    volumes exact, after each was pushed out of its bones; each pair is said in the
    notes. A muscle moved keeps the cage of its mesh as segmented (`read_inputs`).
    With ``rest_overlap = "keep"`` the meshes stay as segmented and the pairs are
    only said (each frame's rounds still take them apart). Meshes in their bodies'
    frames, as prepared. The outcome is cached (``cache``): it depends on the meshes at
    rest, the pairs and the settings alone.
    """
    names = sorted(muscles)
    # every muscle in the ground's frame at rest (each is in its body's)
    to_g = {m.name: drive.rest_poses[m.body] for m in scene.muscles}
    rest = {n: (apply_transform(to_g[n], muscles[n][0]), muscles[n][1]) for n in names}
    keep = scene.rest_overlap == "keep"
    V, found, rounds = _apart_cached(rest, scene.muscle_pairs, not keep, cache)
    unit = scene.mesh_unit
    for p in found:
        (a, b), (na, nb), (da, db) = p.pair, p.inside, p.depth
        msg = (
            f"{a} and {b} overlap at rest: {na} vertices of {a} inside {b} (up to {da:.3g} "
            f"{unit}), {nb} of {b} inside {a} (up to {db:.3g} {unit}); "
            + (
                "kept as segmented (rest_overlap = 'keep'): each frame takes them apart"
                if keep
                else f"taken apart, both sides, in {rounds} rounds (moved up to "
                f"{p.moved[0]:.3g} and {p.moved[1]:.3g} {unit}; {p.left:.2g} {unit} left, "
                f"the rounds stop at {defaults.muscle_overlap_depth:g} mean edges), volumes kept"
            )
        )
        notes.append(msg)
        say(msg)
    out = dict(muscles)
    for n in names:
        if V[n] is not rest[n][0]:
            out[n] = (apply_transform(invert_rigid(to_g[n]), V[n]), muscles[n][1])
    return out


def _apart_cached(
    rest: dict[str, tuple[FloatArray, IntArray]],
    pairs: Any,
    resolve: bool,
    cache: Path | None,
) -> tuple[dict[str, FloatArray], list[Any], int]:
    """`musclewrap.contact.apart_at_rest`, read from the cache where it was made before."""
    names = sorted(rest)
    path = None
    if cache is not None:
        key = cache_key(
            *(a for n in names for a in (rest[n][0], np.asarray(rest[n][1], dtype=np.int64))),
            repr((names, None if pairs is None else sorted(map(tuple, pairs)), resolve)),
            repr((defaults, _APART_FORMAT)),
        )
        path = Path(cache) / f"apart-at-rest-{key[:32]}.npz"
    made: list[Any] = []

    def build() -> dict[str, np.ndarray]:
        V, found, rounds = apart_at_rest(rest, pairs, resolve=resolve)
        made.append((V, found, rounds))
        out = {f"V {n}": V[n] for n in names if V[n] is not rest[n][0]}
        out["pairs"] = np.array([p.pair for p in found], dtype=str).reshape(-1, 2)
        for f in ("inside", "depth", "moved"):
            out[f] = np.array([getattr(p, f) for p in found], dtype=float).reshape(-1, 2)
        out["left"] = np.array([p.left for p in found], dtype=float)
        out["rounds"] = np.array(rounds)
        return out

    got = cached_arrays(path, build)
    if made:
        return made[0]
    V = {n: got[f"V {n}"] if f"V {n}" in got else rest[n][0] for n in names}
    found = [
        RestPair(
            (str(a), str(b)),
            (int(i[0]), int(i[1])),
            (float(d[0]), float(d[1])),
            (float(m[0]), float(m[1])),
            float(left),
        )
        for (a, b), i, d, m, left in zip(
            got["pairs"], got["inside"], got["depth"], got["moved"], got["left"], strict=True
        )
    ]
    return V, found, int(got["rounds"])


def check_muscles_apart(
    scene: Scene, drive: Drive, muscles: dict[str, tuple[FloatArray, IntArray]]
) -> None:
    """Muscles that cannot be kept apart: refused, naming both (muscle contact on).

    Two muscles that are the same mesh (the same file, or the same vertices), or one
    whose every vertex lies inside another at rest (a wrong file, frame or unit).
    """
    specs = {m.name: m for m in scene.muscles}
    names = list(specs)
    rest = {n: apply_transform(drive.rest_poses[specs[n].body], muscles[n][0]) for n in names}
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            Va, Vb = rest[a], rest[b]
            if (Va.min(0) > Vb.max(0)).any() or (Vb.min(0) > Va.max(0)).any():
                continue
            where = f"{a!r} ({specs[a].mesh}) and {b!r} ({specs[b].mesh})"
            size = float(np.ptp(np.vstack([Va, Vb]), axis=0).max())
            same = Path(specs[a].mesh).resolve() == Path(specs[b].mesh).resolve() or (
                Va.shape == Vb.shape
                and np.allclose(np.sort(Va, axis=0), np.sort(Vb, axis=0), atol=1e-9 * size)
            )
            if same:
                raise SceneError(
                    f"muscles {where} are the same mesh: two muscles cannot be kept out of each "
                    "other; name each muscle's own mesh, or set [collisions] muscles = false"
                )
            for x, y in ((a, b), (b, a)):
                if (rest[x].min(0) < rest[y].min(0)).any() or (
                    rest[x].max(0) > rest[y].max(0)
                ).any():
                    continue  # a vertex of x outside y's box: outside y (no grid needed)
                if (WindingGrid(rest[y], muscles[y][1])(rest[x]) > 0).all():
                    raise SceneError(
                        f"muscle {x!r} ({specs[x].mesh}) lies entirely inside {y!r} "
                        f"({specs[y].mesh}) at rest: check their files, frames and units, or set "
                        "[collisions] muscles = false"
                    )


def gather(runner: Runner, nodes: list[Node]) -> dict[Any, Any]:
    """Run ``nodes`` through ``runner`` and wait; results by key.

    Here, in order, without a runner, and for a task whose result is cached already
    (its ``cached()`` says so: reading it back costs less than a round trip).
    """
    here = [n for n in nodes if runner is None or getattr(n.task, "cached", lambda: False)()]
    out = {n.key: n.task.run() for n in here}
    away = [n for n in nodes if n.key not in out]
    for n in away:
        n.priority = 0  # the main process waits for these
    if away:
        runner.add(away)
        runner.wait([n.key for n in away])
        out.update({n.key: runner.result(n.key) for n in away})
    return out


@dataclass(frozen=True)
class RestOutcome:
    """One muscle at the rest pose against its bones: pushed out, or its overlap kept (cached).

    ``T`` takes the muscle's body frame to each bone's; the result holds the positions
    to prepare (``V``), the notes, each kept overlap's allowance and the anchors.
    """

    scene: Scene
    spec: MuscleSpec
    V: FloatArray
    F: IntArray
    bones: dict[str, BoneMesh]
    T: dict[str, FloatArray]
    lines: dict[str, FloatArray]
    body_of: dict[str, str]
    cache: str | None

    @cached_property
    def key(self) -> str:
        """Hash of everything the outcome depends on (names its cache file; once)."""
        scene, spec, names = self.scene, self.spec, list(self.bones)
        lines = self.lines
        return cache_key(
            self.V,
            self.F,
            *(self.bones[b].probe for b in names),
            *(self.T[b] for b in names),
            *(np.asarray(lines[k], dtype=np.float64) for k in sorted(lines)),
            repr((names, sorted(lines), [self.body_of[b] == spec.body for b in names])),
            repr((spec.name, scene.margin, scene.rest_overlap, scene.mesh_unit)),
            repr((defaults.anchor_reach, defaults.anchor_end_reach)),
            repr(defaults.kept_overlap_rings),
        )

    @cached_property
    def path(self) -> Path | None:
        if self.cache is None:
            return None
        return Path(self.cache) / f"rest-outcome-{self.key[:32]}.npz"

    def run(self) -> dict[str, np.ndarray]:
        return cached_arrays(self.path, self._build)

    def _build(self) -> dict[str, np.ndarray]:

        scene, spec, V, F = self.scene, self.spec, self.V, self.F
        cache = None if self.cache is None else Path(self.cache)
        said: list[str] = []
        placed = []
        for b, mesh in self.bones.items():
            pl = Placed(bone_probe(mesh, self.cache), self.T[b], None, b)
            n_in, depth = pl.obstacle.measure(pl.to_obstacle(V))
            if n_in > 0.5 * len(V):
                raise SceneError(
                    f"{spec.mesh}: {n_in} of the {len(V)} vertices of '{spec.name}' lie "
                    f"inside the bone '{b}' ({depth:.3g} {scene.mesh_unit} deep) at the rest "
                    "pose: the muscle and bone meshes must be the same subject's, in the same "
                    "frame and units (or leave this bone out of the muscle's [muscles] bones)"
                )
            placed.append(pl)
        keep = scene.rest_overlap == "keep"
        if placed and not keep:
            _, V, keep = _resolve_rest(spec, V, F, placed, scene, cache, _silent, said)
        out: dict[str, np.ndarray] = {"V": V, "notes": np.array(said, dtype=str)}
        for pl in placed:
            a = kept_allowance(pl, V, scene.margin, F) if keep else None
            if a is not None:
                out[f"allowance {pl.name}"] = a
        own = [pl for pl in placed if self.body_of[pl.name] == spec.body]
        out["anchors"] = anchors_at_rest(V, F, own, self.lines, scene.margin)
        return out


def _silent(_: str) -> None:
    """Says nothing (what is said is kept, and said on every run)."""


def _resolve_rest(
    spec: MuscleSpec,
    V: FloatArray,
    F: IntArray,
    placed: list[Any],
    scene: Scene,
    cache: Path | None,
    say: Callable[[str], None],
    notes: list[str],
) -> tuple[Any, FloatArray, bool]:
    """One muscle's rest overlap pushed out (`_push_out_rest`), said in the notes.

    Returns the push-out's report, the positions to prepare, and whether the
    overlap is kept instead (every push folded the surface).
    """
    P, rep, how = _push_out_rest(V, F, placed, scene.margin, cache)
    if rep.rounds == 0:
        return rep, V, False
    if not rep.ok:
        raise SceneError(
            f"{spec.mesh}: the overlap of '{spec.name}' with its bones at the rest pose "
            f"cannot be resolved ({rep.reason}); set [collisions] rest_overlap = 'keep'"
        )
    if P is None:
        msg = (
            f"{spec.name}: rest overlap with bones kept (up to {rep.depth_before:.3g} "
            f"{scene.mesh_unit} deep): pushing it out folds the surface; only new "
            "penetration is prevented"
        )
    else:
        msg = (
            f"{spec.name}: rest overlap with bones resolved: {rep.contact_vertices} vertices "
            f"now at the bones, up to {rep.depth_before:.3g} {scene.mesh_unit} deep before; "
            f"largest displacement {rep.moved_max:.3g} {scene.mesh_unit}; volume kept"
            + ("" if how == "bone vertices" else "; bone vertices inside the muscle left")
        )
    notes.append(msg)
    say(msg)
    return rep, (V if P is None else P), P is None


def input_files(scene: Scene) -> list[Path]:
    """Every file the scene reads."""
    files = [scene.path, *scene.motions, *(m.mesh for m in scene.muscles)]
    files += [b.mesh for b in scene.bones]
    files += [p for p in (scene.osim, scene.lines_csv, scene.bodies_csv) if p is not None]
    if scene.registration is not None:
        files += [lm.mesh for lm in scene.registration.landmarks]
    return files


def check_outputs_spare_inputs(scene: Scene, outdir: Path) -> None:
    """Refuse an output folder where the run would write over one of its inputs."""
    clash = overwrite_clash(
        input_files(scene),
        [outdir / n for n in TOP_FILES],
        [outdir / m.name for m in scene.muscles] + [outdir / b.name for b in scene.bones],
    )
    if clash is not None:
        raise SceneError(
            f"{clash[0]}: an input of the scene lies where the run writes its outputs (in "
            f"{outdir}); musclewrap never writes over its inputs: choose another output "
            "folder (-o)"
        )


def run_key(scene: Scene, drive: Drive, collisions: bool) -> str:
    """Hash of everything a run's outputs depend on: files, settings, frames, version, code."""
    files = input_files(scene)
    return digest(
        *(f.read_bytes() for f in files),
        np.asarray(drive.frames),
        f"{cache_version()}|collisions={collisions}"
        + ("|together" if scene.muscle_together else "")
        + (f"|line_window={scene.line_window!r}" if scene.line_window else ""),
    )


def _check_units(
    scene: Scene, drive: Drive, muscles: dict[str, tuple[FloatArray, IntArray]]
) -> None:
    """Refuse a muscle whose rest lines cannot belong to its mesh (both in its body frame)."""
    for spec in scene.muscles:
        problem = rest_lines_problem(
            scene, spec, muscles[spec.name][0], drive.rest_lines[spec.name]
        )
        if problem is not None:
            raise SceneError(problem)


def rest_lines_problem(scene: Scene, spec: MuscleSpec, V: FloatArray, lines: Any) -> str | None:
    """Why a muscle's rest lines cannot belong to its mesh (`placement_problem`), or None."""
    problem = placement_problem(V, lines)
    if problem is None:
        return None
    return (
        f"{spec.mesh}: the rest action lines of '{spec.name}' ({scene.mesh_unit}): "
        f"{problem}: check [units] (mesh = '{scene.mesh_unit}', model = "
        f"'{scene.model_unit}'), the muscle's body ('{spec.body}'), or the rest pose"
    )


def end_bones(
    scene: Scene, drive: Drive, spec: MuscleSpec
) -> tuple[tuple[tuple[str, FloatArray], ...], tuple[tuple[str, FloatArray], ...]]:
    """The bones the fibres' areas may lie on: per end (origin, insertion) of the muscle.

    With ``[fibres] attachments = "bones"``, each bone of the scene carried by a body its
    paths' first (last) points are fixed in, with the transform from the muscle's body
    frame into the bone's at rest; none otherwise.
    """
    if scene.fibres is None or scene.fibres.attachments != "bones":
        return (), ()
    ends = drive.path_ends.get(spec.name, ((), ()))
    origin, insertion = (
        tuple(
            (b.name, drive.rest_between(spec.body, b.body)) for b in scene.bones if b.body in bodies
        )
        for bodies in ends
    )
    return origin, insertion


def attachment_area(
    scene: Scene, drive: Drive, spec: MuscleSpec, key: str, V: FloatArray, input_id: IntArray
) -> IntArray | None:
    """A muscle's ``fibre_origin``/``fibre_insertion`` as its vertex numbers (None: default)."""
    given = getattr(spec, f"fibre_{key}")
    if given is None:
        return None
    where = f"{scene.path}: [muscles.{spec.name}] fibre_{key}"
    if isinstance(given[0], int):
        area = np.flatnonzero(np.isin(input_id, np.asarray(given, dtype=np.int64)))
        if not len(area):
            raise SceneError(
                f"{where}: none of its vertex indices is a vertex of {spec.mesh.name} "
                f"(indices 0 to {int(input_id.max())} after merging and repair)"
            )
        return area
    # landmark points, in the mesh's coordinates: the surface within landmark_radius
    P = apply_transform(drive.to_body[spec.name], np.array(given, dtype=np.float64))
    from scipy.spatial import cKDTree

    d, _ = cKDTree(P).query(V)
    radius = scene.fibres.landmark_radius if scene.fibres is not None else 10.0
    area = np.flatnonzero(d <= radius)
    if not len(area):
        raise SceneError(
            f"{where}: no vertex of the muscle lies within landmark_radius = {radius:g} of its "
            f"points (the nearest is {float(d.min()):.3g} away)"
        )
    return area
