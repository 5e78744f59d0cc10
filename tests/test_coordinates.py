import numpy as np
import pytest

from musclewrap.coordinates import mean_value_coordinates


def cube():
    V = np.array([[x, y, z] for x in (0.0, 1) for y in (0.0, 1) for z in (0.0, 1)])
    F = np.array(
        [
            [0, 1, 3],
            [0, 3, 2],
            [4, 6, 7],
            [4, 7, 5],
            [0, 4, 5],
            [0, 5, 1],
            [2, 3, 7],
            [2, 7, 6],
            [0, 2, 6],
            [0, 6, 4],
            [1, 5, 7],
            [1, 7, 3],
        ]
    )
    return V, F


def test_mvc_octahedron_centre_is_uniform():
    # symmetric cage and triangulation: every vertex weighs the same at the centre
    V = np.array([[1.0, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
    F = np.array(
        [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    )
    W = mean_value_coordinates([[0.0, 0.0, 0.0]], V, F)
    assert np.allclose(W, 1 / 6, atol=1e-14)


def test_mvc_identities_random_points():
    V, F = cube()
    P = np.random.default_rng(0).uniform(0.05, 0.95, size=(500, 3))
    W = mean_value_coordinates(P, V, F)
    assert np.allclose(W.sum(axis=1), 1.0, atol=1e-13)
    assert np.abs(W @ V - P).max() < 1e-10
    assert (W > 0).all(), "MVC are positive inside a convex cage"


def test_mvc_special_cases():
    V, F = cube()
    P = np.array([V[3], V[F[2]].mean(axis=0), [0.5, 0.5, 0.0]])
    W = mean_value_coordinates(P, V, F)
    assert W[0, 3] == 1.0 and W[0].sum() == 1.0
    assert np.abs(W @ V - P).max() < 1e-12


def test_mvc_validates_input():
    V, F = cube()
    with pytest.raises(ValueError, match="shape"):
        mean_value_coordinates(np.zeros((3, 2)), V, F)
    with pytest.raises(ValueError, match="indices"):
        mean_value_coordinates(np.zeros((1, 3)), V, F + 10)


@pytest.mark.parametrize("k", [1, 3, 6, 7, 13])
def test_rows_dot_is_w_at_x(k):
    from musclewrap.coordinates import rows_dot

    rng = np.random.default_rng(k)
    W, X = rng.random((257, 300)), rng.normal(size=(300, k))
    assert np.allclose(rows_dot(W, X), W @ X, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="X must be \\(300, k\\)"):
        rows_dot(W, X[:299])
