"""Outputs: ParaView series, CSV reports, plots and pictures."""

from ._render import Pictures, PictureTask, RenderingError, render_series, save_gif
from ._series import (
    plot_convergence,
    plot_moment_arms,
    plot_penetration,
    plot_volume_error,
    write_csv,
    write_pvd,
)

__all__ = [
    "PictureTask",
    "Pictures",
    "RenderingError",
    "plot_convergence",
    "plot_moment_arms",
    "plot_penetration",
    "plot_volume_error",
    "render_series",
    "save_gif",
    "write_csv",
    "write_pvd",
]
