"""``femcrowd plot``, ``report``, ``mesh``, ``new`` and ``info``: looking at results, making scenes."""

import shlex
from pathlib import Path

import click

from ..case import load_case
from ..case.loading import toml_key, toml_value
from .main import main, set_option


def _times(values):
    """--times 0,10 --times 20 -> [0.0, 10.0, 20.0]."""
    out = []
    for value in values:
        for item in filter(None, (v.strip() for v in value.split(","))):
            try:
                out.append(float(item))
            except ValueError:
                raise click.BadParameter(f"{item!r} is not a number", param_hint="--times") from None
    return out


def _is_case(path) -> bool:
    """A case to preview: a .toml file, or a directory with case.toml and no frames of a run."""
    path = Path(path)
    if path.is_file():
        return path.suffix == ".toml"
    return (path / "case.toml").is_file() and not any((path / f"{s}.pvd").is_file() for s in ("solution", "discs"))


@main.command()
@click.argument("outdir", metavar="OUTDIR|CASE_DIR", type=click.Path())
@click.option("-t", "--times", "times", multiple=True, metavar="T[,T...]",
              help="Times (s) of the pictures, comma-separated or repeated; the nearest frames are used. "
                   "Default: 4 evenly spaced times until 95% of the crowd has left.")
@click.option("--no-animation", is_flag=True, help="Skip the animation (the slowest part).")
@click.option("--mp4", is_flag=True, help="Animation as MP4 instead of GIF (needs imageio-ffmpeg).")
@click.option("-o", "--out", type=click.Path(),
              help="Directory for the pictures (default: OUTDIR/plots; for CASE_DIR the current directory).")
@set_option
@click.option("-q", "--quiet", is_flag=True, help="No progress bar, no list of files.")
def plot(outdir, times, no_animation, mp4, out, overrides, quiet):
    """Pictures, animation and curves of a run's output directory OUTDIR, or a preview of the scene of
    CASE_DIR before any run.

    Of a run: density_t*.png and pressure_t*.png (micro runs: discs_t*.png) at
    the chosen times, density.gif (micro: discs.gif) and curves.png (people
    inside and evacuated, flow rate per exit, max pressure, saturated area).
    Rendering is offscreen: no display needed.

    Of a case (a directory with case.toml and no frames, or a .toml file):
    CASE-preview.png, the scene at t = 0 as the run would build it (walls,
    exits with their schedules, sources, measurement lines and areas, the
    initial crowd and its number of people); --set as for femcrowd run.

    \b
    Examples:
      femcrowd plot cases/room/output
      femcrowd plot /tmp/room --times 0,5,10 --no-animation
      femcrowd plot /tmp/room -o /tmp/room-pictures
      femcrowd plot cases/entrance -o /tmp/previews --set model.type=micro
    """
    from ..errors import InputError

    if _is_case(outdir):
        from ..plot.preview import preview

        if times:
            raise InputError(outdir, "--times", ",".join(times), "a case has no frames: --times is for the output "
                             "directory of a run (the preview shows t = 0)")
        path, total = preview(load_case(outdir, overrides), out)
        click.echo(f"wrote {path}")
        return
    if overrides:
        raise InputError(outdir, "--set", overrides[0], "is for a case directory (a preview); the pictures of a "
                         "run show the case it ran")
    from ..plot import plot_run

    written = plot_run(outdir, _times(times) or None, not no_animation, out, mp4, quiet)
    if not quiet:
        for path in written:
            click.echo(f"wrote {path}")
    click.echo(f"{len(written)} files in {Path(written[0]).parent if written else outdir}")


def _segment(value):
    """--exit NAME=X0,Y0,X1,Y1 -> (name, (x0, y0), (x1, y1))."""
    try:
        name, numbers = value.split("=", 1)
        x0, y0, x1, y1 = (float(v) for v in numbers.split(","))
    except ValueError:
        raise click.BadParameter(f"{value!r} is not NAME=X0,Y0,X1,Y1", param_hint="--exit") from None
    return name.strip(), (x0, y0), (x1, y1)


@main.command()
@click.argument("geometry", type=click.Path())
@click.option("-o", "--out", type=click.Path(), help="The .msh file (default: GEOMETRY with .msh).")
@click.option("--exit-size", type=click.FloatRange(min=0, min_open=True), metavar="H",
              help="Cell size near every exit (m), overriding the exits' own 'size' keys.")
@click.option("--size", type=click.FloatRange(min=0, min_open=True), default=0.2, show_default=True, metavar="H",
              help="DXF and WKT plans: the cell size (m).")
@click.option("--units", metavar="UNIT",
              help="DXF and WKT plans: the drawing's length unit (mm, cm, dm, m, km, in, ft, yd). Default: the "
                   "DXF's $INSUNITS (unitless: m); m for WKT.")
