"""Outputs: ParaView series, CSV reports, plots and pictures."""

from ._render import Rendering, render_series, start_rendering
from ._series import (
    plot_convergence,
    plot_moment_arms,
    plot_penetration,
    plot_volume_error,
    write_csv,
    write_pvd,
)

__all__ = [
    "Rendering",
    "plot_convergence",
    "plot_moment_arms",
    "plot_penetration",
    "plot_volume_error",
    "render_series",
    "start_rendering",
    "write_csv",
    "write_pvd",
]
