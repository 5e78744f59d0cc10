"""Muscles against each other (issue 24): the independent check's muscle-muscle part."""

import numpy as np

from musclewrap.scene._verify import muscle_overlaps
from musclewrap.synthetic import capsule


def _sphere(radius: float, centre) -> tuple[np.ndarray, np.ndarray]:
    V, F = capsule(radius=radius, length=0.0, n_around=64, cap_rings=32, segments=1)
    V = V - [0.0, 0.0, radius] + np.asarray(centre, dtype=float)
    return V, F


def test_overlap_of_two_spheres_is_their_lens():
    # spheres of radius 10, centres 16 apart: each reaches 4 into the other, on the line
    # between the centres; a third far away touches neither
    meshes = {
        "a": _sphere(10.0, [0.0, 0.0, 0.0]),
        "b": _sphere(10.0, [16.0, 0.0, 0.0]),
        "c": _sphere(5.0, [0.0, 40.0, 0.0]),
    }
    out = muscle_overlaps(meshes)
    for me, other in (("a", "b"), ("b", "a")):
        n, depth, name = out[me]
        assert name == other
        # the polygonal spheres lie within 0.03 of their radius (64 around, 64 rings)
        assert 3.9 <= depth <= 4.05
        # the lens's cap: the vertices within 4 of the pole facing the other sphere
        V = meshes[me][0]
        c = V.mean(axis=0)
        toward = (V - c) @ (np.sign(16.0 if me == "a" else -16.0) * np.array([1.0, 0.0, 0.0]))
        assert abs(n - int((toward > 8.0).sum())) <= 0.2 * n
    assert out["c"] == (0, 0.0, "")


def test_overlap_of_a_sphere_inside_another():
    out = muscle_overlaps({"big": _sphere(10.0, [0, 0, 0]), "small": _sphere(3.0, [1, 0, 0])})
    n, depth, name = out["small"]
    assert name == "big" and n == len(_sphere(3.0, [1, 0, 0])[0])
    # the small sphere's deepest vertex: 10 - (3 - 1) = 8 from the big one's surface
    assert 7.9 <= depth <= 8.05
    assert out["big"] == (0, 0.0, "")
