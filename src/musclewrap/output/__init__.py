"""Outputs: ParaView series, CSV reports, plots and pictures."""

from ._render import render_series
from ._series import plot_convergence, plot_penetration, plot_volume_error, write_csv, write_pvd

__all__ = [
    "plot_convergence",
    "plot_penetration",
    "plot_volume_error",
    "render_series",
    "write_csv",
    "write_pvd",
]
