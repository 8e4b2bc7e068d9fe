"""The RiMEA verification tests that apply to femcrowd (``femcrowd rimea``, docs/rimea.md).

RiMEA e.V., "Guideline for Microscopic Evacuation Analysis", version 3.0 (2016) and later: each test states
a scene and the result a model must show. The cases are ``cases/rimea/<test>`` (geometries as in
JuPedSim's RiMEA tests, Juelich Supercomputing Centre); each runs with every variant of the models
(:data:`VARIANTS`): the paper's density model and its discs (radius 0.23 m: pi r^2 / hexagonal packing =
1 / 5.4 m^2, so that a disc is one person at the saturation density rho_max = 5.4 persons/m^2), the settings
docs/validation.md recommends for realistic door flows (Predtechenskii and Milinskii's law at the test's own speed
with the capacity of each door's width; arch-breaking discs), the settings recommended before (the variant
weidmann-push: Weidmann's law that pushes, a capacity of 1.9), and in the tests of route choice (10, 11, 14) the
recommended settings with the route choice that sees the crowd (``velocity.route = "congestion"``,
femcrowd/macro/velocity.py CongestionVelocity). Each test
judges what a user reads from the run: history, summary, measurements.csv. The disc runs depend on the
sampling of the discs and their fluctuation (``micro.seed``), and which arch holds at a door even on round-off:
with ``seeds`` they run once per seed and each figure is given over the seeds (:class:`Spread`).
"""

from dataclasses import dataclass
from pathlib import Path
from string import Formatter
from typing import Callable

import numpy as np

from .. import shipped
from ..case import load_case
from ..driver import Simulation
from ..timer import Stopwatch
from .execute import Progress
from .recommended import DISCS, FLUCTUATION, PUSH, PUSH_CAPACITY, PUSHING, WEIDMANN_PUSH, door_capacity
from .recommended import MACRO as RECOMMENDED

#: the cases (shipped with femcrowd)
CASES = shipped.cases("rimea")
#: the route choice that sees the crowd: each cell heads for the exit of least max(walking time, waiting time),
#: re-solved every second (the discs have no door capacity, so they see the walking time on their density only)
ROUTES = {"velocity.route": "congestion"}


@dataclass(frozen=True)
class Variant:
    """A column of the table: a model and its settings, as case overrides. ``capacity``: the capacity every door
    of the test (its exits and its interior doors) gets (persons/(m s), or "auto": that of its width), or None."""

    label: str
    overrides: dict
    capacity: float | str | None = None

    @property
    def micro(self) -> bool:
        return self.overrides.get("model.type") == "micro"


DISC_LABEL = f"discs, Weidmann, push {PUSH:g}, decelerating, fluctuation {FLUCTUATION:g} m/s"
VARIANTS = {
    "macro": Variant("macro (the paper's)", {}),
    "macro-capacity": Variant(f"macro, doors {PUSH_CAPACITY:g} /(m s)", {}, PUSH_CAPACITY),
    "macro-pushing": Variant(f"macro, Weidmann, push {PUSH:g}", PUSHING),
    "macro-recommended": Variant("macro, Predtechenskii-Milinskii, doors of their width (recommended)", RECOMMENDED,
                                 "auto"),
    "macro-weidmann-push": Variant(f"macro, Weidmann, push {PUSH:g}, doors {PUSH_CAPACITY:g} /(m s) (weidmann-push)",
                                   WEIDMANN_PUSH, PUSH_CAPACITY),
    "micro": Variant("discs (the paper's)", {"model.type": "micro"}),
    "micro-recommended": Variant(f"{DISC_LABEL} (recommended)", {"model.type": "micro", **DISCS}),
    "macro-routes": Variant("macro, Predtechenskii-Milinskii, doors of their width, route choice (recommended + "
                            "congestion)", {**RECOMMENDED, **ROUTES}, "auto"),
    "micro-routes": Variant(f"{DISC_LABEL}, route choice (recommended + congestion)",
                            {"model.type": "micro", **DISCS, **ROUTES}),
}
MODELS = tuple(VARIANTS)
#: the variants every test runs with (unless it names its own): all but the route choice, which only the tests of
#: route choice (10, 11, 14) run
PLAIN = MODELS[:7]
#: the density model's columns of PLAIN: the tests the discs do not run (4: a density; 8, 13, 14: buildings whose
#: disc runs are not set up here yet, docs/floors.md)
MACRO = PLAIN[:5]


