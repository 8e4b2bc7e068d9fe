"""Shared fixtures (the helpers that are not fixtures are in support.py)."""

import pytest

from femcrowd.mesh import load_domain

from .support import MESHES


@pytest.fixture(scope="session")
def room_domain():
    """The 10 x 6 m room of cases/room, its door the exit (loaded once per session)."""
    return load_domain(MESHES / "room_one_door.msh", ["exit"])
