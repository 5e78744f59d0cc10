import os
from pathlib import Path

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
