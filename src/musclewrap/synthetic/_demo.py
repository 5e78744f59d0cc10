"""A single fusiform muscle spanning a knee-like joint beside two rods, driven from Python."""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray
from ._capsule import capsule, rings_mesh

__all__ = ["DemoScene", "demo_scene"]


class DemoScene:
    """Synthetic scene: muscle, two bones, action line per frame.

    Attributes
    ----------
    V, F : arrays
        Muscle rest surface (mm).
    bones : dict of str to (V, F)
        Rest bone surfaces ("thigh" fixed, "shank" rotating about the knee).
    rest_line : dict
        Rest action line ``{"main": (3, 3) array}``.
    angles : (k,) float64 array
        Flexion angle per frame, degrees.
    reference : (3,) float64 array
        Reference point (centroid of the thigh bone, fixed).
    """

    def __init__(self, n_frames: int = 61, max_flexion: float = 90.0) -> None:
        s = np.linspace(0.0, 1.0, 72)
        r = 4.0 + 16.0 * np.sin(np.pi * s) ** 1.5
        z = -40.0 + 290.0 * s
        x = 32.0 + 6.0 * np.sin(np.pi * s)
        self.V, self.F = rings_mesh(z, r, 48, x=x)
        bV, bF = capsule(radius=12.0, length=260.0, n_around=24, cap_rings=6, segments=20)
        self.bones = {
            "thigh": (bV + [0.0, 0.0, 15.0], bF),
            "shank": (bV * [1, 1, -1] - [0.0, 0.0, 15.0], bF[:, ::-1].copy()),
        }
        self.rest_line = {
            "main": np.array([[32.0, 0.0, -40.0], [36.0, 0.0, 20.0], [32.0, 0.0, 250.0]])
        }
        self.angles = np.linspace(0.0, max_flexion, n_frames)
        self.reference = self.bones["thigh"][0].mean(axis=0)

    @staticmethod
    def shank_rotation(angle_deg: float) -> FloatArray:
        """Rotation of the shank about the knee axis (y through the origin)."""
        a = np.radians(angle_deg)
        return np.array(
            [[np.cos(a), 0.0, -np.sin(a)], [0.0, 1.0, 0.0], [np.sin(a), 0.0, np.cos(a)]]
        )

    def line(self, frame: int) -> dict[str, FloatArray]:
        """Current action line: insertion moves with the shank, the rest with the thigh."""
        P = self.rest_line["main"].copy()
        P[0] = self.shank_rotation(self.angles[frame]) @ P[0]
        return {"main": P}

    def bone(self, name: str, frame: int) -> tuple[FloatArray, IntArray]:
        """Bone surface at a frame."""
        V, F = self.bones[name]
        if name == "shank":
            return V @ self.shank_rotation(self.angles[frame]).T, F
        return V, F


def demo_scene(n_frames: int = 61) -> DemoScene:
    """Build the embedded demo scene (61 frames of 0 to 90 degrees of flexion)."""
    return DemoScene(n_frames=n_frames)
