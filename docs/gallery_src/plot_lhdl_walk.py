"""
A scene on the real data: the LHDL hip through a walk
=====================================================

``examples/lhdl_walk.toml``: the LHDL right hip model (gluteus maximus and medius, iliacus,
psoas; femur, iliac bone and sacrum) driven by OpenSim through the gait2392 walking trial, with
the muscles kept out of the bones and out of each other. The same as
``musclewrap run examples/lhdl_walk.toml -o lhdl_walk_out``, here on the first frames.
"""

import os
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pyvista as pv

from musclewrap.scene import load_scene, run_scene

ROOT = next(p for p in [Path.cwd(), *Path.cwd().parents] if (p / "examples").is_dir())
n = int(os.environ.get("MUSCLEWRAP_DOCS_FRAMES", "211"))
scene = load_scene(ROOT / "examples" / "lhdl_walk.toml")
out = Path(tempfile.mkdtemp()) / "lhdl_walk_out"
summary = run_scene(scene, out, frames=f"0:{n}", workers=1, progress=None, render=False)
for note in summary.notes[:6]:
    print("note:", note)

# %%
# The report, per frame and muscle
# --------------------------------
# Every frame converged, the volume exact, nothing inside a bone or another muscle.
rows = summary.rows
print(f"{len(rows)} muscle-frames, unconverged {sum(not r['converged'] for r in rows)}")
for key in ("relative_volume_error", "penetration_depth_max", "muscle_overlap_max",
            "shape_change_max"):  # fmt: skip
    print(f"  {key:24s} <= {max(abs(r[key]) for r in rows):.3g}")

# %%
# The last frame, in the pelvis frame
# -----------------------------------
last = n - 1
colours = {"gluteus_maximus": "indianred", "gluteus_medius": "salmon", "iliacus": "orange",
           "psoas": "gold"}  # fmt: skip
p = pv.Plotter(window_size=(700, 700))
for m in scene.muscles:
    p.add_mesh(pv.read(out / m.name / f"{m.name}_{last:04d}.vtp"), color=colours[m.name])
for b in scene.bones:
    files = sorted((out / b.name).glob("*.vtp"))
    moving = [f for f in files if f.stem.endswith(f"_{last:04d}")]
    p.add_mesh(pv.read(moving[0] if moving else files[0]), color="ivory")
# along the scene's thinnest extent, its longest one up (as the run's own pictures)
b = np.array(p.bounds).reshape(3, 2)
extent = np.diff(b, axis=1).ravel()
p.view_vector(np.eye(3)[np.argmin(extent)], viewup=np.eye(3)[np.argmax(extent)])
p.show()

# %%
# The volume error the run plots, per frame
# -----------------------------------------
fig, ax = plt.subplots(figsize=(6, 3))
for m in scene.muscles:
    q = [r for r in rows if r["muscle"] == m.name]
    ax.plot([r["frame"] for r in q], [r["relative_volume_error"] for r in q], ".", label=m.name)
ax.set_xlabel("frame")
ax.set_ylabel("relative volume error")
ax.legend(fontsize=7)
fig.tight_layout()
plt.show()
