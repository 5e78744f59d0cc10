"""
The method step by step
=======================

A synthetic fusiform muscle, its cage and its action line; the muscle deformed to a bent line
with its volume kept exactly; and a rod pressed into it, the muscle kept out of it. These are the
pictures of the guide's page on the method.
"""

# %%
# A muscle and its cage
# ---------------------
# `musclewrap.Muscle.from_mesh` builds the cage (about 300 vertices here 200), the mean value
# coordinates of every fine vertex in it, the Laplacian and the proxy, once per muscle.
import numpy as np
import pyvista as pv

import musclewrap as mw
from musclewrap.synthetic import capsule

V, F = capsule(radius=20.0, length=200.0, n_around=32, cap_rings=8, segments=30)
muscle = mw.Muscle.from_mesh(V, F, cage_size=200)
rest = {"axis": np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 200.0]])}
deformer = muscle.bind(rest)


def surface(P, faces):
    return pv.PolyData(P, np.hstack([np.full((len(faces), 1), 3), faces]).ravel())


p = pv.Plotter(window_size=(500, 600))
p.add_mesh(surface(muscle.V, muscle.F), color="indianred", opacity=0.5)
p.add_mesh(surface(muscle.cage.C, muscle.cage.CF), style="wireframe", color="black")
p.add_points(deformer.rest_samples, color="navy", point_size=8, render_points_as_spheres=True)
p.view_xz()
p.show()

# %%
# Follow a bent action line, volume exact
# ---------------------------------------
# The second half of the line turns by 30 degrees and the line shortens by 15 %; the solve is
# a few fixed-point updates on the proxy and one exact cubic root for the fine volume.
h = 85.0
a = np.radians(30.0)
bent = {"axis": np.array([[0.0, 0.0, 0.0], [0.0, 0.0, h], [h * np.sin(a), 0, h + h * np.cos(a)]])}
result = deformer.deform(bent)
print(f"{result.iterations} iterations, relative volume error {result.relative_volume_error:.1e}")

mesh = surface(result.V, muscle.F)
mesh["displacement (mm)"] = np.linalg.norm(result.V - muscle.V, axis=1)
p = pv.Plotter(window_size=(500, 600))
p.add_mesh(mesh, scalars="displacement (mm)", cmap="viridis")
p.add_lines(bent["axis"][[0, 1, 1, 2]], color="black", width=4)
p.view_xz()
p.show()

# %%
# Keep out of a bone
# ------------------
# A rod (an obstacle, in the muscle's frame) is pushed 8 mm into the muscle's side: the
# vertices inside it are taken out by steps of the cage and a fine push-out, and the volume is
# restored exactly.
from musclewrap.contact import Obstacle  # noqa: E402

rV, rF = capsule(radius=6.0, length=120.0, n_around=24, cap_rings=6, segments=12)
rV = rV - [0.0, 0.0, 60.0]
rV = rV[:, [0, 2, 1]] + [-(20.0 - 8.0 + 6.0), 0.0, 100.0]  # along y, 8 mm into the belly
rF = rF[:, ::-1].copy()  # the swap of two axes turned the faces inside out
rod = Obstacle(rV, rF)
pushed = deformer.deform(rest, obstacles=[rod])
print(
    f"deepest vertex in the rod {pushed.penetration_depth:.3f} mm "
    f"(before: {pushed.penetration_depth_before:.1f} mm), volume error "
    f"{pushed.relative_volume_error:.1e}"
)
p = pv.Plotter(window_size=(500, 600))
p.add_mesh(surface(pushed.V, muscle.F), color="indianred")
p.add_mesh(surface(rV, rF), color="ivory")
p.view_vector((-1.0, -0.8, 0.25), viewup=(0.0, 0.0, 1.0))
p.camera.zoom(1.3)
p.show()

# %%
# Fibres, carried by the cage
# ---------------------------
# A harmonic field between the two ends of the muscle (Choi & Blemker 2013) gives fibres from
# one end to the other; each fibre point has its coordinates in the cage, so the bent pose
# carries them as it carries the surface. Coloured by their stretch (length over rest length).
from musclewrap.fibres import fibres_at_rest  # noqa: E402

fibres = fibres_at_rest(muscle, rest, count=40, points=15, voxels=20_000)
now = fibres.at(result.cage)
stretch = fibres.lengths(now) / fibres.lengths()
print(f"{len(now)} fibres, stretch {stretch.min():.3f} to {stretch.max():.3f}")
p = pv.Plotter(window_size=(500, 600))
p.add_mesh(surface(result.V, muscle.F), color="indianred", opacity=0.15)
for i, pts in enumerate(now):
    line = pv.lines_from_points(pts)
    line["stretch"] = np.full(line.n_cells, stretch[i])
    p.add_mesh(line, scalars="stretch", cmap="coolwarm", clim=(0.8, 1.2), line_width=3,
               show_scalar_bar=i == 0)  # fmt: skip
p.view_xz()
p.show()
