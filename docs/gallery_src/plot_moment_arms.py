"""
Fibres and their moment arms
============================

``examples/lhdl_hip_sweeps.toml`` puts 100 fibres in each muscle and computes their moment arms
about the hip's three coordinates; here the flexion sweep alone, on every few frames. Each
fibre's moment arm is ``-dL/dq`` from the muscle deformed on either side of the frame's pose;
the action line's own moment arm is the same difference on the path's length, and OpenSim's
``computeMomentArm`` is drawn beside it.
"""

import csv
import dataclasses
import math
import os
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

from musclewrap.scene import load_scene, read_motion, run_scene

ROOT = next(p for p in [Path.cwd(), *Path.cwd().parents] if (p / "examples").is_dir())
scene = load_scene(ROOT / "examples" / "lhdl_hip_sweeps.toml")
flexion = next(m for m in scene.motions if m.stem == "hip_flexion")
scene = dataclasses.replace(scene, motions=(flexion,), gif=False)
n = read_motion(flexion).n_frames
step = math.ceil(n / int(os.environ.get("MUSCLEWRAP_DOCS_FRAMES", str(n))))
out = Path(tempfile.mkdtemp()) / "sweeps"
run_scene(scene, out, frames=f"0:{n}:{step}", workers=1, progress=None, render=False)

# %%
# Moment arm against the flexion angle
# ------------------------------------
# The fibres' range (shaded) and mean, the action line and OpenSim, per muscle, from
# moment_arms.csv.
rows = [r for r in csv.DictReader(open(out / "moment_arms.csv"))
        if r["coordinate"] == "hip_flexion_r"]  # fmt: skip
muscles = list(dict.fromkeys(r["muscle"] for r in rows))
fig, axes = plt.subplots(1, len(muscles), figsize=(3 * len(muscles), 3), sharey=True)
for ax, m in zip(axes, muscles):
    q = [r for r in rows if r["muscle"] == m]
    x = [float(r["coordinate_value"]) for r in q]
    col = {k: [float(r[k]) for r in q] for k in ("fibre_min", "fibre_mean", "fibre_max",
                                                 "line_moment_arm", "opensim_moment_arm")}  # fmt: skip
    ax.fill_between(x, col["fibre_min"], col["fibre_max"], alpha=0.3, label="fibres")
    ax.plot(x, col["fibre_mean"], label="fibres' mean")
    ax.plot(x, col["line_moment_arm"], "k-", label="action line")
    ax.plot(x, col["opensim_moment_arm"], "k:", lw=3, label="OpenSim")
    ax.set_title(m.replace("_", " "), fontsize=9)
    ax.set_xlabel("hip flexion (deg)")
axes[0].set_ylabel("moment arm (mm)")
axes[0].legend(fontsize=7)
fig.tight_layout()
plt.show()

# %%
# Every fibre of one muscle
# -------------------------
# fibres.csv holds each fibre's length and moment arm per frame and coordinate.
fib = [r for r in csv.DictReader(open(out / "fibres.csv"))
       if r["muscle"] == "gluteus_maximus" and r["coordinate"] == "hip_flexion_r"]  # fmt: skip
curves: dict[str, list[tuple[float, float]]] = {}
for r in fib:
    curves.setdefault(r["fibre"], []).append((float(r["coordinate_value"]), float(r["moment_arm"])))
fig, ax = plt.subplots(figsize=(6, 3))
for c in curves.values():
    ax.plot(*zip(*sorted(c)), lw=0.5, color="indianred")
ax.set_xlabel("hip flexion (deg)")
ax.set_ylabel("moment arm (mm)")
ax.set_title("gluteus maximus: 100 fibres", fontsize=9)
fig.tight_layout()
plt.show()
