import os

import jax
import pytest
from octopaint_ref.jax_setup import configure

# The package sets nothing on import (jax_setup.py): the suite turns on
# JAX's 64-bit mode, as the package's own entry points do.
configure()


@pytest.fixture(autouse=True)
def strict_dtype_promotion():
    """Every test under JAX's strict dtype promotion: a float32 meeting a
    float64 (or any other implicit promotion between arrays) is an error,
    so no precision is lost or gained behind the study's back. Python
    scalars stay weakly typed."""
    with jax.numpy_dtype_promotion("strict"):
        yield


REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
TRACES = os.path.join(REPO, "traces")


@pytest.fixture
def traces_dir():
    return TRACES
