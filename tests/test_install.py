"""femcrowd installed from a wheel (``pip install .``, not editable) into a new virtual environment: the
studies find the shipped cases and meshes (femcrowd/shipped) from any directory."""

import subprocess
import sys

import pytest

from .support import ROOT


@pytest.mark.slow
def test_the_studies_run_from_an_installed_wheel(tmp_path):
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    pip = subprocess.run([str(venv / "bin" / "pip"), "install", "-q", str(ROOT)], capture_output=True, text=True)
    assert pip.returncode == 0, pip.stderr[-2000:]
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    femcrowd = str(venv / "bin" / "femcrowd")
    studies = (["stress", "--only", "closed-saturated", "--out", "stress"], ["rimea", "--only", "1", "--out", "r"])
    for command in studies:
        done = subprocess.run([femcrowd, *command], cwd=elsewhere, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
        assert "1/1 scenes pass" in done.stdout or "30.1 s: **pass**" in done.stdout
    installed = subprocess.run([str(venv / "bin" / "python"), "-c", "import femcrowd, sys; print(femcrowd.__file__)"],
                               cwd=elsewhere, capture_output=True, text=True).stdout
    assert str(venv) in installed   # the wheel's copy, not the checkout