@dataclass
class Verdict:
    """What a model shows in a test and whether that meets the criterion (None: a test whose result RiMEA asks to
    document, 8 and 14): `text`, a format string of the `figures` (``"N4 {n4:.0f}"``), so that the figures of
    several seeds can be put together (:class:`Spread`)."""

    text: str
    figures: dict
    passed: bool

    @property
    def value(self) -> str:
        return self.text.format(**self.figures)

    @property
    def label(self) -> str:
        return "documented" if self.passed is None else "pass" if self.passed else "fail"


@dataclass
class Spread:
    """The verdicts of one test and variant over the seeds of the discs (micro.seed = 1 to n): each figure as its
    median and, where the seeds differ, its range, ``"N2 126 (106-237)"`` (in the format of the figure); the
    verdict as the number of seeds that pass and that fail, ``"pass 3/5, fail 2/5"``. Seeds whose verdicts read
    differently (a corridor that clogs in one seed, flows in the others) are given apart, with how many seeds each."""

    verdicts: list

    @property
    def passed(self) -> bool:
        return all(v.passed for v in self.verdicts)

    @property
    def label(self) -> str:
        n, passed = len(self.verdicts), sum(v.passed for v in self.verdicts)
        return ", ".join(f"{word} {k}/{n}" for word, k in (("pass", passed), ("fail", n - passed)) if k)

    @property
    def value(self) -> str:
        texts = list(dict.fromkeys(v.text for v in self.verdicts))
        if len(texts) == 1:
            return spread_text(texts[0], self.verdicts)
        return "; ".join(f"{spread_text(t, group)} in {len(group)} of {len(self.verdicts)} seeds"
                         for t in texts for group in [[v for v in self.verdicts if v.text == t]])


def spread_text(text: str, verdicts: list) -> str:
    """`text` with each figure the median (min-max) of its values in `verdicts`, or their value if all read alike."""
    parts = []
    for literal, field, spec, _ in Formatter().parse(text):
        parts.append(literal)
        if field is None:
            continue
        values = np.array([v.figures[field] for v in verdicts], dtype=float)
        low, middle, high = (format(x, spec) for x in (values.min(), np.median(values), values.max()))
        parts.append(middle if low == high else f"{middle} ({low}-{high})")
    return "".join(parts)


@dataclass
class RimeaTest:
    """A RiMEA test: its number and title, the criterion as RiMEA states it (and how it is judged here),
    its cases (names, or (name, overrides) pairs) and the judge of their results (one per case, in order);
    ``micro``: overrides of the disc runs; ``doors``: the interior doors of its floor plan (a capacity in
    the variants with door capacities); ``variants``: those it runs with."""

    number: str
    title: str
    criterion: str
    cases: tuple
    judge: Callable
    micro: dict = None
    doors: tuple = ()
    variants: tuple = PLAIN


def crossing_time(m: dict, line: str, count: float) -> float:
    """The time at which the cumulative count of a line reaches `count` (linear between rows)."""
    c, t = m[f"{line}_count"], m["time"]
    k = int(np.argmax(c >= count - 1e-9))
    if c[k] < count - 1e-9:
        return np.inf
    if k == 0:
        return float(t[0])
    return float(t[k - 1] + (count - c[k - 1]) / (c[k] - c[k - 1]) * (t[k] - t[k - 1]))


def people(result) -> float:
    """How many people a run started with (persons: the macro mass, or the discs)."""
    h = result.history
    return float(h["mass"][0] if "mass" in h else h["count"][0])


def corridor(results) -> Verdict:
    """Test 1: the time between the lines 40 m apart, when half of the person has crossed each."""
    r = results[0]
    half = people(r) / 2
    seconds = crossing_time(r.measurements, "end", half) - crossing_time(r.measurements, "start", half)
    return Verdict("{seconds:.1f} s", {"seconds": seconds}, 26.0 <= seconds <= 34.0)


