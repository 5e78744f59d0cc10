"""
The embedded demo
=================

``musclewrap demo -o demo_out`` needs no data: two synthetic muscles side by side over a knee's
condyles, 61 frames of 0 to 90 degrees of flexion. Their action lines wrap round a cylinder 3 mm
over the condyles, as an OpenSim wrap cylinder would, so the solve alone would drive each
muscle's back about 5 mm into the bone: the contact keeps both out of the bones and out of each
other, the volume exact. The demo writes its scene (``demo_out/input/knee.toml``: meshes, a line
CSV, the tibia's poses in a bodies CSV) and runs it as any scene. Here it runs on fewer frames,
from Python, and its series is read back.
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
main(["demo", "-o", str(out), "--frames", str(frames), "--no-gif", "--workers", "1"])

# %%
# The last frame (90 deg), coloured by the surface's stretch
# ----------------------------------------------------------
# Every muscle file carries ``area_stretch``: the area round each vertex over its rest area.
# Both muscles lengthen as the knee flexes (red); where they are pressed onto the condyles
# their surface is compressed (blue).
last = frames - 1
p = pv.Plotter(window_size=(600, 600))
for m in ("medial", "lateral"):
    p.add_mesh(
        pv.read(out / m / f"{m}_{last:04d}.vtp"),
        scalars="area_stretch",
        cmap="coolwarm",
        clim=(1 / 1.35, 1.35),
        log_scale=True,
        scalar_bar_args={"title": "area stretch"},
    )
    p.add_mesh(pv.read(out / m / f"{m}_lines_{last:04d}.vtp"), color="black", line_width=3)
# a bone that moves has a file per frame; one that does not, one file
p.add_mesh(pv.read(out / "femur" / "femur.vtp"), color="ivory")
p.add_mesh(pv.read(out / "tibia" / f"tibia_{last:04d}.vtp"), color="ivory")
p.view_xz()
p.camera.azimuth = -35
p.show()

# %%
# Contact and volume per frame, from report.csv
# ---------------------------------------------
rows = list(csv.DictReader(open(out / "report.csv")))
fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3))
for m in ("medial", "lateral"):
    r = [x for x in rows if x["muscle"] == m]
    t = [float(x["time"]) * 45 for x in r]  # 2 s from 0 to 90 deg
    a.plot(t, [float(x["penetration_depth_before"]) for x in r], "--", label=f"{m}, solve alone")
    a.plot(t, [float(x["penetration_depth_max"]) for x in r], "o-", ms=3, label=f"{m}, contact")
    b.plot(t, [float(x["relative_volume_error"]) for x in r], "o-", ms=3, label=m)
a.set_xlabel("flexion (deg)")
a.set_ylabel("deepest vertex in a bone (mm)")
a.legend(fontsize=7)
b.set_xlabel("flexion (deg)")
b.set_ylabel("relative volume error")
b.ticklabel_format(axis="y", style="sci", scilimits=(0, 0))
fig.tight_layout()
plt.show()
