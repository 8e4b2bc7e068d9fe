"""The settings a study runs a case with: the case's own, or the recommended ones of the density model
(studies/recommended.py, docs/validation.md), with the recommended step or the fast one, applied to that case's
doors."""

from ..case import load_case
from ..case.loading import toml_value
from ..case.template import door_groups
from ..mesh.domain import load_domain
from .recommended import FAST, FREE_SPEED, MACRO, door_capacity

#: the named settings of the density model: the recommended ones with the recommended step or the fast one
NAMED = {"recommended": MACRO, "fast": FAST}


def recommended(case_dir, overrides=(), macro=MACRO) -> tuple:
    """The --set texts of the recommended settings on a case: `macro` (MACRO, or FAST), the law's free speed
    FREE_SPEED, no push (the law moves a saturated crowd: f(rho_max) = 0.303) and the capacity of its width on
    every exit and every interior door (the interior line groups of its mesh, as ``femcrowd new`` writes them)."""
    case = load_case(case_dir, overrides)
    domain = load_domain(case.path(case["mesh"]["file"]), case["boundary"]["exits"], 0, case.file)
    inside = door_groups(domain)[2]
    settings = {**macro, "velocity.speed": FREE_SPEED, "velocity.push": 0.0,
                **door_capacity([*case["boundary"]["exits"], *inside])}
    return tuple(f"{key}={toml_value(value)}" for key, value in settings.items())


def with_settings(case_dir, settings: str, overrides=()) -> tuple:
    """The overrides of a study's runs: those of ``settings`` ("case": none; "recommended"; "fast": the
    recommended ones with FAST_STEP), then the user's --set, which win."""
    chosen = recommended(case_dir, overrides, NAMED[settings]) if settings in NAMED else ()
    return (*chosen, *overrides)