def corner(results) -> Verdict:
    """Test 6: everyone leaves through the exit; nothing crosses a wall."""
    r = results[0]
    h, n = r.history, people(r)
    out = float(h["evacuated"][-1])
    if "mass" in h:   # the density leaves only through the exit: mass + evacuated = mass(0) at every step
        leak = float(r.summary["max_mass_error"])
        return Verdict("{out:.2f} of {n:.2f} out, mass error {leak:.0e}", {"out": out, "n": n, "leak": leak},
                       out >= n - 0.01 and leak < 1e-10)
    outside = int(r.summary["discs_outside"])
    return Verdict("{out:.0f} of {n:.0f} out, {outside:.0f} discs outside", {"out": out, "n": n, "outside": outside},
                   out == n and outside == 0)


#: test 4: the densities of the corridor (persons/m^2), and how far from Weidmann's speed a measured one may be
#: RiMEA tests 2 and 3 (JuPedSim's set-up): the stair's length along its slope (m), its speeds up and down (m/s)
STAIR_LENGTH, STAIR_UP, STAIR_DOWN = 10.0, 0.5, 0.75
#: the time on the stair within this fraction of STAIR_LENGTH / speed (JuPedSim's runtest_rimea_2.py and _3.py)
STAIR_TOLERANCE = 0.05


def stair_walk(speed):
    """Tests 2, 3: the judge of one person on the stair at `speed`. The time the person spends on it is the
    integral of the people on it (history.csv, on_stair) over the run, per person: the mean residence time,
    which the spreading of the density does not change."""
    def judge(results) -> Verdict:
        h = results[0].history
        on = h["on_stair"]
        seconds = float(np.sum(0.5 * (on[1:] + on[:-1]) * np.diff(h["time"]))) / people(results[0])
        expected = STAIR_LENGTH / speed
        return Verdict("{seconds:.2f} s", {"seconds": seconds}, abs(seconds - expected) <= STAIR_TOLERANCE * expected)
    return judge


DENSITIES = (0.5, 1.0, 2.0, 3.0, 4.0, 5.0)
WEIDMANN_TOLERANCE = 0.15   # m/s, up to 4 persons/m^2


def weidmann_speed(density, free=1.34):
    """Weidmann (1993): v = v0 (1 - exp(-1.913 (1/rho - 1/5.4))), m/s."""
    return free * -np.expm1(-1.913 * (1.0 / density - 1.0 / 5.4))


def fundamental_diagram(results) -> Verdict:
    """Test 4: the mean speed in the measurement area after 5 s, for each density: falling as the density grows
    (never rising), and within WEIDMANN_TOLERANCE of Weidmann's up to 4 persons/m^2."""
    speeds = np.array([float(np.interp(5.0, r.measurements["time"], r.measurements["middle_speed"]))
                       for r in results])
    density = np.array(DENSITIES[:len(speeds)])
    close = np.abs(speeds - weidmann_speed(density))[density <= 4.0].max()
    text = ", ".join(f"{d:g}: {{v{k}:.2f}}" for k, d in enumerate(density)) + " m/s"
    falls = np.all(np.diff(speeds) <= 1e-9) and speeds[-1] < speeds[0]
    return Verdict(text, {f"v{k}": float(v) for k, v in enumerate(speeds)}, bool(falls and close <= WEIDMANN_TOLERANCE))


#: test 9: the space is empty when less than this fraction is inside (half a person of 1000: the last one left)
LEFT_BEHIND = 0.0005


def evacuation_time(result, inside=None) -> float:
    """The first time at which fewer than `inside` persons are inside (default LEFT_BEHIND of the people): the last
    person, for a density."""
    h = result.history
    inside = LEFT_BEHIND * people(result) if inside is None else inside
    gone = np.flatnonzero(h["evacuated"] >= people(result) - inside)
    return float(h["time"][gone[0]]) if len(gone) else np.inf


