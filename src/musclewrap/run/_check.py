"""``musclewrap check``: everything a run reads and validates, without deforming.

Each finding names what it is about, what is wrong and what to change in the scene.
An *error* would make a run wrong (or stop it); a *warning* deserves a look; a *note*
says what the run will do about something (a repair, a rest overlap it takes apart).
`check_scene` gathers them all instead of stopping at the first; ``musclewrap run``
refuses a scene with an error before it starts.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._typing import FloatArray, IntArray, PathLike
from ..constants import defaults
from ..errors import SceneError, suggest
from ..mesh import MeshError, apply_transform, mean_thickness
from ..model import (
    LineFit,
    OpenSimModel,
    line_fit,
    line_fits,
    match_muscle,
    outside_distance,
    path_anatomy,
    read_motion,
    resample_polyline,
)
from ..output import draw_check
from ..scene import (
    UNITS,
    Drive,
    MuscleSpec,
    Scene,
    drive_scene,
    load_scene,
    rest_pose,
    reversed_coordinates,
)
from ._fibres import choose_areas, describe_areas
from ._posture import posture_finding, rest_posture
from ._read import (
    _read_bone,
    _read_muscle,
    attachment_area,
    check_muscles_apart,
    default_cache_dir,
    end_bones,
    fit_bones,
    rest_lines_problem,
)
from ._verify import inside_depths, muscle_overlaps

__all__ = ["CheckReport", "Finding", "check_scene"]


@dataclass(frozen=True)
class Finding:
    """One thing `check_scene` found."""

    level: str  # "error", "warning" or "note"
    subject: str  # the muscle, bone, coordinate or file it is about ("scene": the whole)
    message: str
    fix: str = ""

    def __str__(self) -> str:
        return f"{self.level}: {self.subject}: {self.message}" + (
            f" -> {self.fix}" if self.fix else ""
        )


@dataclass
class CheckReport:
    """The findings, and the figures they were judged by."""

    path: Path
    findings: list[Finding] = field(default_factory=list)
    fits: dict[str, LineFit] = field(default_factory=dict)
    thickness: dict[str, float] = field(default_factory=dict)
    picture: Path | None = None

    @property
    def errors(self) -> list[Finding]:
        return [f for f in self.findings if f.level == "error"]

    @property
    def ok(self) -> bool:
        """No error: a run would not be wrong for any reason the check knows."""
        return not self.errors

    def add(self, level: str, subject: str, message: str, fix: str = "") -> None:
        self.findings.append(Finding(level, subject, message, fix))


def check_scene(
    scene: Scene | PathLike,
    *,
    picture: PathLike | None = None,
    cache_dir: Path | None | bool = True,
    log: Callable[[str], None] | None = None,
) -> CheckReport:
    """Check a scene at its rest pose: files, units, frames, lines, bodies, overlaps, motion.

    Parameters
    ----------
    scene : Scene or path
        A loaded scene, or its file (a file that does not load is one error).
    picture : path, optional
        Where to draw the rest pose from two sides (PNG): meshes translucent,
        bones, and the action lines coloured by their distance outside their muscle.
    cache_dir : path, True or False, optional
        Where the cleaned meshes are cached, as for `run_scene`.
    log : callable, optional
        Receives a line per step.

    Returns
    -------
    CheckReport
    """
    say = log or (lambda s: None)
    if not isinstance(scene, Scene):
        try:
            scene = load_scene(scene)
        except SceneError as exc:
            rep = CheckReport(Path(scene))
            rep.add("error", "scene", str(exc))
            return rep
    rep = CheckReport(scene.path)
    try:
        _check(scene, rep, picture, cache_dir, say)
    except (SceneError, ImportError) as exc:
        rep.add("error", "scene", str(exc))
    return rep


def _check(
    scene: Scene,
    rep: CheckReport,
    picture: PathLike | None,
    cache_dir: Path | None | bool,
    say: Callable[[str], None],
) -> None:

    cache: Path | None
    if cache_dir is True:
        cache = Path(scene.cache_dir or default_cache_dir())
    elif cache_dir is False or cache_dir is None:
        cache = None
    else:
        cache = Path(cache_dir)
    model = None
    if scene.osim is not None:
        model = OpenSimModel(scene.osim)
        if not _check_model(scene, model, rep):
            return
    say("reading the meshes")
    muscles: dict[str, tuple[FloatArray, IntArray]] = {}
    ids: dict[str, IntArray] = {}
    for m in scene.muscles:
        try:
            V, F, notes, ids[m.name] = _read_muscle(m, cache)
        except MeshError as exc:
            rep.add("error", m.name, str(exc), "repair the mesh, or set repair = true")
            continue
        for n in notes:
            rep.add("note", m.name, f"{m.mesh.name}: {n}")
        muscles[m.name] = (V, F)
    bones: dict[str, tuple[FloatArray, IntArray]] = {}
    for b in scene.bones:
        try:
            V, F, said, open_edges = _read_bone(b, cache)
        except (MeshError, ValueError) as exc:
            rep.add("error", b.name, str(exc))
            continue
        for n in said:
            rep.add("note", b.name, f"{b.mesh.name}: {n}")
        if open_edges:
            rep.add(
                "note", b.name,
                f"{b.mesh.name} is open ({open_edges} boundary edges): contact closes it first",
            )  # fmt: skip
        bones[b.name] = (V, F)
    if rep.errors:
        return

    say("the action lines at rest")
    drive = drive_scene(scene, "0:1", {n: V.mean(axis=0) for n, (V, _) in bones.items()})
    body_m = {n: (apply_transform(drive.to_body[n], V), F) for n, (V, F) in muscles.items()}
    body_b = {n: (apply_transform(drive.to_body[n], V), F) for n, (V, F) in bones.items()}
    if scene.registration is not None and scene.muscles:
        T = drive.to_body[scene.muscles[0].name]
        scale = float(np.cbrt(abs(np.linalg.det(T[:3, :3]))))
        if not 1 / 3 < scale < 3:
            # the units that would make the registration scale nearest 1
            now = scene.scale
            u, v = min(
                ((u, v) for u in UNITS for v in UNITS),
                key=lambda p: (abs(np.log(scale * (UNITS[p[1]] / UNITS[p[0]]) / now)), p[1] != "m"),
            )
            rep.add(
                "error", "scene",
                f"the registration scales the meshes by {scale:.3g}: the meshes and the model "
                "are not in the units [units] says (two subjects differ in size by far less)",
                f"set [units] mesh = '{u}', model = '{v}' (now '{scene.mesh_unit}', "
                f"'{scene.model_unit}')",
            )  # fmt: skip
            return
    if any(b.fit for b in scene.bones):
        say("fitting the bones to the muscles")
        said: list[str] = []
        for n, f in fit_bones(scene, drive, body_m, cache, lambda _: None, said).items():
            body_b[n] = (body_b[n][0] + f.move(body_b[n][0]), body_b[n][1])
        for text in said:
            rep.add("note", text.split(":", 1)[0], text.split(": ", 1)[1])
    _check_lines(scene, model, drive, body_m, rep, cache)
    if model is not None:
        _check_bone_bodies(scene, model, body_b, rep, cache)
        registered = {m.name: muscles[m.name] for m in scene.muscles if m.frame == "registration"}
        if scene.registration is not None and any(b.source for b in scene.bones):
            say("the rest pose against the model's bones")
            found = rest_posture(scene, model, registered, body_b, cache)
            if found is not None:
                message, fix = posture_finding(scene, found)
                rep.add("note" if not fix else "warning", "scene", message, fix)
    # every mesh placed in the output frame at rest, once for the overlaps and the picture
    to_out = {
        b: drive.rest_between(b, scene.output_frame)
        for b in {x.body for x in (*scene.muscles, *scene.bones)} | {"ground"}
    }
    rest_m = {n: (apply_transform(to_out[_body(scene, n)], V), F) for n, (V, F) in body_m.items()}
    rest_b = {n: (apply_transform(to_out[_body(scene, n)], V), F) for n, (V, F) in body_b.items()}
    _check_overlaps(scene, drive, body_m, rest_m, rest_b, rep, cache)
    areas = {}
    if scene.fibres is not None:
        say("the fibres' attachment areas")
        areas = _fibre_areas(scene, drive, body_m, body_b, ids, rep, cache)
    if picture is not None:
        say("drawing the rest pose")
        data = _picture_data(scene, model, drive, body_m, to_out, rep)
        # the areas' vertices in the output frame, as the muscles are drawn
        shown = {n: (rest_m[n][0][o], rest_m[n][0][i]) for n, (o, i) in areas.items()}
        rep.picture = draw_check(
            Path(picture), {**data, "muscles": rest_m, "bones": rest_b, "areas": shown}
        )


def _fibre_areas(
    scene: Scene, drive: Drive,
    body_m: dict[str, tuple[FloatArray, IntArray]],
    body_b: dict[str, tuple[FloatArray, IntArray]],
    ids: dict[str, IntArray],
    rep: CheckReport,
    cache: Path | None,
) -> dict[str, tuple[IntArray, IntArray]]:  # fmt: skip
    """Per muscle, the fibres' attachment areas the run takes (at rest, as segmented).

    As the run (`choose_areas`, on the bones of `end_bones`); each muscle's rule as a
    note.
    """
    from ..contact import Obstacle, Placed

    probes: dict[str, Obstacle] = {}

    def probe(name: str) -> Obstacle:
        if name not in probes:
            probes[name] = Obstacle.cached(*body_b[name], cache)  # the run's, where cached
        return probes[name]

    fibres = scene.fibres
    assert fibres is not None
    out = {}
    for spec in scene.muscles:
        V, F = body_m[spec.name]
        try:
            given = tuple(
                attachment_area(scene, drive, spec, k, V, ids[spec.name])
                for k in ("origin", "insertion")
            )
        except SceneError as exc:
            rep.add("error", spec.name, str(exc))
            continue
        ends = end_bones(scene, drive, spec)
        placed = tuple(
            [Placed(probe(n), T) for n, T in bones if n in body_b] if g is None else []
            for bones, g in zip(ends, given, strict=True)
        )
        try:
            o, i, rules = choose_areas(
                V, F, drive.rest_lines[spec.name], scene.margin, given, placed
            )
        except ValueError as exc:  # no axis: the lines' check says why
            rep.add("warning", spec.name, f"no fibres' attachment areas: {exc}")
            continue
        names = tuple(" or ".join(n for n, _ in bones if n in body_b) for bones in ends)
        note = describe_areas(
            rules, (given[0] is not None, given[1] is not None), (names[0], names[1]),
            (len(o), len(i)), fibres.attachments,
        )  # fmt: skip
        rep.add("note", spec.name, note)
        out[spec.name] = (o, i)
    return out


# ---------------------------------------------------------------------------- model, motion
def _check_model(scene: Scene, model: OpenSimModel, rep: CheckReport) -> bool:
    """Bodies, paths and coordinates named by the scene; the coordinates the motion lacks."""
    ok = True
    for x in (*scene.muscles, *scene.bones):
        named = [("body", x.body)] + [("path", p) for p in getattr(x, "paths", ())]
        for kind, name in named:
            try:
                (model.check_body if kind == "body" else model.check_path)(name)
            except SceneError as exc:
                rep.add("error", x.name, str(exc))
                ok = False
    if not ok:
        return False
    bodies = {x.body for x in (*scene.muscles, *scene.bones)}
    bodies |= model.path_bodies([p for m in scene.muscles for p in m.paths])
    moving, _ = model.coordinates_between(sorted(bodies - {"ground"}), scene.output_frame)
    for motion in scene.motions:
        mot = read_motion(motion)
        driven = (
            list(scene.coordinates)
            if scene.coordinates is not None
            else [c for c in mot.columns if c in model.coordinate_names]
        )
        for c in driven:
            if c not in model.coordinate_names:
                rep.add(
                    "error", c, f"[model] coordinates names '{c}', not a coordinate of {model.path.name}",
                    suggest(c, model.coordinate_names),
                )  # fmt: skip
                ok = False
            elif c not in mot.columns:
                rep.add(
                    "error", c,
                    f"{motion.name} has no column '{c}', a coordinate the scene drives",
                    f"use a motion with '{c}', or take it out of [model] coordinates (it is then "
                    "held at the rest pose)",
                )  # fmt: skip
                ok = False
        for c in moving:
            if c not in driven:
                rep.add(
                    "warning", c,
                    f"'{c}' moves the scene's bodies or paths but is not driven "
                    + ("(the motion lacks it)" if c not in mot.columns else "(not in [model] coordinates)")
                    + ": it is held at the rest pose",
                    f"add '{c}' to [model] coordinates" if c in mot.columns else f"use a motion with '{c}'",
                )  # fmt: skip
        if not driven:
            rep.add(
                "error",
                "scene",
                f"{motion.name}: no column of it is a coordinate of {model.path.name}",
            )
            ok = False
            continue
        try:
            flipped = reversed_coordinates(scene, mot, model, driven)
        except SceneError:
            flipped = []  # angles in the wrong unit: the run says so, with its fix
        for c in flipped:
            lo, hi = np.degrees(model.coordinate_range(c))
            v = mot.columns[c]
            rep.add(
                "warning", c,
                f"{motion.name} gives '{c}' outside {model.path.name}'s range [{lo:.4g}, {hi:.4g}] "
                f"deg on most frames, and its negation within it on nearly every frame: the motion "
                f"turns it the other way from the model (written for another model? gait2392's "
                f"knee flexes negative, Rajagopal 2016's positive)",
                f"negate the column '{c}' in {motion.name} (its values now "
                f"{float(v.min()):.4g} .. {float(v.max()):.4g})",
            )  # fmt: skip
    return ok


# ---------------------------------------------------------------------------- lines
def _check_lines(
    scene: Scene,
    model: OpenSimModel,
    drive: Drive,
    body_m: dict[str, tuple[FloatArray, IntArray]],
    rep: CheckReport,
    cache: Path | None = None,
) -> None:

    far = []
    refused: set[str] = set()
    for m in scene.muscles:
        # the names: a neighbour's path can run through a muscle (the vasti's through
        # each other), so only the names tell such a swap
        named = match_muscle(m.mesh.name.rsplit(".", 1)[0]) or match_muscle(m.name)
        of = {a[0].name for a in map(path_anatomy, m.paths) if a is not None}
        if named is not None and of and named.name not in of:
            rep.add(
                "warning", m.name,
                f"its mesh {m.mesh.name} is named like the {named.name.replace('_', ' ')}, its "
                f"paths ({', '.join(m.paths)}) are the {', '.join(sorted(of)).replace('_', ' ')}'s",
                "check its paths (musclewrap init matches them by name)",
            )  # fmt: skip
        V, F = body_m[m.name]
        fit = line_fit(V, F, dict(drive.rest_lines[m.name]), cache=cache)
        rep.fits[m.name] = fit
        thick = float(mean_thickness(V, F))
        rep.thickness[m.name] = thick
        ratio = fit.length / fit.extent
        if ratio < 0.02 or ratio > 50:
            unit = min(UNITS, key=lambda u: abs(np.log(ratio * UNITS[scene.mesh_unit] / UNITS[u])))
            rep.add(
                "error", m.name,
                f"its lines measure {fit.length:.3g} {scene.mesh_unit} and the muscle {fit.extent:.3g} {scene.mesh_unit}: "
                "the units are mixed up",
                f"set [units] mesh = '{unit}' (now '{scene.mesh_unit}')" if unit != scene.mesh_unit
                else "check [units] model",
            )  # fmt: skip
            continue
        problem = rest_lines_problem(scene, m, V, drive.rest_lines[m.name])
        if problem is not None:  # what the run refuses, in its words
            rep.add("error", m.name, problem)
            refused.add(m.name)
        if fit.near > defaults.check_far_thicknesses * thick or m.name in refused:
            far.append(m.name)
        elif ratio < 0.5:
            rep.add(
                "warning", m.name,
                f"its lines measure {fit.length:.3g} {scene.mesh_unit}, half the muscle's length "
                f"({fit.extent:.3g}) or less: the rest of it follows no line",
            )  # fmt: skip
    if not far:
        return
    # every muscle off its lines: the meshes are misplaced, not the paths misnamed (one
    # muscle alone cannot tell: its message names the paths nearest it)
    if len(far) == len(scene.muscles) > 1:
        gaps = ", ".join(f"{n} {rep.fits[n].near:.3g}" for n in far)
        rep.add(
            "error", "scene",
            f"no muscle lies along its lines at rest (a quarter of each line within {gaps} "
            f"{scene.mesh_unit} of its muscle at best): the meshes are not where the model is",
            "if the meshes come from another subject or scanner, place them with a "
            "[registration] (musclewrap init writes one); else check [units], [model] "
            "mesh_frame and rest_pose",
        )  # fmt: skip
        return
    for n in far:
        if n in refused:
            continue
        spec = next(m for m in scene.muscles if m.name == n)
        fit = rep.fits[n]
        better = _nearest_paths(model, spec, body_m[n], scene) if model is not None else []
        fix = (
            "the model's paths that run nearest it: "
            + ", ".join(f"{p} ({g:.3g} {scene.mesh_unit})" for p, g in better)
            + "; set its paths, or its mesh"
            if better
            else "check its paths and its mesh"
        )
        rep.add(
            "error", n,
            f"its lines ({', '.join(spec.paths)}) do not run along it at rest: their nearest "
            f"quarter lies {fit.near:.3g} {scene.mesh_unit} outside it (its mean thickness is "
            f"{rep.thickness[n]:.3g}); the farthest point {fit.far:.3g}",
            fix,
        )  # fmt: skip


def _nearest_paths(
    model: OpenSimModel, spec: MuscleSpec, mesh: tuple[FloatArray, IntArray], scene: Scene
) -> list[tuple[str, float]]:
    """The three model paths whose nearest quarter comes closest to the muscle at rest."""
    names = list(model.path_names)
    model.set_pose(rest_pose(scene, model))
    fits = line_fits(*mesh, [{p: model.path_points(p, spec.body) * scene.scale} for p in names])
    order = np.argsort([f.near for f in fits])[:3]
    return [(names[i], fits[i].near) for i in order]


def _body(scene: Scene, name: str) -> str:
    return next(x.body for x in (*scene.muscles, *scene.bones) if x.name == name)


# ---------------------------------------------------------------------------- bodies
def _check_bone_bodies(
    scene: Scene,
    model: OpenSimModel,
    body_b: dict[str, tuple[FloatArray, IntArray]],
    rep: CheckReport,
    cache: Path | None = None,
) -> None:
    """Each bone against the attachments of the model's paths: whose lie on it."""
    model.set_pose(rest_pose(scene, model))
    s = scene.scale
    owner: list[str] = []
    pts = []
    for p in model.path_names:
        owner += model.path_point_bodies(p)
        pts.append(model.path_points(p, "ground"))
    if not owner:
        return
    G = np.vstack(pts)
    owner_a = np.array(owner)
    for spec in scene.bones:
        if spec.name not in body_b or spec.body == "ground":
            continue
        Ti = np.linalg.inv(model.transform(spec.body, "ground"))
        P = apply_transform(Ti, G) * s  # into the bone's body, mesh units
        V, F = body_b[spec.name]
        # only the points within reach of the bone's box can lie on it (its trees cost more
        # than all the points' queries)
        reach = defaults.check_attached_m * s
        box = np.flatnonzero(((P >= V.min(0) - reach) & (P <= V.max(0) + reach)).all(axis=1))
        on = owner_a[:0]
        if len(box):
            on = owner_a[box[outside_distance(P[box], V, F, cache=cache) <= reach]]
        count = {b: int((on == b).sum()) for b in set(owner)}
        best = max(count, key=lambda b: count[b])
        mine = count.get(spec.body, 0)
        if best != spec.body and count[best] >= 3 and mine * 3 < count[best]:
            rep.add(
                "error", spec.name,
                f"carried by '{spec.body}', but {count[best]} path points of '{best}' lie on it "
                f"(within {defaults.check_attached_m * s:.3g} {scene.mesh_unit}) and {mine} of '{spec.body}'",
                f"set [bones.{spec.name}] body = '{best}'",
            )  # fmt: skip


