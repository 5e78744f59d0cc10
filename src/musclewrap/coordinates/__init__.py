"""Generalized barycentric coordinates of points in the cage."""

from ._mvc import mean_value_coordinates

__all__ = ["mean_value_coordinates"]