def four_and_two_doors(results) -> Verdict:
    """Test 9: the time the space empties with four doors (T4) and with doors 1 and 2 locked (T2); when a run
    does not empty by its end (the disc runs stop at 40 s: 1000 discs for minutes cost more than the table's
    budget), the ratio of the people out by then, N4 / N2 (twice as long = half the flow)."""
    four, two = (evacuation_time(r) for r in results)
    if np.isfinite(four) and np.isfinite(two):
        ratio = two / four
        return Verdict("T4 {four:.0f} s, T2 {two:.0f} s, ratio {ratio:.2f}", {"four": four, "two": two, "ratio": ratio},
                       1.5 <= ratio <= 2.5)
    end = min(r.history["time"][-1] for r in results)
    n4, n2 = (float(np.interp(end, r.history["time"], r.history["evacuated"])) for r in results)
    ratio = n4 / n2 if n2 > 0 else np.inf
    return Verdict("out by {end:.0f} s: N4 {n4:.0f}, N2 {n2:.0f}, ratio {ratio:.2f}",
                   {"end": end, "n4": n4, "n2": n2, "ratio": ratio}, 1.5 <= ratio <= 2.5)


#: test 10: each exit and the population assigned to it ([populations.<name>] exits = [exit])
ASSIGNED = {"main": "to_main", "secondary": "to_secondary"}


def assigned_exits(results) -> Verdict:
    """Test 10: who left by each exit (the count of a line on it) against the population assigned to it.
    Each population heads for its exit only, so a person leaving by the other exit shows as a count above what
    the exit's own population lost (a swap both ways would cancel out; tests/studies/test_rimea.py shows a
    one-way misrouting caught); and everyone has to leave (the last out within the run)."""
    r = results[0]
    h, m = r.history, r.measurements
    cells, figures, wrong, inside = [], {}, 0.0, 0.0
    for door, population in ASSIGNED.items():
        n = float(h[f"mass_{population}"][0] if f"mass_{population}" in h else h[f"count_{population}"][0])
        out, through = float(h[f"evacuated_{population}"][-1]), float(m[f"{door}_count"][-1])
        cells.append(f"{door} {{{door}:.4g}} of {{n_{door}:.0f}}")
        figures.update({door: through, f"n_{door}": n})
        wrong += max(through - out, 0.0)
        inside += n - out
    figures.update(wrong=wrong, inside=inside, end=float(h["time"][-1]))
    state = "all out by {end:.0f} s" if inside < 0.05 else "{inside:.4g} inside at {end:.0f} s"
    return Verdict(f"{', '.join(cells)}, {{wrong:.1f}} by the other exit; {state}", figures,
                   wrong < 0.05 and inside < 0.05)


def exit_choice(results) -> Verdict:
    """Test 11: the share of the people who leave through each exit."""
    m = results[0].measurements   # lines on the two doors
    near, far = float(m["near_count"][-1]), float(m["far_count"][-1])
    total = near + far
    return Verdict("near {near:.0f} %, far {far:.1f} % ({persons:.1f} persons)",
                   {"near": 100 * near / total, "far": 100 * far / total, "persons": far}, near > far and far >= 1.0)


def flow(m: dict, line: str, n: float) -> float:
    """Mean flow through a line while the middle 80 % of the people pass it (persons/s)."""
    return 0.8 * n / (crossing_time(m, line, 0.9 * n) - crossing_time(m, line, 0.1 * n))


def bottlenecks(results) -> Verdict:
    """Test 12: the flow out of the corridor (J_b) and through the last exit (J_e), each while the middle 80 % pass:
    a jam at the exit makes J_e < J_b, but so does a stream whose speed falls with its density while its flow rises
    (docs/rimea.md, test 12). JuPedSim's runtest_rimea_12.py fails the other way, on J_e > J_b + 0.05."""
    r = results[0]
    n = people(r)
    m = r.measurements
    if m["exit_count"][-1] < 0.9 * n:   # a jam that never clears (a stable arch of discs): no flow to compare
        return Verdict("{left:.0f} of {n:.0f} left the corridor, {out:.0f} the exit by t = {end:.0f} s",
                       {"left": float(m["bottleneck_count"][-1]), "n": n, "out": float(m["exit_count"][-1]),
                        "end": float(m["time"][-1])}, False)
    jb, je = flow(m, "bottleneck", n), flow(m, "exit", n)
    return Verdict("J_b {jb:.2f} /s, J_e {je:.2f} /s", {"jb": jb, "je": je}, je >= jb - 0.05)


