"""Shared fixtures: the repository's paths, small meshes, the projection, history files (support.py)."""

import pytest

from femcrowd.mesh import load_domain

from .support import CASES, MESHES, ROOT, Projector, read_history, unit_square


@pytest.fixture(scope="session")
def repo():
    """The repository root."""
    return ROOT


@pytest.fixture(scope="session")
def cases():
    return CASES


@pytest.fixture(scope="session")
def meshes():
    return MESHES


@pytest.fixture
def square_domain():
    """unit_square(n, exits): a structured mesh of [0, 1]^2 with named sides."""
    return unit_square


@pytest.fixture(scope="session")
def room_domain():
    """The 10 x 6 m room of cases/room, its door the exit."""
    return load_domain(MESHES / "room_one_door.msh", ["exit"])


@pytest.fixture
def projector():
    """Projector(domain, **options): the correction step as (rho, phi, info)."""
    return Projector


@pytest.fixture
def history():
    """read_history(path): history.csv as {column: array}."""
    return read_history
