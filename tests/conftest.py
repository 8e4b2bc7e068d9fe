"""Shared fixtures (the helpers that are not fixtures are in support.py)."""

import tempfile

import pytest
from hypothesis.configuration import set_hypothesis_home_dir

from femcrowd.mesh import load_domain

from .support import MESHES


@pytest.hookimpl(trylast=True)
def pytest_configure(config):
    """Hypothesis keeps its caches (constants of the source read when the tests are collected) under pytest's
    temporary directory, not in ./.hypothesis, and so do the scratch directories femcrowd takes from tempfile
    (the meshes of femcrowd.api scenes, the estimate's trial run, dask's scratch): tests write nowhere else."""
    set_hypothesis_home_dir(config._tmp_path_factory.mktemp("hypothesis"))
    tempfile.tempdir = str(config._tmp_path_factory.mktemp("tempfile"))


@pytest.fixture(scope="session")
def room_domain():
    """The 10 x 6 m room of cases/room, its door the exit (loaded once per session)."""
    return load_domain(MESHES / "room_one_door.msh", ["exit"])
