import os
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


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
