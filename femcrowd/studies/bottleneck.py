"""Flow through a bottleneck against its width, for the models of femcrowd, drawn against the experiments
(docs/extensions.md, "Validation"): a waiting crowd of 2.5 persons/m^2 on 6 m x 6 m of an 8 m x 6 m
area leaves through a bottleneck 2 m long and w = 0.8 ... 2.4 m wide (the geometry of cases/bottleneck).

Models: the macro model with the constant speed law (U = 1.34 m/s towards the exit, rho_max = 5.4
persons/m^2), the same with Weidmann's law (Weidmann 1993), and the disc model (discs of radius 0.23 m,
whose hexagonal packing is 5.4 persons/m^2, pushing at 1.34 m/s). The flow J is the slope of the
evacuated people against time while the queue lasts (from 20 % to 80 % of the crowd out); the specific
flow is J / w. The experiments give about 1.9 persons/(m s) whatever the width (Seyfried et al. 2009;
Liao et al. 2014; the RiMEA bottleneck reference J = 1.9 w). The models are run as they are, not tuned.

    python -m femcrowd.studies.bottleneck [--out DIR] [--widths 0.8,1.2,...] [--models macro-constant,...]

writes DIR/bottleneck.csv and DIR/bottleneck.png (default DIR: /tmp/femcrowd-bottleneck).
"""

import argparse
import csv
import time
from pathlib import Path

import numpy as np

from ..case import load_case
from ..driver import Simulation
from ..macro.speed_law import SpeedLaw
from ..mesh.floorplan import build_mesh

#: the experimental specific flow, persons/(m s) (Seyfried et al. 2009; Liao et al. 2014; RiMEA)
EXPERIMENT = 1.9
#: Weidmann (1993): free speed (m/s) and jam density (persons/m^2), as in cases/bottleneck
SPEED, RHO_MAX = 1.34, 5.4
WIDTHS = (0.8, 1.2, 1.6, 2.0, 2.4)
PLAN = """size = 0.25
[outer]
points = [[0, 0], [8, 0], [8, {low}], [10, {low}], [10, {high}], [8, {high}], [8, 6], [0, 6]]
[[exits]]
name = "exit"
from = [10, {low}]
to = [10, {high}]
size = 0.1
"""
#: overrides of cases/bottleneck for each model
MODELS = {
    "macro-constant": {"velocity.speed_law": "constant"},
    "macro-weidmann": {"velocity.speed_law": "weidmann"},
    "discs": {"model.type": "micro", "velocity.speed_law": "constant", "micro.radius": 0.23},
}
LABELS = {"macro-constant": "macro, constant speed", "macro-weidmann": "macro, Weidmann's law",
          "discs": "discs (r = 0.23 m), pushing"}
CASE = Path(__file__).resolve().parents[2] / "cases" / "bottleneck"


def mesh(width, out):
    """The gmsh mesh of the bottleneck of this width (made once in out)."""
    path = Path(out) / f"bottleneck_{width:g}.msh"
    if not path.exists():
        plan = path.with_suffix(".toml")
        plan.write_text(PLAN.format(low=3 - width / 2, high=3 + width / 2))
        build_mesh(plan, path)
    return path


def flow(times, evacuated, total):
    """Persons per second while the queue lasts: the least-squares slope of evacuated(t) between 20 % and
    80 % of the crowd out; a crowd that clogs before 80 % are out gets its mean flow over the run."""
    window = (evacuated >= 0.2 * total) & (evacuated <= 0.8 * total)
    if evacuated[-1] < 0.8 * total or window.sum() < 2:
        return float(evacuated[-1] / times[-1])
    return float(np.polyfit(times[window], evacuated[window], 1)[0])


def run_width(model, width, out):
    """One run: the flow and specific flow, the people and the time they took."""
    overrides = {**MODELS[model], "mesh.file": str(mesh(width, out)), "time.end": 300.0}
    case = load_case(CASE, overrides)
    tic = time.perf_counter()
    result = Simulation(case).run()
    h = result.history
    people = h["count"][0] if "count" in h else h["mass"][0]
    j = flow(h["time"], h["evacuated"], people)
    return {"model": model, "width": width, "flow": j, "specific_flow": j / width, "people": float(people),
            "evacuated": float(h["evacuated"][-1]), "end": float(h["time"][-1]),
            "clogged": bool(h["evacuated"][-1] < 0.8 * people), "seconds": time.perf_counter() - tic}


def plot(rows, path):
    """Specific flow against width per model, with the experiments' 1.9 persons/(m s)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5), layout="constrained")
    for model in dict.fromkeys(r["model"] for r in rows):
        mine = [r for r in rows if r["model"] == model]
        ax.plot([r["width"] for r in mine], [r["specific_flow"] for r in mine], "o-", lw=2, label=LABELS[model])
        for r in mine:
            if r["clogged"]:
                ax.annotate("clogged", (r["width"], r["specific_flow"]), textcoords="offset points", xytext=(8, 0),
                            va="center", fontsize=8)
    widths = [r["width"] for r in rows]
    ax.axhline(EXPERIMENT, color="k", ls="--", lw=1.5,
               label="experiments: J = 1.9 w (Seyfried et al. 2009; Liao et al. 2014; RiMEA)")
    weidmann = SpeedLaw("weidmann", RHO_MAX)
    capacity = SPEED * RHO_MAX * float(weidmann.flux(np.array(weidmann.r_star)))
    ax.axhline(capacity, color="C1", ls=":", lw=1.2, label=f"Weidmann's capacity v0 max rho f(rho) = {capacity:.2f}")
    ax.set(xlabel="bottleneck width w (m)", ylabel="specific flow J / w (persons/(m s))", yscale="log",
           xlim=(min(widths) - 0.1, max(widths) + 0.1),
           title="Flow through a bottleneck, waiting crowd at 2.5 persons/m$^2$")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=110)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="/tmp/femcrowd-bottleneck")
    parser.add_argument("--widths", default=",".join(map(str, WIDTHS)))
    parser.add_argument("--models", default=",".join(MODELS))
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for model in args.models.split(","):
        for width in (float(w) for w in args.widths.split(",")):
            rows.append(run_width(model, width, out))
            r = rows[-1]
            clogged = f", clogged: {r['evacuated']:.0f} out by t = {r['end']:.0f} s" if r["clogged"] else ""
            print(f"{model:15s} w = {width:.1f} m: J = {r['flow']:.3g} persons/s, J/w = {r['specific_flow']:.3g} "
                  f"persons/(m s) ({r['people']:.0f} people{clogged}; run {r['seconds']:.1f} s)", flush=True)
    with open(out / "bottleneck.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    plot(rows, out / "bottleneck.png")
    print(f"wrote {out / 'bottleneck.csv'} and {out / 'bottleneck.png'}")


if __name__ == "__main__":
    main()