@click.option("--wall-thickness", type=click.FloatRange(min=0, min_open=True), metavar="T",
              help="DXF and WKT plans: thickness (m) given to the internal walls drawn as lines (default 0.1).")
@click.option("--walls-layer", default="walls", show_default=True, help="DXF: the layer of the outline.")
@click.option("--obstacles-layer", default="obstacles", show_default=True, help="DXF: the layer of the obstacles.")
@click.option("--door-layers", default="exit,entrance", show_default=True, metavar="PREFIX[,PREFIX...]",
              help="DXF: layers whose names start with one of these hold named boundary segments (exits, "
                   "entrances), one group per layer.")
@click.option("--doors-layer", default="doors", show_default=True, metavar="PREFIX",
              help="DXF: layers whose names start with this hold interior doors (lines between rooms), one line "
                   "group per layer, named after it.")
@click.option("--exit", "exits", multiple=True, metavar="NAME=X0,Y0,X1,Y1",
              help="DXF and WKT plans: a named boundary segment on the outline (repeatable).")
@click.option("--no-exits", is_flag=True, help="Mesh a plan that has no exit (otherwise an error).")
def mesh(geometry, out, exit_size, size, units, wall_thickness, walls_layer, obstacles_layer, door_layers, doors_layer,
         exits, no_exits):
    """Mesh the floor plan GEOMETRY (.toml, .dxf or .wkt) with gmsh.

    A TOML floor plan gives the outer polygon, holes (polygons or circles),
    internal walls, named exit segments, named interior door lines and the
    cell size. A DXF drawing names them by layers: the outline and the
    internal walls on the walls layer, obstacles on theirs, exits and
    entrances on layers named exit*, entrance*, interior doors on layers
    named doors*; its units are its $INSUNITS or --units. A WKT file holds
    one POLYGON (JuPedSim's walkable area), its exits given with --exit. A
    plan must have an exit (--no-exits otherwise) and measure 1 m to 10 km
    across. The .msh has one boundary group per exit and entrance name, one
    line group per interior door name and "wall" for the rest, ready for a
    case (femcrowd new). Drawing a plan: docs/plans.md.

    \b
    Examples:
      femcrowd mesh meshes/room_one_door.toml
      femcrowd mesh plan.toml -o /tmp/plan.msh --exit-size 0.05
      femcrowd mesh plan.dxf --size 0.25 --units mm --walls-layer WALLS
      femcrowd mesh area.wkt --exit exit=10,2.5,10,3.5
    """
    from ..mesh import load_domain
    from ..mesh.floorplan import build_mesh

    cad = {"walls": walls_layer, "obstacles": obstacles_layer, "interior": doors_layer, "size": size, "units": units,
           "wall_thickness": wall_thickness, "doors": [p.strip() for p in door_layers.split(",") if p.strip()],
           "exits": [_segment(e) for e in exits]}
    path = build_mesh(geometry, out, exit_size, cad=cad, require_exits=not no_exits)
    stats = load_domain(path).statistics()
    groups = ", ".join(f"{name} {length:.3g} m" for name, length in stats["boundary_groups"].items())
    click.echo(f"wrote {path}: {stats['triangles']} triangles, h in [{stats['h_min']:.3g}, {stats['h_max']:.3g}] m, "
               f"min angle {stats['min_angle_deg']:.1f} deg; boundary groups: {groups}")
    click.echo(f"next: femcrowd new CASE_DIR --mesh {shlex.quote(str(path))}")


@main.command()
@click.argument("case_dir", type=click.Path())
@click.option("--mesh", "mesh_file", required=True, type=click.Path(), help="The gmsh .msh file of the scene.")
@click.option("--model", type=click.Choice(["recommended", "paper"]), default="recommended", show_default=True,
              help="recommended: the settings of docs/validation.md (rho_max 5.4 persons/m^2, Predtechenskii and "
                   "Milinskii's law at 1.67 m/s, the capacity of its width on every door); paper: the model of Maury "
                   "et al. (rho_max 1, constant speed, free exits).")