#: test 8: the desired speeds on the stairs of the three-storey building (m/s, along the slope), one run each
STAIR_STUDY = (0.5, 0.65, 0.8)


def parameter_study(results) -> Verdict:
    """Test 8: the evacuation time (the last person out: less than half a person inside) for each stair speed of
    STAIR_STUDY.
    RiMEA asks how the time depends on the parameter, no criterion: documented, with whether it falls as the stairs
    get faster."""
    times = [evacuation_time(r, 0.5) for r in results]
    text = ", ".join(f"{v:g} m/s: {{t{k}:.1f}} s" for k, v in enumerate(STAIR_STUDY[:len(times)]))
    falls = bool(np.all(np.diff(times) < 0))
    return Verdict(text + ("; falls as the stairs get faster" if falls else "; does not fall as the stairs get faster"),
                   {f"t{k}": t for k, t in enumerate(times)}, None)


#: test 13: the corridor's area (m^2: 11.5 m x 2 m, meshes/rimea/test13_stair.toml)
CORRIDOR_AREA = 23.0


def stair_congestion(results) -> Verdict:
    """Test 13: the flow into the corridor J_c (the people past the room and its entrance: mass - on_room -
    on_entrance) and onto the stair J_s (on_stair + on_landing + evacuated), each while the middle 80 % pass
    (:func:`flow`), and the most people the corridor held, as a density. A jam in front of the stair (judged as
    JuPedSim): J_s < J_c - 0.05 persons/s."""
    r = results[0]
    h, n = r.history, people(r)
    counts = {"time": h["time"], "corridor_count": n - h["on_room"] - h["on_entrance"],
              "stair_count": h["on_stair"] + h["on_landing"] + h["evacuated"]}
    jc, js = flow(counts, "corridor", n), flow(counts, "stair", n)
    density = float(h["on_corridor"].max()) / CORRIDOR_AREA
    return Verdict("J_c {jc:.2f} /s, J_s {js:.2f} /s, corridor up to {density:.2f} persons/m^2",
                   {"jc": jc, "js": js, "density": density}, js < jc - 0.05)


def routes_over_floors(results) -> Verdict:
    """Test 14: who takes the short route (down the left stair: the flow through its head summed over the steps)
    and who the long one (the others). RiMEA asks no criterion but the state, short, long or mixed: documented."""
    r = results[0]
    h, n = r.history, people(r)
    short = float(np.sum(h["flow_left_head"][1:] * np.diff(h["time"])))
    long = max(n - short, 0.0)
    state = "short" if long < 0.5 else "long" if short < 0.5 else "mixed"
    end, inside = evacuation_time(r, 0.5), n - float(h["evacuated"][-1])
    out = "all out at {end:.0f} s" if np.isfinite(end) else "{inside:.1f} inside at {end:.0f} s"
    return Verdict(f"{state}: short {{short:.1f}}, long {{long:.1f}} of {{n:.0f}}; {out}",
                   {"short": short, "long": long, "n": n, "inside": inside,
                    "end": end if np.isfinite(end) else float(h["time"][-1])}, None)


