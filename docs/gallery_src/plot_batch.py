"""
A batch of scenes
=================

Several scenes run as one plan over one executor: here the LHDL walk and the LHDL running trial,
which share their meshes, so each muscle is prepared once for both. From the command line:
``musclewrap run examples/lhdl_walk.toml examples/lhdl_run.toml -o study_out``; on a Dask
cluster, add ``--scheduler tcp://HOST:8786`` (or pass ``executor=distributed.Client(...)``).
"""

import os
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

from musclewrap.scene import load_scene, run_batch

ROOT = next(p for p in [Path.cwd(), *Path.cwd().parents] if (p / "examples").is_dir())
n = int(os.environ.get("MUSCLEWRAP_DOCS_FRAMES", "211"))
scenes = [load_scene(ROOT / "examples" / f"{s}.toml") for s in ("lhdl_walk", "lhdl_run")]
out = Path(tempfile.mkdtemp()) / "study_out"
summaries = run_batch(
    scenes,
    [out / "walk", out / "run"],
    frames=f"0:{n}",
    workers=1,
    progress=None,
    render=False,
)
for sc, s in zip(scenes, summaries):
    rows = s.rows
    print(
        f"{sc.name}: {len(rows)} muscle-frames, unconverged "
        f"{sum(not r['converged'] for r in rows)}, worst volume error "
        f"{max(abs(r['relative_volume_error']) for r in rows):.1e}"
    )

# %%
# Shape change per frame, both scenes
# -----------------------------------
fig, axes = plt.subplots(1, 2, figsize=(8, 3), sharey=True)
for ax, sc, s in zip(axes, scenes, summaries):
    for m in sc.muscles:
        q = [r for r in s.rows if r["muscle"] == m.name]
        ax.plot([r["frame"] for r in q], [r["shape_change_max"] for r in q], label=m.name)
    ax.set_title(sc.name, fontsize=9)
    ax.set_xlabel("frame")
axes[0].set_ylabel("shape change (mean edges)")
axes[0].legend(fontsize=7)
fig.tight_layout()
plt.show()
