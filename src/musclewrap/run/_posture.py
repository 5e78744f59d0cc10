"""A registered scene's rest pose against the model's bones: the posture its meshes were taken in.

`rest_posture` prices the scene's registered meshes against the model's bones that do not
move with them (those of bodies other than the landmarks'), over the rest pose's values
of the coordinates between (`musclewrap.model.fit_posture`); `posture_finding` says what
it found, for ``musclewrap check``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._cache import cached_measure
from .._typing import FloatArray, IntArray
from ..mesh import apply_transform
from ..model import OpenSimModel, PostureFit, fit_posture, line_fits
from ..scene import Registration, Scene, rest_pose

__all__ = ["RestPosture", "posture_finding", "rest_posture"]


@dataclass(frozen=True)
class RestPosture:
    """`rest_posture`'s answer.

    The fit; the mean share of the paths of the ``crossing`` muscles (those with a point on
    a priced bone's body) inside them, at the scene's rest pose and at the fitted one.
    """

    fit: PostureFit
    inside: tuple[float, float]
    crossing: int


#: a coordinate's rest value changed by this (radians or metres) to see what it moves
_NUDGE = 1e-3


def rest_posture(
    scene: Scene,
    model: OpenSimModel,
    meshes: Mapping[str, tuple[FloatArray, IntArray]],
    bones: Mapping[str, tuple[FloatArray, IntArray]],
    cache: Path | None = None,
    options: Mapping[str, float] | None = None,
) -> RestPosture | None:
    """The rest pose's change that takes the registered ``meshes`` clearest of the model's bones.

    ``meshes``: the scene's registered muscles in the registration's frame; ``bones``:
    its bones in their bodies' frames (mesh units). Only bones from the model
    (``[bones.NAME] model``) of bodies other than the landmarks' are priced, and only
    the scene's rotational coordinates that move one of those bodies against the
    landmarks' without moving the landmarks' bodies against each other are searched.
    ``cache``: a folder where the same search, made before, is read back; ``options``:
    `musclewrap.model.fit_posture`'s keywords (its defaults otherwise). None where
    the scene has no registration, no such bone or no such coordinate.
    """
    reg_spec = scene.registration
    if reg_spec is None or not meshes:
        return None
    marks = {lm.body for lm in reg_spec.landmarks}
    priced = [
        b for b in scene.bones if b.source and b.frame != "registration" and b.body not in marks
    ]
    priced = [b for b in priced if b.name in bones]
    if not priced:
        return None
    rest = rest_pose(scene, model)
    first = reg_spec.landmarks[0].body
    bodies = sorted(marks | {b.body for b in priced})

    def relative(pose: Mapping[str, float]) -> dict[str, FloatArray]:
        model.set_pose(pose)
        return {b: model.transform(b, first) for b in bodies}

    base = relative(rest)
    coords = []
    for c in scene.coordinates or ():
        if c not in rest or not model.is_rotational(c):
            continue
        moved = relative({**rest, c: rest[c] + _NUDGE})
        # a tenth of the nudge: a model whose constraints OpenSim assembles at each pose
        # moves its bodies by 1e-5 whatever coordinate is nudged (Rajagopal 2016's knees
        # did, before `OpenSimModel.set_pose` set their couplers exactly)
        apart = any(not np.allclose(moved[b], base[b], atol=0.1 * _NUDGE) for b in marks)
        moves = any(not np.allclose(moved[b.body], base[b.body], atol=0.1 * _NUDGE) for b in priced)
        if moves and not apart:
            coords.append(c)
    if not coords:
        model.set_pose(rest)
        return None
    reg = Registration(scene)
    s = scene.scale

    def bodies_at(dq: FloatArray) -> dict[str, FloatArray]:
        """Each body's frame to ground (mesh units), the rest pose changed by ``dq``."""
        model.set_pose({**rest, **{c: rest[c] + float(d) for c, d in zip(coords, dq, strict=True)}})
        g = {}
        for b in bodies:
            T = model.transform(b, "ground")
            T[:3, 3] *= s
            g[b] = T
        return g

    def place(dq: FloatArray) -> list[FloatArray]:
        g = bodies_at(dq)
        to_ground = reg.at(g, s)
        return [np.linalg.inv(g[b.body]) @ to_ground for b in priced]

    mesh_names = list(meshes)
    options = dict(options or {})
    keys: list[np.ndarray | str] = [",".join(coords), ",".join(b.name for b in priced)]
    keys.append(repr(sorted(options.items())))
    for n in mesh_names:
        keys += [meshes[n][0], meshes[n][1]]
    for b in priced:
        keys += [bones[b.name][0], bones[b.name][1]]
    # where the search's corners put the bones: the model and the registration, keyed
    span = np.radians(12.5)
    keys.append(
        np.array([place((np.array(c) - 1.0) * span) for c in np.ndindex(*(3,) * len(coords))])
    )

    # the muscles whose paths have a point on a priced bone's body: their paths' share
    # inside them, a measure the fit does not use (the model's own word on the posture)
    on = {b.body for b in priced}
    model.set_pose(rest)
    crossing = [
        m
        for m in scene.muscles
        if m.name in meshes and any(set(model.path_point_bodies(p)) & on for p in m.paths)
    ]

    def inside(changes: list[FloatArray]) -> list[float]:
        """The mean share of those muscles' paths inside them, the rest pose changed by each."""
        if not crossing:
            return [float("nan")] * len(changes)
        lines: dict[str, list[dict[str, FloatArray]]] = {m.name: [] for m in crossing}
        for dq in changes:
            back = np.linalg.inv(reg.at(bodies_at(dq), s))  # the model posed there
            for m in crossing:
                pts = {
                    p: apply_transform(back, model.path_points(p, "ground") * s) for p in m.paths
                }
                lines[m.name].append(pts)
        # one distance query per muscle, every pose's lines in it
        shares = [[f.inside for f in line_fits(*meshes[n], many)] for n, many in lines.items()]
        return [float(x) for x in np.mean(shares, axis=0)]

    def build() -> dict[str, np.ndarray]:
        fit = fit_posture(meshes, [bones[b.name] for b in priced], place, coords, **options)
        return {
            "inside": np.array(inside([np.zeros(len(coords)), fit.change])),
            "change": fit.change,
            "price": np.array(fit.price),
            "before": np.array([fit.before.get(n, (0, 0.0)) for n in mesh_names]),
            "after": np.array([fit.after.get(n, (0, 0.0)) for n in mesh_names]),
            "settled": np.array(fit.settled),
        }

    try:
        got = cached_measure(cache, "posture-9", keys, build)
    finally:
        model.set_pose(rest)
    before = {n: (int(a), float(d)) for n, (a, d) in zip(mesh_names, got["before"], strict=True)}
    after = {n: (int(a), float(d)) for n, (a, d) in zip(mesh_names, got["after"], strict=True)}
    touched = [n for n in mesh_names if before[n][0] or after[n][0]]
    fit = PostureFit(
        coordinates=tuple(coords),
        change=np.asarray(got["change"], dtype=np.float64),
        price=(float(got["price"][0]), float(got["price"][1])),
        before={n: before[n] for n in touched},
        after={n: after[n] for n in touched},
        settled=bool(got["settled"]),
        bones=tuple(b.name for b in priced),
    )
    return RestPosture(fit, (float(got["inside"][0]), float(got["inside"][1])), len(crossing))


def posture_finding(scene: Scene, found: RestPosture) -> tuple[str, str]:
    """What ``musclewrap check`` says of a `rest_posture`: its message and what to do."""
    fit = found.fit
    deg = {c: float(np.degrees(d)) for c, d in zip(fit.coordinates, fit.change, strict=True)}
    now = {c: scene.rest_pose.get(c, 0.0) for c in fit.coordinates}
    bones = ", ".join(fit.bones)
    n0 = sum(v[0] for v in fit.before.values())
    n1 = sum(v[0] for v in fit.after.values())
    values = ", ".join(f"{c} = {now[c] + deg[c]:.4g}" for c in fit.coordinates)
    a, b = (100 * x for x in found.inside)
    paths = f"the paths of the {found.crossing} muscles that reach those bodies run"
    if not np.any(fit.change):
        each = "; ".join(f"{m} {n} ({d:.1f} {scene.mesh_unit})" for m, (n, d) in fit.before.items())
        return (
            f"registration: the model's bones ({bones}) lie clearest of the registered meshes "
            f"at the scene's rest pose ({values} deg; searched within 10 deg): "
            f"{n0} muscle vertices in them"
            + (f" ({each})" if each else "")
            + f"; {paths} {a:.0f} % inside them",
            "",
        )
    turned = ", ".join(f"{now[c]:.4g}" for c in fit.coordinates)
    each = "; ".join(
        f"{m} {fit.before[m][0]} ({fit.before[m][1]:.1f} {scene.mesh_unit}) -> "
        f"{fit.after[m][0]} ({fit.after[m][1]:.1f})"
        for m in fit.before
    )
    if not fit.settled:
        return (
            f"registration: the model's bones ({bones}) lie clearer of the registered meshes "
            f"the further the rest pose turns, to the search's edge ({values} deg; the "
            f"scene's: {turned}; muscle vertices in them {n0} -> {n1}: {each}; {paths} "
            f"{a:.0f} -> {b:.0f} % inside them): they do not "
            "settle the posture the meshes were taken in (a muscle that lies deep in a "
            "generic bone at any posture pulls the fit with it)",
            "keep the rest pose unless another measure agrees (the lines' fit below: how "
            "much of each path runs inside its muscle)",
        )
    return (
        f"registration: the model's bones ({bones}) lie clearer of the registered meshes "
        f"with the rest pose's {values} deg (the scene's: {turned}): muscle vertices in "
        f"them {n0} -> {n1} ({each}); {paths} {a:.0f} -> {b:.0f} % inside them (a measure "
        "the fit does not use). The meshes' subject may have lain so when they were "
        "taken: the landmarks place one body, not the joints beyond it",
        "set [model] rest_pose to those values (with the other coordinates' as they are), "
        "then check again",
    )
