"""The case layer sits above the models: it reads and checks case files with the standard library, numpy and
the neutral modules (femcrowd.expressions, femcrowd.registry), and asks the models for their choices only when
a case is checked."""

import subprocess
import sys

from ..support import CASES

MODELS = ("femcrowd.macro", "femcrowd.micro", "femcrowd.mesh", "femcrowd.driver", "scipy", "skfem", "pymetis")


def imported_by(code: str) -> set:
    """The modules of MODELS that a fresh interpreter has imported after running code."""
    probe = f"{code}\nimport sys\nprint(' '.join(m for m in {MODELS!r} if m in sys.modules))"
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    return set(done.stdout.split())


def test_importing_the_case_layer_imports_no_model():
    assert imported_by("import femcrowd.case") == set()
    assert imported_by("from femcrowd.case import load_case, SCHEMA, Expression") == set()


def test_the_models_are_asked_for_their_choices_when_a_case_is_checked():
    """cases/bottleneck names a speed law: checking it asks the macro model, nothing more."""
    loaded = imported_by(f"from femcrowd.case import load_case\nload_case({str(CASES / 'bottleneck')!r})")
    assert "femcrowd.macro" in loaded and "femcrowd.driver" not in loaded
