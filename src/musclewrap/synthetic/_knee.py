"""The embedded demo: two muscles side by side wrapping over a knee's condyles in flexion.

Everything is made here, in millimetres, in the scene's frame: x forward (anterior), y
along the knee's axis, z up. The femur (fixed) ends in a condyle-like roll about the y
axis; the tibia turns about that axis (flexion moves it backwards). Two fusiform muscles
lie side by side in front of the femur, their bellies over the condyles, from the femur's
shaft to the tibia's front: in flexion their action lines wrap round the condyles (the
shortest way round a cylinder, as OpenSim's wrap cylinders do), the muscles are pressed
onto the bone and against each other, and stretch. `write_knee_scene` writes it as an
ordinary scene (meshes, a line CSV, the tibia's poses in a bodies CSV and the TOML file)
that ``musclewrap run`` runs with contact on.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._typing import FloatArray, IntArray, PathLike

__all__ = ["KneeDemo", "knee_demo", "write_knee_scene"]

#: radius of the condyles' roll about the knee's axis (mm)
CONDYLE_RADIUS = 24.0
#: how far over the condyles the action lines wrap (mm): at 3 mm a muscle 9.5 mm deep about
#: its line is pressed into the bone in flexion, and the contact keeps it out
#: (`benchmarks/speed/bench_demo.py` measures other margins)
WRAP_MARGIN = 3.0
#: where the muscles' lines run at rest (x, z; mm): from the femur's shaft (origin) to a
#: point above the condyles (fixed on the femur), one below them and the tibia's front
#: (insertion; both on the tibia); at rest the middle part clears the wrap cylinder
REST_LINE = np.array([[24.0, 165.0], [34.0, 60.0], [34.0, -40.0], [24.0, -110.0]])


def _capsule_sdf(P: FloatArray, a: FloatArray, b: FloatArray, r: float) -> FloatArray:
    ab = b - a
    t = np.clip(((P - a) @ ab) / (ab @ ab), 0.0, 1.0)
    return np.linalg.norm(P - (a + t[:, None] * ab), axis=1) - r


def _smooth_min(d1: FloatArray, d2: FloatArray, k: float) -> FloatArray:
    h = np.clip(0.5 + 0.5 * (d2 - d1) / k, 0.0, 1.0)
    return d2 * (1 - h) + d1 * h - k * h * (1 - h)


def _surface(sdf, lo: FloatArray, hi: FloatArray, step: float) -> tuple[FloatArray, IntArray]:  # noqa: ANN001
    """The zero level of a signed distance, a closed triangle mesh (VTK's flying edges)."""
    import pyvista as pv

    n = np.ceil((hi - lo) / step).astype(int) + 1
    grid = pv.ImageData(dimensions=tuple(n), spacing=(step,) * 3, origin=tuple(lo))
    grid.point_data["d"] = sdf(np.asarray(grid.points))
    surf = grid.contour([0.0], scalars="d", method="flying_edges").triangulate().clean()
    V = np.asarray(surf.points, dtype=np.float64)
    F = np.asarray(surf.faces, dtype=np.int64).reshape(-1, 4)[:, 1:]
    # outward: the distance grows along the normals
    from ..mesh import volume

    if volume(V, F) < 0:
        F = F[:, ::-1].copy()
    return V, F


def femur() -> tuple[FloatArray, IntArray]:
    """A femur's distal end: a shaft into a roll of condyles about the y axis (mm)."""

    def sdf(P: FloatArray) -> FloatArray:
        shaft = _capsule_sdf(P, np.array([-2.0, 0.0, 20.0]), np.array([5.0, 0.0, 175.0]), 15.0)
        roll = _capsule_sdf(P, np.array([0.0, -30.0, 0.0]), np.array([0.0, 30.0, 0.0]), 24.0)
        return _smooth_min(shaft, roll, 10.0)

    return _surface(sdf, np.array([-40.0, -60.0, -30.0]), np.array([40.0, 60.0, 195.0]), 2.0)


def tibia() -> tuple[FloatArray, IntArray]:
    """A tibia's proximal end at zero flexion: a plateau under the condyles, a shaft (mm)."""

    def sdf(P: FloatArray) -> FloatArray:
        plateau = _capsule_sdf(P, np.array([1.0, -26.0, -44.0]), np.array([1.0, 26.0, -44.0]), 15.0)
        shaft = _capsule_sdf(P, np.array([0.0, 0.0, -50.0]), np.array([-2.0, 0.0, -190.0]), 13.0)
        return _smooth_min(plateau, shaft, 10.0)

    return _surface(sdf, np.array([-35.0, -50.0, -215.0]), np.array([35.0, 50.0, -20.0]), 2.0)


def muscle(
    y: float, half_width: float, half_depth: float, *, rings: int = 90, around: int = 40
) -> tuple[FloatArray, IntArray]:
    """A fusiform muscle in front of the bones, its cross-sections ellipses (mm).

    Its centre follows `REST_LINE` (smoothed) at ``y`` from side to side; ``half_depth``
    (front to back) and ``half_width`` (side to side) at the belly, over the condyles.
    """
    from ._capsule import rings_mesh

    s = np.linspace(0.0, 1.0, rings)
    z = REST_LINE[0, 1] + (REST_LINE[-1, 1] - REST_LINE[0, 1]) * s
    shape = np.sin(np.pi * s) ** 1.2
    a = 1.5 + (half_depth - 1.5) * shape  # front to back
    b = 1.5 + (half_width - 1.5) * shape  # side to side
    x = np.interp(-z, -REST_LINE[:, 1], REST_LINE[:, 0])
    x = np.convolve(np.pad(x, 4, mode="edge"), np.ones(9) / 9, mode="valid")
    V, F = rings_mesh(z, np.ones_like(z), around, x=x)
    # rings_mesh makes circles of radius 1 round (x, 0, z): stretch them into ellipses
    ring = np.repeat(np.arange(1, rings - 1), around)
    V[1:-1, 0] = x[ring] + (V[1:-1, 0] - x[ring]) * a[ring]
    V[1:-1, 1] = V[1:-1, 1] * b[ring]
    V[:, 1] += y
    return V, F[:, ::-1].copy()  # the rings run downwards: turn the faces outwards


def _turn(angle_deg: float) -> FloatArray:
    """Flexion: the tibia turns about the y axis, its far end going backwards."""
    t = np.radians(angle_deg)
    return np.array([[np.cos(t), 0.0, np.sin(t)], [0.0, 1.0, 0.0], [-np.sin(t), 0.0, np.cos(t)]])


def wrapped_line(
    angle_deg: float, y: float, n: int = 40, margin: float = WRAP_MARGIN
) -> FloatArray:
    """A muscle's action line at a flexion angle: `REST_LINE`, wrapped where it must be.

    Its first two points move with the femur, its last two with the tibia; between
    them the line takes the shortest way in front of the cylinder of radius
    `CONDYLE_RADIUS` + ``margin`` about the knee's axis (as OpenSim's wrap cylinders): straight where
    it clears the cylinder, along it where not. ``n`` points, evenly spaced, at ``y``.
    """
    R = _turn(angle_deg)[[0, 2]][:, [0, 2]]  # the turn in the (x, z) plane
    o, v1 = REST_LINE[0], REST_LINE[1]
    v2, i = R @ REST_LINE[2], R @ REST_LINE[3]
    r = CONDYLE_RADIUS + margin

    def tangent(p: FloatArray, sign: float) -> float:
        # the angle (from +x towards +z) of p's tangent point on the circle, on one side
        return float(np.arctan2(p[1], p[0]) + sign * np.arccos(r / np.hypot(*p)))

    # down the front: from v1's tangent point through decreasing angles to v2's
    a1, a2 = tangent(v1, -1.0), tangent(v2, +1.0)
    turn = (a1 - a2 + np.pi) % (2 * np.pi) - np.pi
    if turn <= 0.0:  # the straight way clears the cylinder
        middle = np.zeros((0, 2))
    else:
        arc = np.linspace(a1, a1 - turn, 48)
        middle = np.stack([r * np.cos(arc), r * np.sin(arc)], 1)
    pts = np.vstack([o, v1, middle, v2, i])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    t = np.linspace(0.0, s[-1], n)
    return np.stack([np.interp(t, s, pts[:, 0]), np.full(n, y), np.interp(t, s, pts[:, 1])], axis=1)


@dataclass(frozen=True)
class KneeDemo:
    """The demo's parts at rest and its motion (mm, degrees)."""

    muscles: dict[str, tuple[FloatArray, IntArray]]
    femur: tuple[FloatArray, IntArray]
    tibia: tuple[FloatArray, IntArray]
    #: each muscle's place from side to side (its line's y)
    sides: dict[str, float]
    angles: FloatArray
    #: the wrap cylinder's margin over the condyles (mm)
    margin: float = WRAP_MARGIN

    def lines(self, k: int) -> dict[str, FloatArray]:
        """Each muscle's action line at frame ``k``."""
        a = float(self.angles[k])
        return {m: wrapped_line(a, y, margin=self.margin) for m, y in self.sides.items()}

    def tibia_pose(self, k: int) -> FloatArray:
        """The tibia's pose (4 x 4) at frame ``k``: its frame is the scene's at rest."""
        T = np.eye(4)
        T[:3, :3] = _turn(float(self.angles[k]))
        return T


def knee_demo(
    n_frames: int = 61, max_flexion: float = 90.0, margin: float = WRAP_MARGIN
) -> KneeDemo:
    """Build the demo: its meshes, the flexion per frame, the lines' wrap margin (mm)."""
    sides = {"medial": -14.3, "lateral": 13.5}
    return KneeDemo(
        muscles={
            "medial": muscle(sides["medial"], 14.0, 9.5),
            "lateral": muscle(sides["lateral"], 13.0, 9.5),
        },
        femur=femur(),
        tibia=tibia(),
        sides=sides,
        angles=np.linspace(0.0, max_flexion, n_frames),
        margin=margin,
    )


def write_knee_scene(
    folder: PathLike, n_frames: int = 61, max_flexion: float = 90.0, margin: float = WRAP_MARGIN
) -> Path:
    """Write the demo as a scene in ``folder`` and return its TOML file."""
    from ..mesh import write_mesh

    demo = knee_demo(n_frames, max_flexion, margin)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for name, (V, F) in demo.muscles.items():
        write_mesh(folder / f"{name}.vtp", V, F)
    write_mesh(folder / "femur.vtp", *demo.femur)
    write_mesh(folder / "tibia.vtp", *demo.tibia)
    rows = ["frame,time,muscle,line,point,x,y,z"]
    bodies = ["frame,time,body,r11,r12,r13,r21,r22,r23,r31,r32,r33,x,y,z"]
    for k, angle in enumerate(demo.angles):
        t = 2.0 * k / max(len(demo.angles) - 1, 1)  # two seconds
        for m, P in demo.lines(k).items():
            rows += [
                f"{k},{t:.6g},{m},main,{j},{p[0]:.9g},{p[1]:.9g},{p[2]:.9g}"
                for j, p in enumerate(P)
            ]
        T = demo.tibia_pose(k)
        values = [*T[:3, :3].ravel(), *T[:3, 3]]
        bodies.append(f"{k},{t:.6g},tibia," + ",".join(f"{v:.12g}" for v in values))
    (folder / "lines.csv").write_text("\n".join(rows) + "\n")
    (folder / "bodies.csv").write_text("\n".join(bodies) + "\n")
    toml = folder / "knee.toml"
    toml.write_text(_SCENE.replace("MAX", f"{max_flexion:g}"))
    return toml


_SCENE = """\
# musclewrap's demo: two muscles side by side over a knee's condyles, 0 to MAX deg of
# flexion. Made by musclewrap.synthetic.write_knee_scene; run it again with
#     musclewrap run knee.toml -o out
name = "Demo: two muscles over a knee"

[units]
mesh = "mm"

[lines]
csv = "lines.csv"        # each muscle's action line per frame (round the condyles)
bodies = "bodies.csv"    # the tibia's pose per frame (the femur does not move)

[bones.femur]
mesh = "femur.vtp"

[bones.tibia]
mesh = "tibia.vtp"
body = "tibia"           # its frame is the scene's at rest

[muscles.medial]
mesh = "medial.vtp"
reference = "femur"      # fixes the twist about the line

[muscles.lateral]
mesh = "lateral.vtp"
reference = "femur"

[output]
colour = "stretch"       # the muscles coloured by how much their surface stretches
view = [-35, 12]         # turned from the side towards the front, to see both muscles
"""
