"""
The embedded demo
=================

``musclewrap demo -o demo_out`` needs no data: a synthetic fusiform muscle beside a knee-like
joint, 61 frames of 0 to 90 degrees of flexion. Here it runs on fewer frames, from Python, and
its series is read back.
"""

import csv
import os
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import pyvista as pv

from musclewrap.cli import main

frames = min(61, int(os.environ.get("MUSCLEWRAP_DOCS_FRAMES", "61")))
out = Path(tempfile.mkdtemp()) / "demo_out"
main(["demo", "-o", str(out), "--frames", str(frames), "--no-gif"])

# %%
# The last frame, with the bones
# ------------------------------
last = frames - 1
p = pv.Plotter(window_size=(500, 600))
p.add_mesh(pv.read(out / "muscle" / f"muscle_{last:04d}.vtp"), color="indianred")
for bone in ("thigh", "shank"):
    p.add_mesh(pv.read(out / bone / f"{bone}_{last:04d}.vtp"), color="ivory")
p.add_mesh(pv.read(out / "muscle" / f"muscle_lines_{last:04d}.vtp"), color="black", line_width=4)
p.view_xz()
p.show()

# %%
# The volume error per frame, from report.csv
# --------------------------------------------
rows = list(csv.DictReader(open(out / "report.csv")))
fig, ax = plt.subplots(figsize=(6, 3))
ax.plot([float(r["flexion_deg"]) for r in rows], [float(r["relative_volume_error"]) for r in rows], "o-")
ax.set_xlabel("flexion (deg)")
ax.set_ylabel("relative volume error")
ax.ticklabel_format(axis="y", style="sci", scilimits=(0, 0))
fig.tight_layout()
plt.show()
