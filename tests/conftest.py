import os
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.fixture(scope="session")
def chromium() -> str:
    """Chromium from the OS packages, for Playwright (``.ci/run`` installs both); required in
    CI, skipped elsewhere when missing."""
    import shutil

    found = shutil.which("chromium") or shutil.which("chromium-browser")
    missing = "chromium not found: .ci/run installs it from the OS packages"
    try:
        import playwright  # noqa: F401
    except ImportError:
        found, missing = None, "playwright missing: the [dev] extra installs it"
    if found is None:
        if os.environ.get("CI"):
            pytest.fail(missing)
        pytest.skip(missing)
    return found


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """The third-party real data; required (not skipped) in CI."""
    if not DATA.is_dir():
        if os.environ.get("CI"):
            pytest.fail(f"real data missing at {DATA}: CI must run the real-data tests")
        pytest.skip(f"real data not found at {DATA}")
    return DATA


@pytest.fixture
def double_proxy():
    """Give a Deformer double-precision copies of the proxy matrices its default solve steers by.

    The same iteration in double precision: the reference for the float32 products.
    """
    return lambda d: d._proxy_matrices(np.float64)


@pytest.fixture(scope="session")
def small_muscle():
    """A capsule muscle prepared once (200 cage vertices): shared, never modified."""
    from musclewrap.solver import Muscle
    from musclewrap.synthetic import capsule

    V, F = capsule(n_around=32, cap_rings=8, segments=30)
    return Muscle.from_mesh(V, F, cage_size=200)
