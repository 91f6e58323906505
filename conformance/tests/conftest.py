import os
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
CONFORMANCE = os.path.dirname(HERE)
REPO = os.path.dirname(CONFORMANCE)
sys.path.insert(0, CONFORMANCE)
PAINTER = os.path.join(REPO, "painter", "target", "release", "octopaint")


@pytest.fixture(scope="session")
def painter():
    """The painter binary; `make test` builds it before running these tests."""
    if not os.path.exists(PAINTER):
        raise FileNotFoundError(f"{PAINTER} is not built: run `make painter` (make test does)")
    return PAINTER
