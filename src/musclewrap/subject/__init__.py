"""A user's own subject: from an OpenSim model and a folder of meshes to a scene."""

from ..model import MUSCLES, Anatomy, match_bone, match_muscle, path_anatomy, split_path_name
from ._init import InitResult, init_scene, survey

__all__ = [
    "MUSCLES",
    "Anatomy",
    "InitResult",
    "init_scene",
    "match_bone",
    "match_muscle",
    "path_anatomy",
    "split_path_name",
    "survey",
]
