"""The unit of the people of a case or run (pictures, `femcrowd info`, the end of a run): people, or crowd area
at saturation.

docs/case-format.md: densities are in the unit of `model.rho_max`; with rho_max = 5.4 they are people per
m^2, with the default rho_max = 1 fractions of saturation, so a mass (density x m^2) is then the area the
crowd fills at rho_max (m^2 at rho_max), unless Weidmann's law says the densities are people per m^2.
"""


def counts_people(case: dict) -> bool:
    """Are the densities of the case (a case's resolved table, or a run's copy of it) people per m^2? Yes with a
    rho_max other than 1, Weidmann's law or a number of people (initial.people, populations.<name>.people)."""
    populations = case.get("populations", {}).values()
    laws = [case.get("velocity", {}).get("speed_law")] + [spec.get("speed_law") for spec in populations]
    people = [case.get("initial", {}).get("people")] + [spec.get("people") for spec in populations]
    return case.get("model", {}).get("rho_max", 1.0) != 1 or "weidmann" in laws or any(n is not None for n in people)


def density_title(people: bool) -> str:
    return "density (people/m^2)" if people else "density (rho / rho_max)"


def crowd_unit(people: bool) -> str:
    """The unit of a number of people (history's mass or count), for axis labels: 'people' or 'm^2 at rho_max'."""
    return "people" if people else "m^2 at rho_max"


def people_unit(case: dict) -> str:
    """The unit of a count of the case's crowd: 'people' (discs, or densities in people per m^2) or
    'm^2 at rho_max'."""
    return "people" if case.get("model", {}).get("type") == "micro" or counts_people(case) else crowd_unit(False)
