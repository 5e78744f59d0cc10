"""The names of the files a run writes at the top of its output folder.

Besides one folder per muscle and bone: the ParaView series, the report, the pictures
and plots, the fibres' tables and the journal that lets an interrupted run go on.
Everything that writes, reads or guards them imports the names from here.
"""

from __future__ import annotations

from pathlib import Path

__all__ = [
    "FIBRES_CSV",
    "GIF",
    "JOURNAL",
    "MOMENT_ARMS_CSV",
    "PLOT_CONVERGENCE",
    "PLOT_MOMENT_ARMS",
    "PLOT_PENETRATION",
    "PLOT_VOLUME",
    "PVD",
    "REPORT",
    "TOP_FILES",
]

PVD, REPORT, GIF = "scene.pvd", "report.csv", "scene.gif"
PLOT_VOLUME, PLOT_CONVERGENCE = "volume_error.png", "convergence.png"
PLOT_PENETRATION = "penetration.png"
FIBRES_CSV, MOMENT_ARMS_CSV, PLOT_MOMENT_ARMS = "fibres.csv", "moment_arms.csv", "moment_arms.png"
#: the journal of an interrupted run (hidden; removed when the run completes)
JOURNAL = ".musclewrap-run"

#: every one of them (render_series also writes the GIF's middle picture beside it, as .png)
TOP_FILES = (
    PVD,
    REPORT,
    GIF,
    Path(GIF).with_suffix(".png").name,
    PLOT_VOLUME,
    PLOT_CONVERGENCE,
    PLOT_PENETRATION,
    FIBRES_CSV,
    MOMENT_ARMS_CSV,
    PLOT_MOMENT_ARMS,
    JOURNAL,
)
