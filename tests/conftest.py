"""Shared pytest fixtures."""

import pytest

from fe.scenarios import build_scenario


@pytest.fixture(scope="session")
def coarse_diagonal():
    """The diagonal compression test on a coarse mesh (2 × 1 Q8 per unit): fast, same physics."""
    return build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})


@pytest.fixture(scope="session")
def default_diagonal():
    """The diagonal compression test with its default (converged) mesh."""
    return build_scenario("diagonal_compression")