def new(case_dir, mesh_file, model):
    """Write a commented CASE_DIR/case.toml for the mesh FILE.msh.

    Exits are the mesh's boundary groups not named wall* nor entrance*; a
    group named entrance* becomes a [[sources]] entry (people arriving); a
    mesh without an exit gets U = 0 to edit. The settings are the
    recommended ones (every exit and interior line group gets the door
    capacity, by its name), or the paper's with --model paper; every other
    key is the default, with a comment. An existing case.toml is never
    overwritten.

    \b
    Example:
      femcrowd new cases/my-hall --mesh meshes/two_exits.msh
      femcrowd run cases/my-hall
    """
    from ..case.template import door_groups, new_case_file, write_new_case
    from ..mesh import load_domain

    file = new_case_file(case_dir)
    domain = load_domain(mesh_file, (), 0, case_file=file)
    write_new_case(file, mesh_file, domain, model)
    exits, entrances, _ = door_groups(domain)
    click.echo(f"wrote {file}; exits {', '.join(exits) or 'none'}; entrances {', '.join(entrances) or 'none'}")
    if not exits:
        click.echo("note: the mesh has no exit: the desired velocity is U = 0 until you give [velocity] ux, uy")
    click.echo(f"edit [initial] density, then: femcrowd run {shlex.quote(str(case_dir))}")


@main.command()
@click.argument("case_dir", type=click.Path())
@set_option
def info(case_dir, overrides):
    """Resolved configuration, people, mesh statistics and run estimate of a case.

    The configuration is TOML (defaults filled in, keys not set as comments).
    People at t = 0: in all and per population (macro: the integral of the
    initial density; micro: the discs). Mesh statistics: cells, edge lengths,
    angles, Delaunay check, boundary groups and their lengths. Estimate: time
    step, steps, frames, memory and files, the plan `femcrowd run` checks
    against its limits (a case beyond them is named with the line the run
    would stop with), and the wall time of `femcrowd run` on this machine:
    start-up and set-up as measured here, the run timed for up to 1.5 s and
    extrapolated to when it ends (the crowd out, or time.end). Nothing is
    written in the case.

    \b
    Examples:
      femcrowd info cases/room
      femcrowd info cases/room --set mesh.refine=2
    """
    from ..driver.estimate import case_info
    from ..driver.people import initial_people
    from ..timer import process_seconds

    case = load_case(case_dir, overrides)
    info = case_info(case, startup=process_seconds())
    if "over" not in info:   # a case beyond the limits is not set up (its discs not sampled)
        info.update(people=initial_people(case), sources=bool(case["sources"]))
    click.echo(format_info(info))


def _duration(seconds):
    return f"{seconds:.2g} s" if seconds < 60 else f"{seconds / 60:.2g} min"


def _config_toml(config) -> list:
    """The resolved configuration as TOML lines, indented: the top-level values first (TOML puts every key after
    a table header into that table), then one table per section; a key not set is a comment."""
    def line(key, value):
        return f"# {key}: not set" if value is None else f"{toml_key(key)} = {toml_value(value)}"
    tables = [(k, v) for k, v in config.items() if isinstance(v, dict)]
    lines = [f"  {line(k, v)}" for k, v in config.items() if not isinstance(v, dict)]
    for section, values in tables:
        lines += [f"  [{toml_key(section)}]", *(f"    {line(k, v)}" for k, v in values.items())]
    return lines


def _people(people, sources) -> str:
    """People at t = 0: total, per population, and the unit when it is not people."""
    fmt = "{:d}".format if isinstance(people["total"], int) else "{:.4g}".format
    text = f"people at t = 0: {fmt(people['total'])}"
    if people["unit"] != "people":
        text += f" {people['unit']}"
    if people["populations"]:
        text += " (" + ", ".join(f"{name} {fmt(n)}" for name, n in people["populations"].items()) + ")"
    if people["unit"] != "people":
        text += ("; with model.rho_max = 1 the densities are fractions of saturation (for a count of people, "
                 "give them in people/m^2 and rho_max = 5.4, say)")
    return text + ("; more arrive through [[sources]]" if sources else "")


def _count(n):
    return f"{n}" if isinstance(n, int) and n < 10 ** 9 else f"{n:.3g}"


def _bytes(n):
    return f"{n / 1e9:.3g} GB" if n >= 1e9 else f"{n / 1e6:.3g} MB"


def _mesh_lines(info) -> list:
    """The mesh statistics of `femcrowd info` (none for a mesh too large to be built)."""
    m = info.get("mesh")
    if m is None:
        return []
    lines = ["", "mesh:",
             f"  {m['triangles']} triangles, {m['nodes']} nodes, area {m['area']:.4g} m^2",
             f"  edge length h: min {m['h_min']:.3g} m, max {m['h_max']:.3g} m",
             f"  angles: min {m['min_angle_deg']:.1f} deg, max {m['max_angle_deg']:.1f} deg; "
             f"smallest cell {m['min_cell_area']:.3g} m^2",
             "  Delaunay: " + ("yes (all interior pairs)" if m["non_delaunay_pairs"] == 0 else
                               f"NO: {m['non_delaunay_pairs']} non-Delaunay pairs") +
             f"; {m['clipped_transmissibilities']} transmissibilities clipped to keep the M-matrix",
             "  boundary groups:"]
    for name, length in m["boundary_groups"].items():
        lines.append(f"    {name:<16} {length:9.4g} m   {'exit' if name in info['exits'] else 'wall'}")
    return lines


