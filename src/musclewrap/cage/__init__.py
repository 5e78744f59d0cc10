"""The coarse envelope (cage) of a muscle mesh."""

from ._build import Cage, CageError, build_cage, cage_self_intersections, verify_cage

__all__ = ["Cage", "CageError", "build_cage", "cage_self_intersections", "verify_cage"]
