"""Plausibility warnings of a scene (docs/case-format.md, "Plausibility warnings"): inputs that load and run
but are most likely a slip of units. Warnings, not errors: one line each on the "femcrowd" log (stderr)."""

import logging

import numpy as np

log = logging.getLogger("femcrowd")

#: walking speeds (m/s) taken as plausible, checked when the densities are in people/m^2 (rho_max != 1)
SPEEDS = (0.1, 5.0)
#: the warnings given so far in this process: each once (a study builds its scene once per level)
_given = set()


def warn_implausible(scene) -> list:
    """Log each of the scene's plausibility warnings that was not given before; all of them, as text."""
    found = [*_speeds(scene), *_weidmann(scene), *_discs(scene)]
    for text in found:
        if text not in _given:
            _given.add(text)
            log.warning(text)
    return found


def _population_key(case, name, key):
    """The key that sets `key` of population `name`: populations.<name>.<key>, or the one of [velocity]."""
    spec = case["populations"].get(name) if case["populations"] else None
    return (f"populations.{name}.{key}", spec[key]) if spec and spec[key] is not None \
        else (f"velocity.{key}", case["velocity"][key])


def _speeds(scene):
    """Desired speeds (at t = 0, over the cells) whose largest is outside SPEEDS, in a case in people/m^2."""
    case = scene.case
    if case["model"]["rho_max"] == 1:   # densities in fractions of saturation: lengths and times may be unitless
        return []
    exits = scene.boundary.at(0.0)
    found = []
    for population in scene.populations:
        fastest = float(np.hypot(*population.velocity.at_centroids(0.0, exits).T).max())
        if not SPEEDS[0] <= fastest <= SPEEDS[1]:
            kind = _population_key(case, population.name, "type")[1]
            key, value = _population_key(case, population.name, "speed" if kind == "exits" else "ux")
            if kind != "exits":
                key, value = f"{key} and uy", f"{value}, {_population_key(case, population.name, 'uy')[1]}"
            found.append(f"{case.file}: {key} = {value!r}: a desired speed of up to {fastest:.3g} m/s, outside "
                         f"the {SPEEDS[0]:g}-{SPEEDS[1]:g} m/s people walk at (model.rho_max = "
                         f"{case['model']['rho_max']:g} people/m^2; a speed in other units?)")
    return found


def _weidmann(scene):
    """Weidmann's law, a fit in people/m^2 (jam at 5.4), with rho_max = 1: the crowd jams at 1 person/m^2."""
    case = scene.case
    if case["model"]["rho_max"] != 1:
        return []
    keys = dict(_population_key(case, p.name, "speed_law") for p in scene.populations if p.law.spec == "weidmann")
    return [f"{case.file}: {key} = {value!r} with model.rho_max = 1: Weidmann's law is in people/m^2 (a jam at "
            f"5.4 people/m^2); give the densities in people/m^2 and model.rho_max = 5.4" for key, value in keys.items()]


def _discs(scene):
    """Discs (of micro.radius, the smallest) wider than the widest exit: none could leave."""
    case = scene.case
    exits = [door for door in scene.boundary.doors if door.exit]
    if case["model"]["type"] != "micro" or case["micro"]["positions"] is not None or not exits:
        return []
    widest = max(exits, key=lambda door: door.width)
    diameter = 2 * float(np.min(case["micro"]["radius"]))
    if diameter <= widest.width:
        return []
    return [f"{case.file}: micro.radius = {case['micro']['radius']!r}: discs {diameter:.3g} m wide, wider than every "
            f"exit (the widest, {widest.name}, is {widest.width:.3g} m): no disc can leave"]
