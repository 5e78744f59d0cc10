"""Soft conditions of the deformation: shape (Laplacian) and skeleton (action lines)."""

from ._laplacian import cotangent_laplacian
from ._lines import (
    LineError,
    LineSampling,
    PathLines,
    check_lines,
    csv_rows,
    distinct_mask,
    placement_problem,
    polyline_at,
    read_lines_csv,
    sample_lines,
    set_point_params,
    window_mean,
    within_reach,
)
from ._rotation import (
    RotationField,
    SampleRotations,
    kabsch,
    matrix_to_quaternion,
    minimal_rotation,
    path_rotations,
    quaternion_to_matrix,
    sample_rotations,
)

__all__ = [
    "LineError",
    "LineSampling",
    "PathLines",
    "RotationField",
    "SampleRotations",
    "check_lines",
    "cotangent_laplacian",
    "csv_rows",
    "distinct_mask",
    "kabsch",
    "matrix_to_quaternion",
    "minimal_rotation",
    "path_rotations",
    "placement_problem",
    "polyline_at",
    "quaternion_to_matrix",
    "read_lines_csv",
    "sample_lines",
    "sample_rotations",
    "set_point_params",
    "window_mean",
    "within_reach",
]
