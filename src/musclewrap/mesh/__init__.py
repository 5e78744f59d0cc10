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
    "FORMATS",
    "MeshCheck",
    "MeshError",
    "WindingGrid",
    "apply_transform",
    "atomic_path",
    "available_memory",
    "barycentric",
    "bin_boxes",
    "check_memory",
    "check_mesh",
    "clean_mesh",
    "combine_pair",
    "cubic_root_near",
    "face_areas",
    "half_edges",
    "in_box",
    "invert_rigid",
    "mean_edge_length",
    "mean_rows",
    "mean_thickness",
    "merge_duplicate_vertices",
    "orient_faces",
    "read_mesh",
    "repair_mesh",
    "self_intersecting_faces",
    "split_nonmanifold_vertices",
    "tidy_mesh",
    "umbrella_laplacian",
    "vertex_adjacency",
    "vertex_normals",
    "vertex_origins",
    "volume",
    "volume_cubic",
    "volume_cubic_pair",
    "volume_gradient",
    "volume_hessian_reduced",
    "winding_numbers",
    "write_mesh",
]