TESTS = [
    RimeaTest("1", "speed in a corridor", "one person at 1.33 m/s covers 40 m in 26 s to 34 s",
              ("test01-corridor",), corridor),
    RimeaTest("2", "walking up a stair", f"one person keeps its speed up a stair {STAIR_LENGTH:g} m long (judged as "
              f"JuPedSim: the time on the stair within {STAIR_TOLERANCE:.0%} of {STAIR_LENGTH:g} m / {STAIR_UP:g} m/s "
              f"= {STAIR_LENGTH / STAIR_UP:g} s)", ("test02-stair-up",), stair_walk(STAIR_UP)),
    RimeaTest("3", "walking down a stair", f"one person keeps its speed down a stair {STAIR_LENGTH:g} m long (judged "
              f"as JuPedSim: the time on the stair within {STAIR_TOLERANCE:.0%} of {STAIR_LENGTH:g} m / "
              f"{STAIR_DOWN:g} m/s = {STAIR_LENGTH / STAIR_DOWN:.3g} s)", ("test03-stair-down",),
              stair_walk(STAIR_DOWN)),
    RimeaTest("4", "fundamental diagram", "the speed in a corridor against the density (0.5 to 5 persons/m^2) "
              "as the empirical diagram (judged: falling, within 0.15 m/s of Weidmann 1993 up to 4 persons/m^2)",
              tuple(("test04-fundamental-diagram", {"initial.density": d}) for d in DENSITIES),
              fundamental_diagram, variants=MACRO),
    RimeaTest("6", "movement around a corner", "20 persons go around a left corner without passing through "
              "walls (judged: all leave by the exit; macro: no mass lost, micro: no disc outside)",
              ("test06-corner",), corner),
    RimeaTest("8", "parameter analysis", "a three-storey building: how the evacuation time depends on a parameter "
              f"(here the desired speed on the stairs, {', '.join(f'{v:g}' for v in STAIR_STUDY)} m/s; documented, "
              "no criterion)", tuple(("test08-three-storeys", {"velocity.speeds": {"stair_01": v, "stair_12": v}})
                                     for v in STAIR_STUDY), parameter_study,
              variants=("macro", "macro-recommended")),
    RimeaTest("9", "leaving a large public space", "1000 persons, four doors; with doors 1 and 2 locked it takes "
              "approximately twice as long (judged: 1.5 <= T2 / T4 <= 2.5, T when the last person has left)",
              ("test09-four-exits", "test09-two-exits"), four_and_two_doors, {"time.end": 40.0}),
    RimeaTest("10", "allocation of escape routes", "23 persons in twelve rooms, each assigned the main exit "
              "(rooms 1-4, 7-10: 15) or the secondary one (rooms 5, 6, 11, 12: 8), use their assigned exits "
              "(judged: each exit passes its 15 or 8 and nobody else, everyone out)",
              ("test10-escape-routes",), assigned_exits, variants=MODELS),
    RimeaTest("11", "choice of exit", "the persons prefer the nearest exit, some choose the second one "
              "(judged: more use the near exit, at least one person the far one)",
              ("test11-exit-choice",), exit_choice, variants=MODELS),
    RimeaTest("12", "effect of bottlenecks", "150 persons leave a room through a corridor into a second room; "
              "no congestion at the last exit (judged: J_e >= J_b - 0.05 persons/s, JuPedSim's tolerance; RiMEA asks "
              "to document it, not to exclude a model by it)",
              ("test12-bottlenecks",), bottlenecks, doors=("corridor",)),
    RimeaTest("13", "flow at a stair", "150 persons walk from a room along a corridor 2 m wide to a stair up; they "
              "walk slower on the stair, so a jam forms in front of it (judged as JuPedSim: the flow onto the stair "
              "J_s < the flow into the corridor J_c - 0.05 persons/s)", ("test13-stair-congestion",),
              stair_congestion, doors=("stair_foot", "stair_head"), variants=MACRO),
    RimeaTest("14", "route choice over floors", "150 persons choose between a short route down and up two stairs "
              "and a long one on their floor: which they take, short, long or mixed (documented, no criterion)",
              ("test14-routes-over-floors",), routes_over_floors,
              doors=("left_foot", "left_head", "right_foot", "right_head"), variants=(*MACRO, "macro-routes")),
]


def select(only=()) -> list:
    """The tests to run: all, or those whose numbers are in `only`."""
    known = {t.number for t in TESTS}
    unknown = [n for n in only if n not in known]
    if unknown:
        raise ValueError(f"no RiMEA test {unknown[0]!r} here (tests: {', '.join(sorted(known, key=int))})")
    return [t for t in TESTS if not only or t.number in only]


