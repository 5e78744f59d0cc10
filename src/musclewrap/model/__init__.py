"""The OpenSim side of a scene: the model, its motion, names, registration and the lines' fit.

What a scene takes from a musculoskeletal model: `OpenSimModel` (bodies, coordinates,
paths, posed), `Motion` (coordinate values per frame), the bone meshes it attaches to its
bodies (`model_geometry`), the lower limb's anatomy by name
(`match_muscle`, `match_bone`), the similarity that places meshes of another subject
(`similarity`, `axes_rotation`), a model's long bone fitted to them (`fit_shaft`), the
posture they were taken in (`fit_posture`) and how well a mesh sits on its lines
(`line_fits`).
"""

from ._fit import LineFit, line_fit, line_fits, outside_distance, resample_polyline
from ._geometry import ModelGeometry, body_meshes, geometry_folders, model_geometry
from ._motion import Motion, random_motion, read_motion, write_motion
from ._names import (
    BONES,
    GROUPS,
    LANDMARKS,
    MUSCLES,
    Anatomy,
    MuscleGroup,
    NameMatch,
    match_bone,
    match_group,
    match_muscle,
    mesh_name_tokens,
    path_anatomy,
    split_path_name,
)
from ._opensim import OpenSimModel, import_opensim
from ._posture import PostureFit, fit_posture
from ._register import (
    FEMUR_FITS,
    axes_rotation,
    cap_spread,
    check_landmarks,
    femur_landmarks,
    fit_sphere,
    landmark_point,
    similarity,
    surface_centroid,
)
from ._shaft import ShaftFit, fit_shaft

__all__ = [
    "BONES",
    "FEMUR_FITS",
    "GROUPS",
    "LANDMARKS",
    "MUSCLES",
    "Anatomy",
    "LineFit",
    "ModelGeometry",
    "Motion",
    "MuscleGroup",
    "NameMatch",
    "OpenSimModel",
    "PostureFit",
    "ShaftFit",
    "axes_rotation",
    "body_meshes",
    "cap_spread",
    "check_landmarks",
    "femur_landmarks",
    "fit_posture",
    "fit_shaft",
    "fit_sphere",
    "geometry_folders",
    "import_opensim",
    "landmark_point",
    "line_fit",
    "line_fits",
    "match_bone",
    "match_group",
    "match_muscle",
    "mesh_name_tokens",
    "model_geometry",
    "outside_distance",
    "path_anatomy",
    "random_motion",
    "read_motion",
    "resample_polyline",
    "similarity",
    "split_path_name",
    "surface_centroid",
    "write_motion",
]
