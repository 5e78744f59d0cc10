"""
One muscle from the Python API
==============================

A real muscle (the Visible Human Female semitendinosus, from ``../shared/data``): read, checked,
prepared once, bound to a rest action line and deformed to another. Every figure the result
claims is on it.
"""

from pathlib import Path

import numpy as np
import pyvista as pv

import musclewrap as mw
from musclewrap.synthetic import principal_axis_scenario

ROOT = next(p for p in [Path.cwd(), *Path.cwd().parents] if (p / "examples").is_dir())
DATA = ROOT.parent / "shared" / "data"

V, F = mw.read_mesh(DATA / "vhf" / "VHF_Right_Muscle_Semitendonosus_smooth.stl")
muscle = mw.Muscle.from_mesh(V, F)
print(f"{len(muscle.V)} vertices, cage of {len(muscle.cage.C)}, "
      f"prepared in {muscle.seconds_prepare:.2f} s")  # fmt: skip

# %%
# Bind and deform
# ---------------
# The rest line joins the muscle's ends along its principal axis; the current one bends its
# second half by 30 degrees and shortens it by 15 %.
rest, current = principal_axis_scenario(muscle.V, "bend_short")
deformer = muscle.bind(rest)
r = deformer.deform(current)
print(f"converged {r.converged} in {r.iterations} iterations, {1000 * r.seconds:.1f} ms; "
      f"relative volume error {r.relative_volume_error:.1e}; "
      f"skeleton fit {r.skeleton_fit_mean:.2f} mm; "
      f"shape change {muscle.shape_change(r.V).max():.2f} mean edges")  # fmt: skip


# %%
# Rest and deformed, side by side
# -------------------------------
def surface(P):
    return pv.PolyData(P, np.hstack([np.full((len(muscle.F), 1), 3), muscle.F]).ravel())


p = pv.Plotter(shape=(1, 2), window_size=(800, 700))
p.add_mesh(surface(muscle.V), color="ivory")
p.add_lines(np.repeat(rest["axis"], 2, axis=0)[1:-1], color="black", width=4)
p.subplot(0, 1)
moved = surface(r.V)
moved["displacement (mm)"] = np.linalg.norm(r.V - muscle.V, axis=1)
p.add_mesh(moved, scalars="displacement (mm)", cmap="viridis")
p.add_lines(np.repeat(current["axis"], 2, axis=0)[1:-1], color="black", width=4)
p.link_views()
# look across the plane of the bend: the muscle's third principal axis
axes = np.linalg.svd(muscle.V - muscle.V.mean(axis=0), full_matrices=False)[2]
p.view_vector(axes[2], viewup=axes[0])
p.show()
