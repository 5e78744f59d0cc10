"""What drives a scene per frame: action lines, reference points and body frames."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from .._typing import FloatArray, IntArray
from ..conditions import PathLines, csv_rows, set_point_params
from ..constants import defaults
from ..errors import SceneError, suggest
from ..mesh import apply_transform, invert_rigid, read_mesh, tidy_mesh
from ..model import (
    Motion,
    OpenSimModel,
    axes_rotation,
    check_landmarks,
    landmark_point,
    read_motion,
    similarity,
)
from ._config import UNITS, Scene

__all__ = [
    "CENTRAL",
    "Drive",
    "MomentArmPoses",
    "Poser",
    "Registration",
    "Stencil",
    "Waypoints",
    "drive_scene",
    "lattice_parent",
    "lattice_paths",
    "one_sided",
    "parse_frames",
    "polyline_length",
    "rest_pose",
    "reversed_coordinates",
]


class Registration:
    """A scene's ``[registration]``: its landmarks read once, the similarity at any pose.

    ``P`` (n, 3) the landmarks in the meshes' frame (mesh units), ``names`` theirs,
    ``fits`` what fitting them said (a sphere's residual).
    """

    def __init__(self, scene: Scene) -> None:
        reg = scene.registration
        assert reg is not None
        self.scene = scene
        P, names, fits = [], [], []
        for lm in reg.landmarks:
            V, F, _ = tidy_mesh(*read_mesh(lm.mesh))
            c, said = landmark_point(V, F, lm.fit, lm.name, lm.mesh)
            if said:
                fits.append(said)
            P.append(c)
            names.append(lm.name)
        self.P = np.array(P)
        self.names = names
        self.fits = fits
        check_landmarks(self.P, names, str(scene.path))
        self.R0 = None if reg.axes is None else axes_rotation(reg.axes)

    def targets(self, g: Mapping[str, FloatArray], s: float) -> FloatArray:
        """The landmarks' places in the model (ground, mesh units) for bodies ``g``."""
        reg = self.scene.registration
        assert reg is not None
        return np.array(
            [apply_transform(g[lm.body], np.array(lm.point)[None] * s)[0] for lm in reg.landmarks]
        )

    def at(self, g: Mapping[str, FloatArray], s: float) -> FloatArray:
        """The similarity from the meshes' frame to ground, the bodies placed by ``g``.

        ``g``: each landmark body's frame to ground (mesh units), ``s`` the scene's scale.
        """
        return similarity(self.P, self.targets(g, s), self.R0)


def _register(scene: Scene, g: dict[str, FloatArray], s: float, notes: list[str]) -> FloatArray:
    """Similarity from the registration's mesh frame to ground (mesh units), with a note."""
    reg = Registration(scene)
    Q = reg.targets(g, s)
    check_landmarks(Q, reg.names, str(scene.path))
    T = similarity(reg.P, Q, reg.R0)
    scale = float(np.cbrt(np.linalg.det(T[:3, :3])))
    res = np.linalg.norm(apply_transform(T, reg.P) - Q, axis=1)
    notes.append(
        f"registration: meshes scaled by {scale:.4f}; landmark misfit "
        + ", ".join(f"{n} {d:.2g}" for n, d in zip(reg.names, res, strict=True))
        + f" {scene.mesh_unit}"
        + (f"; {'; '.join(reg.fits)}" if reg.fits else "")
    )
    return T


def parse_frames(text: str | None, n: int, *, source: str) -> list[int]:
    """Frame positions from ``start:stop:step`` (Python slice rules, no negative step)."""
    if text is None:
        return list(range(n))
    parts = text.split(":")
    if not 1 <= len(parts) <= 3:
        raise SceneError(f"--frames {text!r}: write START:STOP[:STEP], e.g. 0:211:1")
    try:
        vals = [int(p) if p.strip() else None for p in parts]
    except ValueError:
        raise SceneError(f"--frames {text!r}: START, STOP and STEP must be integers") from None
    if len(vals) == 1:
        vals = [vals[0], None if vals[0] is None else vals[0] + 1]
    start, stop = vals[0], vals[1]
    step = vals[2] if len(vals) == 3 else None
    if step is not None and step <= 0:
        raise SceneError(f"--frames {text!r}: STEP must be positive")
    for v in (start, stop):
        if v is not None and not -n <= v <= n:
            raise SceneError(f"--frames {text!r}: out of range; {source} has frames 0..{n - 1}")
    frames = list(range(n))[slice(start, stop, step)]
    if not frames:
        raise SceneError(f"--frames {text!r} selects no frame of {source} (frames 0..{n - 1})")
    return frames


@dataclass
class Drive:
    """Per-frame input of every muscle, in mesh units.

    ``to_body[name]`` maps a muscle's or bone's mesh coordinates (given in
    its ``frame`` at the rest pose) into the
    frame of the body that carries it, in which the muscle is deformed;
    ``to_output[body][k]`` maps that body's frame to the output frame at
    frame position ``k``.
    """

    frames: list[int]
    times: FloatArray
    rest_lines: dict[str, dict[str, FloatArray]]
    lines: dict[str, list[dict[str, FloatArray]]]
    rest_reference: dict[str, FloatArray | None]
    references: dict[str, list[FloatArray | None]]
    to_body: dict[str, FloatArray]
    to_output: dict[str, FloatArray]
    notes: list[str] = field(default_factory=list)
    moment_arms: MomentArmPoses | None = None
    waypoints: Waypoints | None = None
    #: each frame's value (n,) of the driven and moment-arm coordinates: degrees for a
    #: rotational coordinate, mm for a translational one (empty without a model)
    coordinate_values: dict[str, FloatArray] = field(default_factory=dict)
    #: the coordinate the motion sweeps: the only one of them that changes over the frames
    swept: str | None = None
    #: the unit of each of ``coordinate_values``: "deg" or "mm"
    coordinate_units: dict[str, str] = field(default_factory=dict)
    #: each body's frame to the ground's (the scene's, without a model) at the rest pose
    rest_poses: dict[str, FloatArray] = field(default_factory=dict)
    #: per muscle, the bodies its paths' first points and last points are fixed in at the
    #: rest pose (its origin's and insertion's; empty without a model)
    path_ends: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = field(default_factory=dict)
    #: the model, posable at any coordinates (`drive_scene(keep_poser=True)` only)
    poser: Poser | None = field(default=None, repr=False, compare=False)

    def rest_between(self, a: str, b: str) -> FloatArray:
        """Body ``a``'s frame to body ``b``'s at the rest pose (4 x 4, mesh units)."""
        return invert_rigid(self.rest_poses[b]) @ self.rest_poses[a]


@dataclass
class Waypoints:
    """Poses on a path from the rest pose to every frame: where contact takes its sides.

    Which side of a bone a muscle belongs on is a matter of the way it came (see
    `musclewrap.contact.SideReference`). Each frame is solved from the rest pose on
    its own, so the way is made up: a lattice over the driven coordinates, ``steps``
    apart from the rest pose, and from each pose the lattice point one step nearer
    the rest pose along the straight line to it (``parent``): the waypoints are
    shared by all frames near each other, and a frame's result depends on its pose
    alone (not on the frames around it, the chunks or the workers).

    ``nodes`` (K, d) are the lattice points (in steps from the rest pose), in an
    order where each one's ``parent`` (an index, -1: the rest pose) comes before
    it; ``frame`` (n,) is each frame's waypoint (-1: the rest pose); ``lines``,
    ``references`` per muscle and ``to_output`` per body as in `Drive`, at each
    waypoint; ``rest`` the rest pose's coordinates (model units) and ``rotational``
    which of them are angles.
    """

    coordinates: tuple[str, ...]
    steps: FloatArray
    nodes: npt.NDArray[np.int64]
    parent: npt.NDArray[np.int64]
    frame: npt.NDArray[np.int64]
    lines: dict[str, list[dict[str, FloatArray]]]
    references: dict[str, list[FloatArray | None]]
    to_output: dict[str, FloatArray]
    rest: FloatArray | None = None
    rotational: tuple[bool, ...] = ()

    def describe(self, k: int) -> str:
        """Waypoint ``k``'s pose in words: ``hip_flexion_r 40 deg, hip_adduction_r -10 deg``."""
        rest = np.zeros(len(self.coordinates)) if self.rest is None else self.rest
        rot = self.rotational or (True,) * len(self.coordinates)
        v = rest + self.nodes[k] * self.steps
        return ", ".join(
            f"{c} {np.degrees(x):.4g} deg" if r else f"{c} {x:.4g}"
            for c, x, r in zip(self.coordinates, v.tolist(), rot, strict=True)
        )


def lattice_parent(u: FloatArray) -> FloatArray:
    """The lattice point one step nearer the origin than ``u`` on the way to it.

    ``u`` is a pose in steps from the rest pose; with ``N`` the number of steps of
    its largest coordinate (rounded up), the parent is ``u (N - 1) / N`` rounded
    to the lattice (half away from zero): the straight line to the rest pose,
    followed on the lattice. Within one step of the rest pose: the rest pose.
    """
    u = np.asarray(u, dtype=np.float64)
    n = int(np.ceil(float(np.abs(u).max(initial=0.0)) - 1e-9))
    if n <= 1:
        return np.zeros_like(u)
    v = u * (n - 1) / n
    return np.sign(v) * np.floor(np.abs(v) + 0.5)


def lattice_paths(
    U: FloatArray,
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """The waypoints of the poses ``U`` (n, d): ``nodes``, ``parent`` and each pose's waypoint.

    As in `Waypoints`: ``nodes`` (K, d) ordered by their largest coordinate, then
    lexicographically (so that a parent comes first), ``parent`` (K,) and the
    poses' waypoints (n,), -1 for the rest pose.
    """
    U = np.atleast_2d(np.asarray(U, dtype=np.float64))
    first = [lattice_parent(u) for u in U]
    seen: dict[tuple[int, ...], None] = {}
    for p in first:
        while np.any(p != 0):
            key = tuple(int(x) for x in p)
            if key in seen:
                break
            seen[key] = None
            p = lattice_parent(p)
    keys = sorted(seen, key=lambda k: (max(abs(x) for x in k), k))
    index = {k: i for i, k in enumerate(keys)}

    def at(p: FloatArray) -> int:
        return -1 if not np.any(p != 0) else index[tuple(int(x) for x in p)]

    d = U.shape[1]
    nodes = np.array(keys, dtype=np.int64).reshape(-1, d)
    parent = np.array([at(lattice_parent(n)) for n in nodes], dtype=np.int64)
    return nodes, parent, np.array([at(p) for p in first], dtype=np.int64)


def one_sided(sign: int, second_order: bool) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Offsets and weights of the one-sided difference towards ``sign`` (-1 or +1).

    Second order: ``(-3 L(q) + 4 L(q + s h) - L(q + 2 s h)) / (2 s h)``; first order
    where the path changes again within ``2 h``.
    """
    if second_order:
        return (0.0, sign, 2.0 * sign), (-1.5 * sign, 2.0 * sign, -0.5 * sign)
    return (0.0, float(sign)), (-1.0 * sign, 1.0 * sign)


#: the central difference ``dL/dq ~ sum(w L(q + o h)) / h``: offsets ``o`` and weights ``w``
CENTRAL = ((-1.0, 1.0), (-0.5, 0.5))


@dataclass(frozen=True)
class Stencil:
    """A frame's one-sided moment arm of one muscle about one coordinate.

    Per pose of the difference (``dL/dq ~ sum(weights * L) / h``): the muscle's lines and
    reference point (as in `musclewrap.scene._drive.Drive`), its body's transform
    ``to_output`` (P, 4, 4) and each bone's ``bone_T`` (P, 4, 4).
    """

    weights: tuple[float, ...]
    lines: tuple[dict[str, FloatArray], ...]
    references: tuple[FloatArray | None, ...]
    to_output: FloatArray
    bone_T: dict[str, FloatArray]


@dataclass
class MomentArmPoses:
    """The poses on either side of each frame for moment arms by differences.

    For frame position ``k`` and moment-arm coordinate ``c``, the pose is the frame's
    with ``c`` moved by ``-steps[c]`` (side 0) and ``+steps[c]`` (side 1), in model
    units. ``lines[muscle][k][c][side]`` and ``references`` are as in `Drive`;
    ``to_output[body]`` is (n, C, 2, 4, 4). ``line[path]`` is (n, C): the moment arm
    ``-dL/dq`` of the action line (its poly-line's length ``L``), and ``opensim[path]``
    (n, C) OpenSim's ``computeMomentArm`` in the frame's pose; both in mesh units for a
    rotational coordinate, and without units for a translational one. ``per_q[c]``
    turns a length difference (mesh units) over ``steps[c]`` into those units.

    ``switch[path]`` (n, C) marks where the path's points differ in number between
    the frame and a side pose (a conditional via point switched, or a wrap began or
    ended: the length has a kink, or a step, between them). There the path's moment
    arm is the one-sided difference on the side whose points are the frame's
    (`one_sided`: the path OpenSim's moment arm is taken on), and so is a muscle's,
    its fibres' included, when all its switching paths agree on the side:
    ``one_sided[muscle][(k, c)]`` is its `Stencil`. ``both_sides[path]`` marks where
    the path's points change on both sides, so that no side is free of the change
    (the central difference is kept there).
    """

    coordinates: tuple[str, ...]
    steps: FloatArray
    per_q: FloatArray
    lines: dict[str, list[list[tuple[dict[str, FloatArray], dict[str, FloatArray]]]]]
    references: dict[str, list[list[tuple[FloatArray | None, FloatArray | None]]]]
    to_output: dict[str, FloatArray]
    line: dict[str, FloatArray]
    opensim: dict[str, FloatArray]
    switch: dict[str, npt.NDArray[np.bool_]]
    both_sides: dict[str, npt.NDArray[np.bool_]]
    one_sided: dict[str, dict[tuple[int, int], Stencil]]


def polyline_length(P: FloatArray) -> float:
    """Length of a poly-line (k, 3)."""
    return float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())


def _angle_in_degrees(scene: Scene, motion, model: OpenSimModel, coords) -> tuple[bool, str]:  # noqa: ANN001
    rot = [c for c in coords if model.is_rotational(c)]
    peak = max((float(np.abs(motion.columns[c]).max()) for c in rot), default=0.0)
    worst = max(rot, key=lambda c: float(np.abs(motion.columns[c]).max())) if rot else ""
    if scene.angle_unit != "header":
        deg = scene.angle_unit == "deg"
        how = f"angles in {'degrees' if deg else 'radians'} ([model] angle_unit)"
    elif motion.degrees_declared:
        deg = motion.in_degrees
        how = f"angles in {'degrees' if deg else 'radians'} (header inDegrees)"
    else:
        deg = peak > 2 * np.pi
        how = (
            f"no inDegrees line in the header: angles taken as {'degrees' if deg else 'radians'} "
            f"(largest |value| {peak:.3g} in '{worst}'); set [model] angle_unit to be explicit"
        )
    if not deg and peak > 2 * np.pi + 1e-9:
        raise SceneError(
            f"{motion.path}: angles are read as radians but '{worst}' reaches {peak:.4g} "
            f"(more than a full turn): the motion looks like degrees; fix its header "
            f"(inDegrees=yes) or set [model] angle_unit = 'deg'"
        )
    if deg and 0 < peak <= 2 * np.pi:
        # every rotation stays within 6.3 degrees: radians written under a degrees header?
        how += (
            f"; note: the largest angle is {peak:.3g} degrees ('{worst}'): if the motion is in "
            "radians, fix its header (inDegrees=no) or set [model] angle_unit = 'rad'"
        )
    return deg, how


def drive_scene(
    scene: Scene,
    frames: str | None,
    bone_centroids: dict[str, FloatArray],
    *,
    waypoints: bool = False,
    keep_poser: bool = False,
) -> Drive:
    """Compute every muscle's action lines for the selected frames.

    A model's lines are `PathLines` (their points' bodies' rotations turn the muscle);
    a line CSV's come with the muscles' reference points.

    Parameters
    ----------
    scene : Scene
        The parsed scene.
    frames : str or None
        ``start:stop:step`` over the motion's rows (or the CSV's frames).
    bone_centroids : dict of str to (3,) array
        Centroid of each bone mesh in mesh coordinates (a line CSV's reference points).
    waypoints : bool, optional
        Also the poses on the paths from the rest pose to the frames (`Waypoints`;
        a model's scene only: a line CSV has no poses in between).
    """
    if scene.osim is not None and scene.motion is not None:
        return _drive_opensim(scene, frames, waypoints, keep_poser)
    if scene.lines_csv is not None:
        return _drive_csv(scene, frames, bone_centroids)
    raise SceneError(f"{scene.path}: nothing drives the scene (no motion, no line CSV)")


def rest_pose(scene: Scene, model: OpenSimModel) -> dict[str, float]:
    """Every coordinate at the scene's rest pose (model units: radians or metres)."""
    names = model.coordinate_names
    rest = model.default_pose()
    for c, v in scene.rest_pose.items():
        if c not in names:
            raise SceneError(
                f"{scene.path}: [model] rest_pose names '{c}', not a coordinate of "
                f"{model.path.name}; " + suggest(c, names)
            )
        rest[c] = np.radians(v) if model.is_rotational(c) else v
    return rest


class Poser:
    """A scene's model, posed at any coordinates: the lines and bodies a run takes there.

    ``coordinates`` are those the scene drives (in the motion's order), ``degrees``
    whether the motion gives their angles in degrees, ``rest`` every coordinate at the
    rest pose (model units). `pose` turns values in the motion's units into a pose, as
    a run does for each frame; `at` gives that pose's lines and output transforms.
    """

    def __init__(
        self,
        scene: Scene,
        model: OpenSimModel,
        bodies: list[str],
        coordinates: list[str],
        degrees: bool,
        rest: dict[str, float],
    ) -> None:
        self.scene, self.model, self.bodies = scene, model, bodies
        self.coordinates, self.degrees, self.rest = coordinates, degrees, rest
        self.s = scene.scale
        #: per coordinate, its values at the frames driven (the motion's units)
        self.motion_values: dict[str, FloatArray] = {}
        model.set_pose(rest)
        # every body's orientation at the rest pose: a path point's body turns from there
        self.rest_R = {
            b: model.transform(b, "ground")[:3, :3] for b in (*model.body_names, "ground")
        }
        #: per path, its set's size and whether a point of it can be off (conditional)
        self.path_sets = {p: model.path_set_conditional(p) for m in scene.muscles for p in m.paths}

    def transform(self, body: str, frame: str) -> FloatArray:
        """Body's frame to ``frame`` at the model's current pose (mesh units)."""
        T = self.model.transform(body, frame)
        T[:3, 3] *= self.s
        return T

    def pose(self, values: dict[str, float]) -> dict[str, float]:
        """The rest pose with ``values`` (the motion's units) of driven coordinates set."""
        pose = dict(self.rest)
        for c, v in values.items():
            pose[c] = np.radians(v) if (self.degrees and self.model.is_rotational(c)) else v
        return pose

    def lines_now(
        self,
    ) -> tuple[
        dict[str, dict[str, FloatArray]], dict[str, FloatArray | None], dict[str, FloatArray]
    ]:
        """Every muscle's lines (`PathLines`) and every body's frame to ground, as posed now."""
        scene, model, rest_R, s = self.scene, self.model, self.rest_R, self.s
        to_g = {b: self.transform(b, "ground") for b in self.bodies}
        turned: dict[str, FloatArray] = {}  # body -> its rotation from the rest pose (ground)

        def turn(b: str) -> FloatArray:
            if b not in turned:
                G = to_g[b][:3, :3] if b in to_g else model.transform(b, "ground")[:3, :3]
                turned[b] = G @ rest_R[b].T
            return turned[b]

        def turns(bodies: list[str], body: str) -> FloatArray:
            # per point, its body's rotation from the rest pose in the frame of ``body``
            mb = rest_R[body].T @ turn(body).T
            return np.array([mb @ turn(b) @ rest_R[body] for b in bodies])

        L, R = {}, {}
        for m in scene.muscles:
            pts = {p: model.path_points(p, m.body) * s for p in m.paths}
            keys = {}
            for p in m.paths:
                # every point of the path's set, active or not, turns the samples near it
                # (where they are the path's points, those turn them as they are)
                size, conditional = self.path_sets[p]
                if not conditional and len(pts[p]) == size:
                    continue  # every point of the set is on, and no wrap adds any
                X, bodies = model.path_set_points(p, m.body)
                X *= s
                if len(X) >= 2 and (X.shape != pts[p].shape or np.any(X != pts[p])):
                    keys[p] = (set_point_params(pts[p], X), turns(bodies, m.body))
            L[m.name] = PathLines(
                pts, {p: turns(model.path_point_bodies(p), m.body) for p in m.paths}, keys
            )
            R[m.name] = None  # the points' bodies turn it: no reference point
        return L, R, to_g

    def output_transforms(self, to_g: dict[str, FloatArray]) -> dict[str, FloatArray]:
        """Each body's frame to the output frame, from each body's frame to ground."""
        out = self.scene.output_frame
        out_inv = invert_rigid(to_g[out]) if out != "ground" else np.eye(4)
        return {b: out_inv @ to_g[b] for b in self.bodies}

    def at(
        self, pose: dict[str, float]
    ) -> tuple[
        dict[str, dict[str, FloatArray]], dict[str, FloatArray | None], dict[str, FloatArray]
    ]:
        """The lines, reference points and bodies' output transforms at ``pose``."""
        self.model.set_pose(pose)
        L, R, to_g = self.lines_now()
        return L, R, self.output_transforms(to_g)


def _drive_opensim(
    scene: Scene, frames_text: str | None, waypoints: bool, keep_poser: bool = False
) -> Drive:
    model = OpenSimModel(scene.osim)
    motion = read_motion(scene.motion)
    names = model.coordinate_names
    if scene.coordinates is not None:
        coords = list(scene.coordinates)
        for c in coords:
            if c not in names:
                raise SceneError(
                    f"{scene.path}: [model] coordinates: the model has no coordinate '{c}'; "
                    + suggest(c, names)
                )
            if c in motion.repeated:
                raise SceneError(f"{motion.path}: the column '{c}' occurs more than once")
            if c not in motion.columns:
                raise SceneError(
                    f"{motion.path}: the motion has no column '{c}'; "
                    + suggest(c, list(motion.columns))
                )
    else:
        coords = [c for c in motion.columns if c in names]
        if not coords:
            raise SceneError(
                f"{motion.path}: none of its columns is a coordinate of {model.path.name} "
                f"(model coordinates: {', '.join(names)})"
            )
    notes = []
    ignored = [c for c in motion.columns if c not in coords]
    if ignored:
        notes.append(
            f"motion columns not used ({len(ignored)}): {', '.join(ignored[:6])}"
            + (" ..." if len(ignored) > 6 else "")
        )
    deg, how = _angle_in_degrees(scene, motion, model, coords)
    notes.append(how)
    rest = rest_pose(scene, model)
    pos = parse_frames(frames_text, motion.n_frames, source=str(motion.path))
    s = scene.scale
    for spec in scene.muscles:
        model.check_body(spec.body)
        for p in spec.paths:
            model.check_path(p)
    for b in scene.bones:
        model.check_body(b.body)
    model.check_body(scene.output_frame)
    for spec in scene.muscles:
        if spec.reference is not None:
            notes.append(
                f"[muscles.{spec.name}] reference '{spec.reference}' is not used with a model: "
                "the muscle turns with the bodies its path's points are fixed in"
            )

    reg = scene.registration
    bodies = sorted({m.body for m in scene.muscles} | {b.body for b in scene.bones} | {
        x.frame for x in (*scene.muscles, *scene.bones) if x.frame != "registration"} | {
        lm.body for lm in (reg.landmarks if reg else ())} | {"ground", scene.output_frame})  # fmt: skip
    model.set_pose(rest)
    for b in bodies:
        model.check_body(b)
    poser = Poser(scene, model, bodies, list(coords), deg, rest)
    transform = poser.transform
    g = {b: transform(b, "ground") for b in bodies}
    if reg is not None:
        g["registration"] = _register(scene, g, s, notes)
    to_body = {x.name: invert_rigid(g[x.body]) @ g[x.frame] for x in (*scene.muscles, *scene.bones)}
    lines_now, output_transforms = poser.lines_now, poser.output_transforms

    rest_lines, rest_ref, _ = lines_now()
    ends = {p: model.path_point_bodies(p) for m in scene.muscles for p in m.paths}
    path_ends = {
        m.name: (
            tuple(sorted({ends[p][0] for p in m.paths})),
            tuple(sorted({ends[p][-1] for p in m.paths})),
        )
        for m in scene.muscles
    }
    lines = {m.name: [] for m in scene.muscles}
    refs = {m.name: [] for m in scene.muscles}
    out_T = {b: np.empty((len(pos), 4, 4)) for b in bodies}
    values = {c: motion.columns[c] for c in coords}
    # the driven values of the frames run, as read (the live viewer poses frames from them)
    poser.motion_values = {c: np.asarray(values[c])[pos] for c in coords}
    ma = _moment_arm_poses(scene, model, len(pos), bodies)

    driven = np.empty((len(pos), len(coords)))
    for k, i in enumerate(pos):
        pose = poser.pose({c: values[c][i] for c in coords})
        driven[k] = [pose[c] for c in coords]
        model.set_pose(pose)
        L, R, to_g = lines_now()
        if ma is not None:
            for p in ma.opensim:
                for j, c in enumerate(ma.coordinates):
                    ma.opensim[p][k, j] = model.moment_arm(p, c) * s * ma.per_q[j]
        for m in scene.muscles:
            lines[m.name].append(L[m.name])
            refs[m.name].append(R[m.name])
        for b, T in output_transforms(to_g).items():
            out_T[b][k] = T
        if ma is None:
            continue
        for m in scene.muscles:
            ma.lines[m.name].append([])
            ma.references[m.name].append([])
        for j, c in enumerate(ma.coordinates):
            _frame_moment_arms(
                scene, model, ma, k, j, pose, (L, R, to_g), lines_now, output_transforms
            )
        model.set_pose(pose)
    notes += _outside_ranges(model, coords, driven, pos, motion.time)
    shown = list(dict.fromkeys([*coords, *(ma.coordinates if ma is not None else ())]))
    shown_values = {}
    for c in shown:
        q = driven[:, list(coords).index(c)] if c in coords else np.full(len(pos), rest[c])
        shown_values[c] = (
            np.degrees(q) if model.is_rotational(c) else q * UNITS[scene.model_unit] * 1e3
        )
    moving = [c for c in coords if np.ptp(shown_values[c]) > 1e-9]
    path = None
    if waypoints:
        path = _waypoints(scene, model, coords, rest, driven, bodies, lines_now, output_transforms)
        model.set_pose(rest)
    return Drive(
        poser=poser if keep_poser else None,
        frames=pos,
        times=motion.time[pos],
        rest_lines=rest_lines,
        lines=lines,
        rest_reference=rest_ref,
        references=refs,
        to_body=to_body,
        to_output=out_T,
        notes=notes,
        rest_poses={b: T for b, T in g.items() if b != "registration"},
        moment_arms=ma,
        waypoints=path,
        coordinate_values=shown_values,
        swept=moving[0] if len(moving) == 1 else None,
        coordinate_units={c: "deg" if model.is_rotational(c) else "mm" for c in shown},
        path_ends=path_ends,
    )


def _frame_moment_arms(
    scene: Scene,
    model: OpenSimModel,
    ma: MomentArmPoses,
    k: int,
    j: int,
    pose: dict[str, float],
    here: tuple[Any, Any, dict[str, FloatArray]],
    lines_now: Any,
    output_transforms: Any,
) -> None:
    """Frame ``k``'s poses, action-line moment arms and stencils about coordinate ``j``."""
    c, h = ma.coordinates[j], ma.steps[j]
    poses: dict[float, tuple[Any, Any, dict[str, FloatArray]]] = {0.0: here}

    def at(o: float) -> tuple[Any, Any, dict[str, FloatArray]]:
        if o not in poses:
            model.set_pose({**pose, c: pose[c] + o * h})
            poses[o] = lines_now()
        return poses[o]

    def count(m: str, p: str, o: float) -> int:
        return len(at(o)[0][m][p])

    (Lm, Rm, gm), (Lp, Rp, gp) = at(-1.0), at(1.0)
    for side, g in enumerate((gm, gp)):
        for b, T in output_transforms(g).items():
            ma.to_output[b][k, j, side] = T
    for m in scene.muscles:
        name = m.name
        ma.lines[name][k].append((Lm[name], Lp[name]))
        ma.references[name][k].append((Rm[name], Rp[name]))
        signs = set()
        for p in m.paths:
            n0 = count(name, p, 0.0)
            moved = (count(name, p, -1.0) != n0, count(name, p, 1.0) != n0)
            ma.switch[p][k, j] = any(moved)
            ma.both_sides[p][k, j] = all(moved)
            offsets, weights = CENTRAL
            if any(moved) and not all(moved):
                sign = 1 if moved[0] else -1
                signs.add(sign)
                offsets, weights = one_sided(sign, count(name, p, 2.0 * sign) == n0)
            dL = sum(w * polyline_length(at(o)[0][name][p]) for o, w in zip(offsets, weights))
            ma.line[p][k, j] = -dL / h * ma.per_q[j]
        if len(signs) == 1:
            (sign,) = signs
            second = all(count(name, p, 2.0 * sign) == count(name, p, 0.0) for p in m.paths)
            offsets, weights = one_sided(sign, second)
            got = [at(o) for o in offsets]
            to_out = [output_transforms(g) for _, _, g in got]
            ma.one_sided[name][(k, j)] = Stencil(
                weights=weights,
                lines=tuple(L[name] for L, _, _ in got),
                references=tuple(R[name] for _, R, _ in got),
                to_output=np.stack([T[m.body] for T in to_out]),
                bone_T={b.name: np.stack([T[b.body] for T in to_out]) for b in scene.bones},
            )


def _reversed(model: OpenSimModel, c: str, v: FloatArray) -> bool:
    """Whether angle ``c``'s values ``v`` (radians) look written with the opposite sign.

    Outside the model's range on more than half the frames, and within it on all but
    a twentieth of them once negated: a motion written for a model that turns the
    joint the other way (gait2392's knee flexes negative, Rajagopal 2016's positive;
    gait2392's walk reaches +1.1 deg on 4 of its 211 frames). A coordinate that leaves
    its range on a few frames only is not (its negation could fit a one-sided range).
    """
    if not model.is_rotational(c) or not len(v):
        return False
    lo, hi = model.coordinate_range(c)
    outside = (v < lo) | (v > hi)
    flipped_out = (-v < lo) | (-v > hi)
    return bool(2 * outside.sum() > len(v) and 20 * flipped_out.sum() <= len(v))


def reversed_coordinates(
    scene: Scene, motion: Motion, model: OpenSimModel, coords: list[str]
) -> list[str]:
    """The angles of ``coords`` that ``motion`` seems to give with the opposite sign.

    Each as `_reversed` decides, on every frame of the motion, its angles read as a
    run reads them (the scene's ``[model] angle_unit`` or the header).
    """
    coords = [c for c in coords if c in motion.columns and model.is_rotational(c)]
    if not coords:
        return []
    deg, _ = _angle_in_degrees(scene, motion, model, coords)
    return [
        c
        for c in coords
        if _reversed(model, c, np.radians(motion.columns[c]) if deg else motion.columns[c])
    ]


def _outside_ranges(
    model: OpenSimModel, coords: list[str], driven: FloatArray, frames: list[int], times: FloatArray
) -> list[str]:
    """A note per coordinate that leaves the model's range: on which frames, how far."""
    out = []
    for j, c in enumerate(coords):
        lo, hi = model.coordinate_range(c)
        v = driven[:, j]
        bad = np.flatnonzero((v < lo) | (v > hi))
        if not len(bad):
            continue
        rot = model.is_rotational(c)
        unit = "deg" if rot else "model units"
        conv = np.degrees if rot else (lambda x: x)
        worst = int(bad[np.argmax(np.maximum(lo - v[bad], v[bad] - hi))])
        runs = _frame_runs(frames, bad)
        out.append(
            f"{c} leaves the model's range [{conv(lo):.4g}, {conv(hi):.4g}] {unit} on "
            f"{len(bad)} frame(s) ({runs}): up to {float(conv(v[worst])):.4g} {unit} at frame "
            f"{frames[worst]} (t = {float(times[frames[worst]]):.4g} s); the model's paths and "
            "the muscles are extrapolated there"
            + (
                f"; negated, it lies within the range on nearly every frame run: the motion may turn "
                f"it the other way from {model.path.name} (written for another model?); negate "
                "its column if so"
                if _reversed(model, c, v)
                else ""
            )
        )
    return out


def _frame_runs(frames: list[int], picked: IntArray) -> str:
    """``3-7, 12, 20-24``: the frames at positions ``picked`` as runs of the frames run.

    At most six runs are named.
    """
    runs: list[list[int]] = []
    for k in picked.tolist():
        if runs and k == runs[-1][1] + 1:
            runs[-1][1] = k
        else:
            runs.append([k, k])
    text = [f"{frames[a]}" if a == b else f"{frames[a]}-{frames[b]}" for a, b in runs]
    return ", ".join(text[:6]) + (f" and {len(text) - 6} more runs" if len(text) > 6 else "")


def _waypoints(
    scene: Scene,
    model: OpenSimModel,
    coords: list[str],
    rest: dict[str, float],
    driven: FloatArray,
    bodies: list[str],
    lines_now: Any,
    output_transforms: Any,
) -> Waypoints:
    """The lattice of poses between the rest pose and the frames (`Waypoints`)."""
    steps = np.array(
        [
            np.radians(defaults.path_step)
            if model.is_rotational(c)
            else defaults.path_step_translation * 1e-3 / UNITS[scene.model_unit]
            for c in coords
        ]
    )
    r = np.array([rest[c] for c in coords])
    nodes, parent, frame = lattice_paths((driven - r) / steps)
    lines: dict[str, list[dict[str, FloatArray]]] = {m.name: [] for m in scene.muscles}
    refs: dict[str, list[FloatArray | None]] = {m.name: [] for m in scene.muscles}
    out_T = {b: np.empty((len(nodes), 4, 4)) for b in bodies}
    for k, u in enumerate(nodes):
        model.set_pose({**rest, **dict(zip(coords, (r + u * steps).tolist(), strict=True))})
        L, R, to_g = lines_now()
        for m in scene.muscles:
            lines[m.name].append(L[m.name])
            refs[m.name].append(R[m.name])
        for b, T in output_transforms(to_g).items():
            out_T[b][k] = T
    rot = tuple(bool(model.is_rotational(c)) for c in coords)
    return Waypoints(tuple(coords), steps, nodes, parent, frame, lines, refs, out_T, r, rot)


def _moment_arm_poses(
    scene: Scene, model: OpenSimModel, n: int, bodies: list[str]
) -> MomentArmPoses | None:
    if scene.fibres is None or not scene.fibres.output or not scene.fibres.moment_arms:
        return None
    names = model.coordinate_names
    for c in scene.fibres.moment_arms:
        if c not in names:
            raise SceneError(
                f"{scene.path}: [fibres] moment_arms: the model has no coordinate '{c}'; "
                + suggest(c, names)
            )
    coords = scene.fibres.moment_arms
    rot = np.array([model.is_rotational(c) for c in coords])
    s = scene.scale
    # a rotational step in degrees; a translational one in millimetres (model units here)
    steps = np.where(
        rot, np.radians(scene.fibres.step), scene.fibres.step * 1e-3 / UNITS[scene.model_unit]
    )
    paths = [p for m in scene.muscles for p in m.paths]
    return MomentArmPoses(
        coordinates=tuple(coords),
        steps=steps,
        per_q=np.where(rot, 1.0, 1.0 / s),
        lines={m.name: [] for m in scene.muscles},
        references={m.name: [] for m in scene.muscles},
        to_output={b: np.empty((n, len(coords), 2, 4, 4)) for b in bodies},
        line={p: np.empty((n, len(coords))) for p in paths},
        opensim={p: np.empty((n, len(coords))) for p in paths},
        switch={p: np.zeros((n, len(coords)), dtype=bool) for p in paths},
        both_sides={p: np.zeros((n, len(coords)), dtype=bool) for p in paths},
        one_sided={m.name: {} for m in scene.muscles},
    )


_CSV_HEADER = ["frame", "time", "muscle", "line", "point", "x", "y", "z"]


def _drive_csv(scene: Scene, frames_text: str | None, centroids: dict[str, FloatArray]) -> Drive:
    p = scene.lines_csv
    data: dict[int, dict[str, dict[str, list[tuple[int, list[float]]]]]] = {}
    times: dict[int, float] = {}
    muscles = {m.name for m in scene.muscles}
    for row_no, row in csv_rows(p, _CSV_HEADER, error=SceneError):
        try:
            frame, point = int(row[0]), int(row[4])
            t = float(row[1])
            xyz = [float(v) for v in row[5:]]
        except ValueError:
            raise SceneError(
                f"{p}: row {row_no} has a non-numeric frame, time, point or coordinate"
            ) from None
        if not np.isfinite(xyz).all() or not np.isfinite(t):
            raise SceneError(f"{p}: row {row_no} has a NaN or infinite value")
        muscle, line = row[2].strip(), row[3].strip()
        if muscle not in muscles:
            raise SceneError(
                f"{p}: row {row_no} names muscle '{muscle}', not in the scene; "
                + suggest(muscle, sorted(muscles))
            )
        if times.setdefault(frame, t) != t:
            raise SceneError(f"{p}: frame {frame} has two different times")
        data.setdefault(frame, {}).setdefault(muscle, {}).setdefault(line, []).append((point, xyz))
    if not data:
        raise SceneError(f"{p}: no action-line rows")
    order = sorted(data)
    if scene.rest_frame not in data:
        raise SceneError(
            f"{scene.path}: [lines] rest_frame = {scene.rest_frame} is not a frame of {p} (frames {order[0]}..{order[-1]})"
        )

    def frame_lines(
        f: int,
    ) -> tuple[dict[str, dict[str, FloatArray]], dict[str, FloatArray | None]]:
        L, R = {}, {}
        for m in scene.muscles:
            got = data[f].get(m.name)
            if not got:
                raise SceneError(f"{p}: frame {f} has no lines for muscle '{m.name}'")
            lines = {}
            for name, pts in got.items():
                pts = sorted(pts)
                idx = [q for q, _ in pts]
                if len(set(idx)) != len(idx):
                    raise SceneError(
                        f"{p}: frame {f}, muscle '{m.name}', line '{name}' repeats a point number"
                    )
                lines[name] = np.array([xyz for _, xyz in pts])
            ref = lines.pop("reference", None)
            if ref is not None and len(ref) != 1:
                raise SceneError(
                    f"{p}: frame {f}, muscle '{m.name}': 'reference' must be one point"
                )
            R[m.name] = None if ref is None else ref[0]
            if not lines:
                raise SceneError(f"{p}: frame {f} has no action line for muscle '{m.name}'")
            L[m.name] = lines
        return L, R

    pos = parse_frames(frames_text, len(order), source=str(p))
    # the bodies' poses: the rest frame's and the selected frames' (ground does not move)
    moving = sorted({b.body for b in scene.bones} - {"ground"})
    poses = _body_poses(scene, moving, [scene.rest_frame] + [order[k] for k in pos], times)
    poses["ground"] = [np.eye(4)] * (1 + len(pos))
    to_body = {x.name: np.eye(4) for x in (*scene.muscles, *scene.bones)}
    for b in scene.bones:
        # a mesh in its body's own frame, or in the scene's at the rest frame
        if b.frame == "ground":
            to_body[b.name] = invert_rigid(poses[b.body][0])
        elif b.frame != b.body:
            raise SceneError(
                f"{scene.path}: [bones.{b.name}] frame = '{b.frame}': without a model a mesh "
                "is in its body's frame ('body') or the scene's at the rest frame ('ground')"
            )
    body_of = {b.name: b.body for b in scene.bones}

    def centroid(bone: str, i: int) -> FloatArray:
        # a bone's centroid in the scene's frame at the rest frame (0) or at frame pos[i - 1]
        return apply_transform(poses[body_of[bone]][i] @ to_body[bone], centroids[bone])

    rest_lines, rest_ref = frame_lines(scene.rest_frame)
    for m in scene.muscles:
        if m.reference is not None and rest_ref[m.name] is None:
            rest_ref[m.name] = centroid(m.reference, 0)
    lines = {m.name: [] for m in scene.muscles}
    refs = {m.name: [] for m in scene.muscles}
    for i, k in enumerate(pos, start=1):
        L, R = frame_lines(order[k])
        for m in scene.muscles:
            if set(L[m.name]) != set(rest_lines[m.name]):
                raise SceneError(
                    f"{p}: frame {order[k]} names lines {sorted(L[m.name])} for '{m.name}', the rest "
                    f"frame {sorted(rest_lines[m.name])}"
                )
            lines[m.name].append(L[m.name])
            ref = R[m.name]
            if ref is None and m.reference is not None:
                ref = centroid(m.reference, i)
            if (ref is None) != (rest_ref[m.name] is None):
                raise SceneError(
                    f"{p}: muscle '{m.name}' has a reference point in some frames only"
                )
            refs[m.name].append(ref)
    notes = [f"action lines from {p.name} (rest frame {scene.rest_frame})"]
    if moving:
        assert scene.bodies_csv is not None
        notes.append(f"poses of {', '.join(moving)} from {scene.bodies_csv.name}")
    return Drive(
        frames=[order[k] for k in pos],
        times=np.array([times[order[k]] for k in pos]),
        rest_lines=rest_lines,
        lines=lines,
        rest_reference=rest_ref,
        references=refs,
        to_body=to_body,
        to_output={b: np.stack(poses[b][1:]) for b in poses},
        notes=notes,
        rest_poses={b: T[0] for b, T in poses.items()},
    )


_BODIES_HEADER = ["frame", "time", "body"] + [f"r{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3)]
_BODIES_HEADER += ["x", "y", "z"]


def _body_poses(
    scene: Scene, bodies: list[str], frames: list[int], times: dict[int, float]
) -> dict[str, list[FloatArray]]:
    """Each body's pose (4 x 4, body frame to the scene's) at each of ``frames``.

    From ``[lines] bodies``: every body a bone names, at every frame wanted, once, a
    rotation (orthonormal to 1e-6, determinant +1) and a translation, at the line CSV's
    time of that frame.
    """
    if not bodies:
        return {}
    p = scene.bodies_csv
    if p is None:
        raise SceneError(
            f"{scene.path}: bones on {', '.join(bodies)} need the bodies' poses per frame "
            "([lines] bodies)"
        )
    got: dict[tuple[int, str], FloatArray] = {}
    for row_no, row in csv_rows(p, _BODIES_HEADER, error=SceneError):
        try:
            frame, t = int(row[0]), float(row[1])
            values = np.array([float(v) for v in row[3:]])
        except ValueError:
            raise SceneError(
                f"{p}: row {row_no} has a non-numeric frame, time or pose value"
            ) from None
        body = row[2].strip()
        if not np.isfinite(values).all() or not np.isfinite(t):
            raise SceneError(f"{p}: row {row_no} has a NaN or infinite value")
        if (frame, body) in got:
            raise SceneError(f"{p}: row {row_no} gives body '{body}' at frame {frame} again")
        if frame in times and not np.isclose(times[frame], t, rtol=0.0, atol=1e-9):
            raise SceneError(
                f"{p}: row {row_no}: frame {frame} at time {t:g}, the line CSV's at "
                f"{times[frame]:g}"
            )
        R = values[:9].reshape(3, 3)
        if np.abs(R @ R.T - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
            raise SceneError(
                f"{p}: row {row_no}: the rotation of '{body}' at frame {frame} is not a "
                "rotation (orthonormal rows, determinant +1, to 1e-6)"
            )
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, values[9:]
        got[(frame, body)] = T
    named = {b for _, b in got}
    out: dict[str, list[FloatArray]] = {}
    for b in bodies:
        if b not in named:
            raise SceneError(
                f"{p}: no poses of body '{b}' (a bone's body in {scene.path.name}); "
                + suggest(b, sorted(named))
            )
        missing = [f for f in frames if (f, b) not in got]
        if missing:
            raise SceneError(
                f"{p}: body '{b}' has no pose at frame(s) {', '.join(map(str, missing[:5]))}"
                + (" ..." if len(missing) > 5 else "")
            )
        out[b] = [got[(f, b)] for f in frames]
    return out