# ---------------------------------------------------------------------------- overlaps
def _check_overlaps(
    scene: Scene, drive: Drive,
    body_m: dict[str, tuple[FloatArray, IntArray]],
    rest_m: dict[str, tuple[FloatArray, IntArray]],
    rest_b: dict[str, tuple[FloatArray, IntArray]],
    rep: CheckReport,
    cache: Path | None = None,
) -> None:  # fmt: skip
    """Rest overlaps (meshes in the output frame at rest): what the run refuses or resolves."""
    unit = scene.mesh_unit
    found = {}  # (muscle, bone): its vertices inside the bone, the deepest; per bone one query
    for b in scene.bones:
        near = [m for m in scene.muscles if m.bones is None or b.name in m.bones]
        if not near:
            continue
        got = inside_depths([rest_m[m.name][0] for m in near], *rest_b[b.name], cache=cache)
        found.update({(m.name, b.name): g for m, g in zip(near, got, strict=True)})
    for m in scene.muscles:
        V = rest_m[m.name][0]
        for b in scene.bones:
            if (m.name, b.name) not in found:
                continue
            n, depth = found[m.name, b.name]
            if n > 0.5 * len(V):
                rep.add(
                    "error", m.name,
                    f"{n} of its {len(V)} vertices lie inside the bone '{b.name}' at rest "
                    f"({depth:.3g} {unit} deep)",
                    "the muscle and the bone must be the same subject's, in the same frame and "
                    "units: check both bodies and [units]",
                )  # fmt: skip
            elif n:
                rep.add(
                    "note", m.name,
                    f"{n} vertices inside the bone '{b.name}' at rest, up to {depth:.3g} {unit}: "
                    "the run pushes them out once, volume kept, unless that folds the "
                    "surface (then it keeps them and says so)"
                    + (" (rest_overlap = 'keep': kept)" if scene.rest_overlap == "keep" else ""),
                )  # fmt: skip
    if not scene.muscle_collisions:
        return
    try:  # what the run refuses: the same mesh twice, a muscle inside another
        check_muscles_apart(scene, drive, body_m)
    except SceneError as exc:
        rep.add("error", "scene", str(exc))
        return
    for name, (n, depth, other) in muscle_overlaps(rest_m, cache=cache).items():
        if n:
            rep.add(
                "note", name,
                f"{n} vertices inside '{other}' at rest, up to {depth:.3g} {unit}: the run "
                "takes them apart once, volumes kept",
            )  # fmt: skip


def _picture_data(
    scene: Scene, model: OpenSimModel, drive: Drive, body_m: dict, to_out: dict, rep: CheckReport
) -> dict[str, Any]:  # noqa: ANN401
    """The action lines in the output frame at rest, with their distances; the view."""
    lines = []
    for m in scene.muscles:
        for L in drive.rest_lines[m.name].values():
            P = resample_polyline(L, rep.fits[m.name].extent / 100)
            lines.append((apply_transform(to_out[m.body], P), outside_distance(P, *body_m[m.name])))
    if model is not None:
        # OpenSim's ground: x forward, y up; in the output frame
        R = to_out["ground"][:3, :3]
        view = np.array([R @ [1.0, 0, 0], R @ [0, 1.0, 0]])
    else:
        # no model, no convention: from the muscles' thinnest extent, their longest one up
        P = np.vstack([apply_transform(to_out[m.body], body_m[m.name][0]) for m in scene.muscles])
        ext = np.ptp(P, axis=0)
        view = np.eye(3)[[int(np.argmin(ext)), int(np.argmax(ext))]]
    return {
        "view": view,
        "lines": lines,
        "unit": scene.mesh_unit,
        "title": f"{scene.name}: rest pose",
    }
