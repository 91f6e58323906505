import os
import sys

import pytest
from octopaint_ref.jax_setup import configure

HERE = os.path.dirname(os.path.abspath(__file__))
CONFORMANCE = os.path.dirname(HERE)
REPO = os.path.dirname(CONFORMANCE)
sys.path.insert(0, CONFORMANCE)
# The reference sets nothing on import: the tests that run it in this
# process need its float64 (octopaint_ref/jax_setup.py).
configure()
PAINTER = os.path.join(REPO, "painter", "target", "release", "octopaint")


@pytest.fixture(scope="session")
def painter():
    """The painter binary; `make test` builds it before running these tests."""
    if not os.path.exists(PAINTER):
        raise FileNotFoundError(f"{PAINTER} is not built: run `make painter` (make test does)")
    return PAINTER
