"""Outputs: ParaView series, CSV reports, plots."""

from ._series import plot_volume_error, write_csv, write_pvd

__all__ = ["plot_volume_error", "write_csv", "write_pvd"]