def run_test(test: RimeaTest, variant: str, cases=CASES, out=None, seed=None, progress=None) -> tuple:
    """Run a test's cases with one variant (writing OUT/<case>-<variant> when out is given, OUT/<case>-<variant>-seed<k>
    for a disc variant given a seed k: micro.seed = k); (Verdict, seconds). progress: a Progress counting the runs."""
    clock = Stopwatch()
    chosen, results = VARIANTS[variant], []
    seeded = {"micro.seed": seed} if chosen.micro and seed is not None else {}
    for k, entry in enumerate(test.cases):
        name, own = (entry, {}) if isinstance(entry, str) else entry
        overrides = {**chosen.overrides, **own, **((test.micro or {}) if chosen.micro else {}), **seeded}
        if chosen.capacity is not None:
            overrides.update(door_capacity([*load_case(Path(cases) / name)["boundary"]["exits"], *test.doors],
                                           chosen.capacity))
        case = load_case(Path(cases) / name, overrides)
        suffix = ("" if isinstance(entry, str) else f"-{k}") + (f"-seed{seed}" if seeded else "")
        target = Path(out) / f"{name}-{variant}{suffix}" if out is not None else None
        results.append(Simulation(case).run(target, force=True))
        if progress is not None:
            progress.advance()
    return test.judge(results), clock.seconds


def run_seeds(test: RimeaTest, variant: str, seeds: int, cases=CASES, out=None, progress=None) -> tuple:
    """A disc variant with micro.seed = 1 to `seeds` (Spread, seconds of all); a macro variant, deterministic, once."""
    if not VARIANTS[variant].micro:
        return run_test(test, variant, cases, out, progress=progress)
    runs = [run_test(test, variant, cases, out, seed, progress) for seed in range(1, seeds + 1)]
    return Spread([verdict for verdict, _ in runs]), sum(seconds for _, seconds in runs)


def run_all(only=(), models=MODELS, cases=CASES, out=None, echo=None, seeds=None, quiet: bool = True) -> list:
    """Every selected test with every variant in `models` it runs with: rows (test, {variant: (Verdict, seconds)});
    with `seeds`, the disc variants over micro.seed = 1 to `seeds` (:func:`run_seeds`: (Spread, seconds)).
    echo(row) after each test; unless quiet, a progress bar of the runs."""
    rows, tests = [], select(only)
    total = sum(len(test.cases) * (seeds if seeds and VARIANTS[variant].micro else 1)
                for test in tests for variant in models if variant in test.variants)
    with Progress(total, echo, quiet) as progress:
        for test in tests:
            verdicts = {variant: None if variant not in test.variants
                        else run_test(test, variant, cases, out, progress=progress) if seeds is None
                        else run_seeds(test, variant, seeds, cases, out, progress) for variant in models}
            rows.append((test, verdicts))
            progress.echo(format_row(test, verdicts))
    return rows


def format_row(test: RimeaTest, verdicts: dict) -> str:
    cells = ["not run" if v is None else f"{v[0].value} ({v[0].label.replace('fail', 'FAIL')}, {v[1]:.0f} s)"
             for v in verdicts.values()]
    return f"{test.number:>3} {test.title:<30} " + " | ".join(cells)


def table_markdown(rows) -> str:
    """The table of docs/rimea.md; below it, when disc variants ran over seeds, how to read their cells."""
    variants = list(rows[0][1]) if rows else list(MODELS)
    lines = ["| test | criterion (RiMEA) | " + " | ".join(VARIANTS[v].label for v in variants) + " |",
             "|---|---|" + "---|" * len(variants)]
    for test, verdicts in rows:
        cells = ["not run" if v is None else f"{v[0].value}: **{v[0].label}** ({v[1]:.0f} s)"
                 for v in verdicts.values()]
        lines.append(f"| {test.number} {test.title} | {test.criterion} | " + " | ".join(cells) + " |")
    spreads = [v[0] for _, verdicts in rows for v in verdicts.values() if v is not None and isinstance(v[0], Spread)]
    if spreads:
        n = len(spreads[0].verdicts)
        lines += ["", f"Disc columns: each figure the median (min-max) over micro.seed = 1 to {n} (one value: all "
                      f"seeds alike), pass k/{n}, fail k/{n}: the seeds that pass, that fail; the seconds those of all "
                      f"{n}; macro columns: one run (deterministic)."]
    return "\n".join(lines) + "\n"
