import numpy as np
import pytest

from musclewrap.cage import build_cage, cage_self_intersections
from musclewrap.synthetic import capsule


def test_cage_encloses_and_is_clean(small_muscle):
    c = small_muscle.cage
    assert c.min_winding > 0.99 and c.min_distance > 0
    assert cage_self_intersections(c.C, c.CF) == 0
    # uniform remesh: well-shaped triangles spread along the whole capsule, not slivers
    # joining the two caps (what quadric decimation gives on a cylinder)
    assert c.method == "uniform" and c.min_angle_deg > 15.0
    z = c.C[:, 2]
    assert np.sum((z > 40) & (z < 160)) > 0.3 * len(z)


def test_cage_too_small_rejected():
    V, F = capsule(n_around=12, cap_rings=4, segments=5)
    with pytest.raises(ValueError, match="at least 20"):
        build_cage(V, F, size=5)


def test_verify_cage_reports_unenclosed_vertices(small_muscle):
    from musclewrap.cage import verify_cage

    c = small_muscle.cage
    assert verify_cage(small_muscle.V, c.C, c.CF, margin=0.0) == []
    shrunk = c.C.mean(axis=0) + 0.5 * (c.C - c.C.mean(axis=0))
    problems = verify_cage(small_muscle.V, shrunk, c.CF, margin=0.0)
    assert any("outside the cage" in p for p in problems)


def test_quadric_coarsening_builds_valid_cage():
    V, F = capsule(n_around=32, cap_rings=8, segments=30)
    c = build_cage(V, F, size=200, coarsening="quadric")
    assert c.method == "quadric" and c.min_winding > 0.99
    with pytest.raises(ValueError, match="coarsening"):
        build_cage(V, F, coarsening="other")