def _estimate_lines(e, end) -> list:
    """The run time of `femcrowd info` (driver/estimate.py) and what it is based on."""
    parts = (f"start-up {e['startup_seconds']:.2g} s, set-up {e['setup_seconds']:.2g} s, "
             f"run {_duration(e['loop_seconds'])}")
    if e["measured"]:
        based = f"the whole run timed here: {e['steps']} steps to t = {e['end_time']:.4g} s"
    else:
        ends = {"time.end": "time.end"}.get(e["end"], f"t = {e['end_time']:.4g} s, {e['end']}")
        based = (f"{e['prefix_steps']} steps to t = {e['prefix_time']:.3g} s timed here "
                 f"({_duration(e['prefix_seconds'])}), extrapolated to about {_count(round(e['steps']))} steps "
                 f"and their frames to {ends}")
    lines = [f"  run time of femcrowd run: about {_duration(e['seconds'])} ({parts})", f"    based on {based}"]
    if e.get("clog"):
        out = e["startup_seconds"] + e["setup_seconds"] + e["loop_seconds"]
        lines.append(f"    discs may clog at a door: {_duration(out)} if they do not, {_duration(e['seconds_to_end'])} "
                     f"if they stay until time.end = {end:g} s; the estimate is between the two")
    elif not e["measured"] and e["end"] != "time.end":
        lines.append(f"    if people stay until time.end = {end:g} s: about {_duration(e['seconds_to_end'])}")
    return lines


def format_info(info):
    """The report printed by ``femcrowd info``."""
    lines = [f"case: {info['case_file']}", "",
             "resolved configuration (TOML; defaults filled in, keys not set as comments):",
             *_config_toml(info["config"])]
    if "people" in info:
        lines += ["", _people(info["people"], info["sources"])]
    lines += _mesh_lines(info)
    p = info["plan"]
    lines += ["", "run estimate (the limits of femcrowd run: docs/tools.md, \"Limits\"):"]
    if "triangles" in p and "mesh" not in info:
        lines.append(f"  {_count(p['triangles'])} triangles after mesh.refine = {info['config']['mesh']['refine']}")
    if "discs" in p:
        lines.append(f"  {_count(p['discs'])} discs")
    if "steps" in p:
        lines += [f"  time step {p['dt']:.4g} s -> about {_count(p['steps'])} steps"
                  " (fewer if everybody has left before the end)",
                  f"  {_count(p['frames'])} frames, about {_bytes(p['disk'])} of files"]
    lines.append(f"  memory: about {_bytes(p['memory'])}")
    if "over" in info:
        lines.append(f"  beyond a limit: femcrowd run refuses it: {info['over']}")
    e = info.get("estimate")
    if e is not None:
        lines += _estimate_lines(e, info["config"]["time"]["end"])
    return "\n".join(lines)
    low, high = e["seconds"]
    lines += [f"  run time: {_duration(low)} (no congestion) to {_duration(high)} "
              f"(the initial crowd's {e['congested_cells']} cells congested at every step)",
              f"  measured here: {1e3 * e['free_step_seconds']:.3g} ms per free step, "
              f"{1e3 * e['congested_step_seconds']:.3g} ms per congested step, "
              f"{1e3 * e['frame_seconds']:.3g} ms per frame"]
    return "\n".join(lines)


@main.command()
@click.argument("outdir", type=click.Path())
@click.option("-t", "--times", "times", multiple=True, metavar="T[,T...]",
              help="Times (s) of the density and level-of-service maps, comma-separated or repeated; the nearest "
                   "frames are used. Default: 4 evenly spaced times until 95% of the crowd has left.")
@click.option("-o", "--out", type=click.Path(), help="The HTML file (default: OUTDIR/report.html).")
def report(outdir, times, out):
    """One self-contained HTML page of the run (or study) in OUTDIR, to hand in.

    Of a run: the scene (plan with the doors, their widths and capacities; the
    people; the settings and femcrowd's version), the evacuation time and the
    times at which 50, 90 and 99 % are out, the N-t curves, per door the people
    through, the mean and peak flow, the time at capacity and the longest queue,
    who is left and why, the density and level-of-service maps. Of a study
    (sweep, convergence, evacuation-times): the headline numbers of each run,
    their spread and change, the study's tables and figures. The figures are
    embedded: the page needs no other file and no network.

    \b
    Examples:
      femcrowd report cases/room/output
      femcrowd report /tmp/room --times 0,5,10 -o /tmp/room.html
    """
    from ..report import report as write_report

    click.echo(f"wrote {write_report(outdir, _times(times) or None, out)}")
