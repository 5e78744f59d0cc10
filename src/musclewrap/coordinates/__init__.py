"""Generalized barycentric coordinates of points in the cage."""

from ._mvc import mean_value_coordinates, rows_dot

__all__ = ["mean_value_coordinates", "rows_dot"]
