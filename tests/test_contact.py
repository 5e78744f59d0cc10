import numpy as np
import pytest

from musclewrap.contact import Obstacle
from musclewrap.synthetic import capsule


# ------------------------------------------------------------------ obstacles
def test_obstacle_matches_a_sphere():
    V, F = capsule(radius=10.0, length=0.0, n_around=96, cap_rings=48, segments=1)
    probe = Obstacle(V, F)
    rng = np.random.default_rng(1)
    d = rng.normal(size=(400, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    r = rng.uniform(0.0, 20.0, 400)
    centre = V.mean(axis=0)  # the capsule with no cylinder is a sphere about its middle
    Q = centre + d * r[:, None]
    n, depth = probe.measure(Q)
    # the polygonal sphere's inscribed radius is within 0.02 of 10
    inside = r < 10.0 - 0.03
    outside = r > 10.0 + 0.03
    amb = ~(inside | outside)
    assert inside.sum() <= n <= inside.sum() + amb.sum()
    assert depth == pytest.approx(10.0 - r[inside].min(), abs=0.05)
    assert probe.measure(Q[outside]) == (0, 0.0)


def _brute_force(probe, Q):
    """Closest-point query with the pseudo-normal side on every point."""
    d, side = probe._distance(Q)
    inside = side < 0
    return int(inside.sum()), float(d[inside].max()) if inside.any() else 0.0


def test_obstacle_grid_is_exact_and_cached(tmp_path):
    # a long capsule: deep points, points near the surface, and far points
    V, F = capsule(radius=8.0, length=40.0, n_around=40, cap_rings=12, segments=16)
    rng = np.random.default_rng(3)
    lo, hi = V.min(axis=0) - 5, V.max(axis=0) + 5
    Q = lo + rng.random((3000, 3)) * (hi - lo)
    near = V[rng.integers(0, len(V), 1000)] + rng.normal(scale=0.3, size=(1000, 3))
    probe = Obstacle(V, F, max_grid_nodes=20_000)
    for pts in (Q, near, Q[:5], np.vstack([Q, near])):
        assert probe.measure(pts) == _brute_force(probe, pts)
    # the grid goes to the cache and comes back identical; a damaged file is rebuilt
    a = Obstacle.cached(V, F, tmp_path)
    (path,) = tmp_path.glob("bone-probe-*.npz")
    b = Obstacle.cached(V, F, tmp_path)
    assert np.array_equal(a._lo_sd, b._lo_sd) and a.measure(Q) == b.measure(Q)
    path.write_bytes(path.read_bytes()[:-100])
    c = Obstacle.cached(V, F, tmp_path)
    assert c.measure(Q) == _brute_force(c, Q)
