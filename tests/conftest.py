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
    from musclewrap.mesh import mean_rows, volume
    from musclewrap.solver._proxy import mat3

    def convert(d):  # noqa: ANN001, ANN202
        mu, C = d.muscle, d.muscle.cage.C
        d._Wd32 = np.ascontiguousarray(mu.proxy_W)
        d._B32 = d._Hinv @ mu.proxy_W_T
        d._Vd32 = volume(mat3(d._Wd32, C - mean_rows(C)), mu.proxy_F, center=np.zeros(3))
        return d

    return convert
