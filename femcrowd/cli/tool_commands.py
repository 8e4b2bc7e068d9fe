"""``femcrowd plot``, ``mesh``, ``new`` and ``info``: looking at results, making scenes."""

import shlex
from pathlib import Path

import click

from ..case import load_case
from ..case.template import toml_value
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
@click.option("--walls-layer", default="walls", show_default=True, help="DXF: the layer of the outline.")
@click.option("--obstacles-layer", default="obstacles", show_default=True, help="DXF: the layer of the obstacles.")
@click.option("--door-layers", default="exit,entrance", show_default=True, metavar="PREFIX[,PREFIX...]",
              help="DXF: layers whose names start with one of these hold named boundary segments (exits, "
                   "entrances), one group per layer.")
@click.option("--exit", "exits", multiple=True, metavar="NAME=X0,Y0,X1,Y1",
              help="DXF and WKT plans: a named boundary segment on the outline (repeatable).")
def mesh(geometry, out, exit_size, size, walls_layer, obstacles_layer, door_layers, exits):
    """Mesh the floor plan GEOMETRY (.toml, .dxf or .wkt) with gmsh.

    A TOML floor plan gives the outer polygon, holes (polygons or circles),
    named exit segments, named interior door lines ([[doors]]: a door between
    two rooms, for a capacity) and the cell size (format:
    femcrowd/mesh/plan.py and the shipped meshes/*.toml). A DXF drawing names them by layers:
    the outline on the walls layer, obstacles on theirs, exits and
    entrances on layers named exit*, entrance* (closed polylines, lines,
    arcs, circles). A WKT file holds one POLYGON (JuPedSim's walkable
    area), its exits given with --exit. The .msh has one boundary group
    per exit name and "wall" for the rest, ready for a case (femcrowd new).

    \b
    Examples:
      femcrowd mesh meshes/room_one_door.toml
      femcrowd mesh plan.toml -o /tmp/plan.msh --exit-size 0.05
      femcrowd mesh plan.dxf --size 0.25 --walls-layer WALLS
      femcrowd mesh area.wkt --exit exit=10,2.5,10,3.5
    """
    from ..mesh import load_domain
    from ..mesh.floorplan import build_mesh

    cad = {"walls": walls_layer, "obstacles": obstacles_layer, "size": size,
           "doors": [p.strip() for p in door_layers.split(",") if p.strip()], "exits": [_segment(e) for e in exits]}
    path = build_mesh(geometry, out, exit_size, cad=cad)
    stats = load_domain(path).statistics()
    groups = ", ".join(f"{name} {length:.3g} m" for name, length in stats["boundary_groups"].items())
    click.echo(f"wrote {path}: {stats['triangles']} triangles, h in [{stats['h_min']:.3g}, {stats['h_max']:.3g}] m, "
               f"min angle {stats['min_angle_deg']:.1f} deg; boundary groups: {groups}")
    click.echo(f"next: femcrowd new CASE_DIR --mesh {shlex.quote(str(path))}")


@main.command()
@click.argument("case_dir", type=click.Path())
@click.option("--mesh", "mesh_file", required=True, type=click.Path(), help="The gmsh .msh file of the scene.")
def new(case_dir, mesh_file):
    """Write a commented CASE_DIR/case.toml for the mesh FILE.msh.

    Exits are the mesh's boundary groups not named wall*; every other key is
    the default, with a comment. An existing case.toml is never overwritten.

    \b
    Example:
      femcrowd new cases/my-hall --mesh meshes/two_exits.msh
      femcrowd run cases/my-hall
    """
    from ..case.template import new_case_file, write_new_case
    from ..mesh import load_domain

    file = new_case_file(case_dir)
    write_new_case(file, mesh_file, load_domain(mesh_file, (), 0, case_file=file))
    click.echo(f"wrote {file}; edit [initial] density, then: femcrowd run {shlex.quote(str(case_dir))}")


@main.command()
@click.argument("case_dir", type=click.Path())
@set_option
def info(case_dir, overrides):
    """Resolved configuration, mesh statistics and run estimate of a case.

    Mesh statistics: cells, edge lengths, angles, Delaunay check, boundary
    groups and their lengths. Estimate: number of time steps and a run-time
    range measured from a few steps on this machine (below 1 s for the
    shipped cases). Nothing is written.

    \b
    Examples:
      femcrowd info cases/room
      femcrowd info cases/room --set mesh.refine=2
    """
    from ..driver.estimate import case_info

    click.echo(format_info(case_info(load_case(case_dir, overrides))))


def _duration(seconds):
    return f"{seconds:.2g} s" if seconds < 60 else f"{seconds / 60:.2g} min"


def format_info(info):
    """The report printed by ``femcrowd info``."""
    lines = [f"case: {info['case_file']}", "", "resolved configuration (defaults filled in):"]
    for section, values in info["config"].items():
        if not isinstance(values, dict):
            lines.append(f"  {section} = {toml_value(values)}")
            continue
        lines.append(f"  [{section}]")
        lines += [f"    {k} = {'(not set)' if v is None else toml_value(v)}" for k, v in values.items()]
    m = info["mesh"]
    lines += ["", "mesh:",
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
    e = info.get("estimate")
    if e is None:
        lines += ["", "run estimate: macro cases only"]
        return "\n".join(lines)
    low, high = e["seconds"]
    lines += ["", "run estimate:",
              f"  time step {e['dt']:.4g} s -> about {e['steps']} steps"
              " (fewer if everybody has left before the end)",
              f"  {e['frames']} frames",
              f"  run time: {_duration(low)} (no congestion) to {_duration(high)} "
              f"(the initial crowd's {e['congested_cells']} cells congested at every step)",
              f"  measured here: {1e3 * e['free_step_seconds']:.3g} ms per free step, "
              f"{1e3 * e['congested_step_seconds']:.3g} ms per congested step, "
              f"{1e3 * e['frame_seconds']:.3g} ms per frame"]
    return "\n".join(lines)
