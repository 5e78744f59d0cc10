"""Mesh input/output, checks and volume."""

from ._checks import (
    MeshCheck,
    MeshError,
    available_memory,
    check_memory,
    check_mesh,
    merge_duplicate_vertices,
    orient_faces,
    self_intersecting_faces,
    split_nonmanifold_vertices,
    tidy_mesh,
    vertex_origins,
)
from ._clean import clean_mesh
from ._cubic import cubic_root_near
from ._geometry import (
    apply_transform,
    barycentric,
    face_areas,
    half_edges,
    in_box,
    invert_rigid,
    mean_edge_length,
    umbrella_laplacian,
    vertex_adjacency,
    vertex_normals,
)
from ._io import FORMATS, atomic_path, read_mesh, write_mesh
from ._repair import repair_mesh
from ._volume import (
    combine_pair,
    mean_rows,
    mean_thickness,
    volume,
    volume_cubic,
    volume_cubic_pair,
    volume_gradient,
    volume_hessian_reduced,
)
from ._winding import WindingGrid, bin_boxes, winding_numbers

__all__ = [
    "apply_transform",
    "invert_rigid",
    "FORMATS",
    "MeshCheck",
    "MeshError",
    "WindingGrid",
    "atomic_path",
    "barycentric",
    "bin_boxes",
    "available_memory",
    "check_memory",
    "combine_pair",
    "cubic_root_near",
    "face_areas",
    "half_edges",
    "in_box",
    "mean_edge_length",
    "mean_rows",
    "mean_thickness",
    "umbrella_laplacian",
    "vertex_adjacency",
    "vertex_normals",
    "vertex_origins",
    "check_mesh",
    "clean_mesh",
    "merge_duplicate_vertices",
    "orient_faces",
    "read_mesh",
    "repair_mesh",
    "self_intersecting_faces",
    "split_nonmanifold_vertices",
    "tidy_mesh",
    "volume",
    "volume_cubic",
    "volume_cubic_pair",
    "volume_gradient",
    "volume_hessian_reduced",
    "winding_numbers",
    "write_mesh",
]
