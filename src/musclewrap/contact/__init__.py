"""Obstacles: bones as rigid closed surfaces, with signed distance and closest points."""

from ._obstacle import Obstacle

__all__ = ["Obstacle"]
