"""
Fibres and their moment arms
============================

``examples/lhdl_hip_sweeps.toml`` puts 100 fibres in each muscle and computes their moment arms
about the hip's three coordinates, each swept on its own: flexion, adduction and rotation,
here on every few frames. Each fibre's moment arm is ``-dL/dq`` from the muscle deformed on
either side of the frame's pose; the action line's own moment arm is the same difference on
the path's length, and OpenSim's ``computeMomentArm`` is drawn beside it.
"""

import csv
import dataclasses
import math
import os
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

from musclewrap.fibres import LHDL_FIBRE_RANGES, published_cover
from musclewrap.scene import load_scene, read_motion, run_scene

ROOT = next(p for p in [Path.cwd(), *Path.cwd().parents] if (p / "examples").is_dir())
scene = load_scene(ROOT / "examples" / "lhdl_hip_sweeps.toml")
SWEPT = {"hip_flexion": "hip_flexion_r", "hip_adduction": "hip_adduction_r",
         "hip_rotation": "hip_rotation_r"}  # fmt: skip
rows: dict[str, list[dict[str, str]]] = {}
base = Path(tempfile.mkdtemp())
for motion in scene.motions:
    n = read_motion(motion).n_frames
    step = math.ceil(n / int(os.environ.get("MUSCLEWRAP_DOCS_FRAMES", str(n))))
    out = base / motion.stem
    sweep = dataclasses.replace(scene, motions=(motion,), gif=False)
    run_scene(sweep, out, frames=f"0:{n}:{step}", workers=1, progress=None, render=False)
    coordinate = SWEPT[motion.stem]
    rows[motion.stem] = [r for r in csv.DictReader(open(out / "moment_arms.csv"))
                         if r["coordinate"] == coordinate]  # fmt: skip

# %%
# Moment arm against the swept angle
# ----------------------------------
# Per sweep and muscle, from moment_arms.csv: the fibres' range (shaded) and mean, the
# action line and OpenSim. At the right of a panel, the same specimen's fibres as
# published (Modenese & Kohout 2020, Table 2: the smallest and largest moment arm across a
# muscle's fibres over the sweep; the eight muscle-tasks issue 48 quotes,
# ``musclewrap.fibres.LHDL_FIBRE_RANGES``), and how much of that range ours covers.
muscles = list(dict.fromkeys(r["muscle"] for r in rows["hip_flexion"]))
fig, axes = plt.subplots(len(rows), len(muscles), figsize=(3 * len(muscles), 2.8 * len(rows)))
for i, (sweep, got) in enumerate(rows.items()):
    for j, m in enumerate(muscles):
        ax = axes[i, j]
        q = [r for r in got if r["muscle"] == m]
        x = [float(r["coordinate_value"]) for r in q]
        col = {k: [float(r[k]) for r in q] for k in ("fibre_min", "fibre_mean", "fibre_max",
                                                     "line_moment_arm", "opensim_moment_arm")}  # fmt: skip
        ax.fill_between(x, col["fibre_min"], col["fibre_max"], alpha=0.3, label="fibres")
        ax.plot(x, col["fibre_mean"], label="fibres' mean")
        ax.plot(x, col["line_moment_arm"], "k-", label="action line")
        ax.plot(x, col["opensim_moment_arm"], "k:", lw=3, label="OpenSim")
        pub = LHDL_FIBRE_RANGES.get((SWEPT[sweep], m))
        if pub is not None:
            at = max(x) + 0.04 * (max(x) - min(x))
            ax.plot([at, at], pub, color="darkorange", lw=4, label="published fibres")
            lo, hi = min(col["fibre_min"]), max(col["fibre_max"])
            cover = published_cover(lo, hi, pub)
            ax.text(0.02, 0.04, f"covers {cover:.0%}", transform=ax.transAxes, fontsize=7)
        ax.set_title(m.replace("_", " "), fontsize=9)
        ax.set_xlabel(sweep.replace("_", " ") + " (deg)", fontsize=8)
    axes[i, 0].set_ylabel("moment arm (mm)")
legend = {}
for ax in axes.flat:
    legend.update(zip(*ax.get_legend_handles_labels()[::-1]))  # label -> handle, once each
fig.legend(legend.values(), legend.keys(), loc="lower center", ncol=len(legend), fontsize=8)
fig.tight_layout(rect=(0, 0.04, 1, 1))
plt.show()

# %%
# Every fibre of one muscle
# -------------------------
# fibres.csv holds each fibre's length and moment arm per frame and coordinate.
fib = [r for r in csv.DictReader(open(base / "hip_flexion" / "fibres.csv"))
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
