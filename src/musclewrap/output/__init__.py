"""Outputs: ParaView series, CSV reports, plots and pictures."""

from ._check_picture import draw_check
from ._render import (
    STRETCH_RANGE,
    Pictures,
    PictureTask,
    RenderingError,
    View,
    close_renderer,
    frame_view,
    label_files,
    muscles_box,
    render_series,
    save_gif,
    stretch_colours,
    stretch_table,
)
from ._series import (
    plot_convergence,
    plot_moment_arms,
    plot_penetration,
    plot_volume_error,
    write_csv,
    write_pvd,
)

__all__ = [
    "STRETCH_RANGE",
    "PictureTask",
    "Pictures",
    "RenderingError",
    "View",
    "close_renderer",
    "draw_check",
    "frame_view",
    "label_files",
    "muscles_box",
    "plot_convergence",
    "plot_moment_arms",
    "plot_penetration",
    "plot_volume_error",
    "render_series",
    "save_gif",
    "stretch_colours",
    "stretch_table",
    "write_csv",
    "write_pvd",
]
