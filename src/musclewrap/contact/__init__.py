"""Obstacles: bones as rigid closed surfaces, with signed distance and closest points."""

from ._obstacle import Obstacle, bone_surface, pseudo_normals, signed_from_closest

__all__ = ["Obstacle", "bone_surface", "pseudo_normals", "signed_from_closest"]
