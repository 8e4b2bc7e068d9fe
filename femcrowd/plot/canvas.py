"""An offscreen top view of a floor plan with one coloured layer (pyvista, EGL: no display needed)."""

import os

import numpy as np

from ..files import replaced

os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")  # before vtk creates a window
import pyvista as pv  # noqa: E402

pv.OFF_SCREEN = True

BACKGROUND, TEXT = "white", "#202020"
WALL, EXIT, OBSTACLE, FLOOR = "#6e6e6e", "#00a651", "#bdbdbd", "#ebebe6"
CMAPS = {"density": "YlOrRd", "pressure": "PuBu"}
#: one colour map per population (density_<name> arrays), in the order of the case's tables
POPULATION_CMAPS = ("Blues", "Reds", "Greens", "Purples", "Oranges", "Greys")
PRESSURE_TITLE = "pressure p (m^2/s)"  # u = U - grad p: p has units of speed x length
DISC_PRESSURE_TITLE = "pressure: sum of contact multipliers (m/s)"  # u + B^T lambda = U


def _lines(segments, z):
    """Segments (n, 2, 2) as a PolyData of lines at height z."""
    n = len(segments)
    points = np.column_stack([segments.reshape(-1, 2), np.full(2 * n, z)])
    return pv.PolyData(points, lines=np.column_stack([np.full(n, 2), 2 * np.arange(n), 2 * np.arange(n) + 1]))


class Canvas:
    """An offscreen top view of the floor plan with one coloured layer, a colour bar and a title.

    Layout in pixels: title band on top, colour bar band at the bottom, the
    floor plan in between at a uniform scale (parallel projection).
    """

    TOP, BOTTOM, MARGIN = 70, 100, 24

    def __init__(self, bounds, walls, exits, labels, floor, width):
        (x0, x1), (y0, y1) = bounds
        dx, dy = max(x1 - x0, 1e-12), max(y1 - y0, 1e-12)
        scale = min((width - 2 * self.MARGIN) / dx, 0.8 * width / dy)  # pixels per metre
        height = int(round(dy * scale)) + self.TOP + self.BOTTOM + 2 * self.MARGIN
        height += height % 2  # even sizes keep video encoders happy
        self.width, self.height = width, height
        self.plotter = p = pv.Plotter(off_screen=True, window_size=(width, height))
        p.set_background(BACKGROUND)
        size = max(dx, dy)
        if floor is not None:
            # under-plate: the bounding box in light grey, seen through the holes (obstacles);
            # the floor on it is seen where no coloured layer covers it (discs)
            plate = pv.Plane(center=((x0 + x1) / 2, (y0 + y1) / 2, -1e-3 * size), direction=(0, 0, 1),
                             i_size=dx, j_size=dy, i_resolution=1, j_resolution=1)
            p.add_mesh(plate, color=OBSTACLE, lighting=False)
            p.add_mesh(floor.translate((0, 0, -5e-4 * size)), color=FLOOR, lighting=False)
        self.scale, self.size, self.boundary, self.drawn = scale, size, [], None
        self.doors(walls, exits, labels)
        self._scale_bar(x0, y0 - (self.MARGIN + 40) / scale, width)
        self.text = p.add_text("", position=(self.MARGIN, height - self.TOP + 6), font_size=max(10, width // 75),
                               color=TEXT)
        self.layer = self.outline = self.legend = None
        camera = p.camera
        camera.parallel_projection = True
        world_height = height / scale
        centre_y = (y0 + y1) / 2 + (height / 2 - (self.BOTTOM + self.MARGIN + dy * scale / 2)) / scale
        camera.focal_point = ((x0 + x1) / 2, centre_y, 0.0)
        camera.position = ((x0 + x1) / 2, centre_y, 10 * size)
        camera.up = (0, 1, 0)
        camera.parallel_scale = world_height / 2
        p.renderer.ResetCameraClippingRange()

    def _scale_bar(self, left, y, width):
        """A map's scale: a bar of a round length (1, 2 or 5 x 10^k m, at most 0.15 of the picture's width) in the
        bottom band left of the colour bar, from below the plan's left edge, labelled with its length."""
        target = 0.15 * width / self.scale
        unit = 10.0 ** np.floor(np.log10(target))
        length = max(m * unit for m in (1, 2, 5) if m * unit <= target)
        z = 3e-3 * self.size
        tick = 5 / self.scale
        right = left + length
        bar = np.array([[[left, y], [right, y]], [[left, y - tick], [left, y + tick]],
                        [[right, y - tick], [right, y + tick]]])
        self.plotter.add_mesh(_lines(bar, z), color=TEXT, line_width=2, lighting=False)
        self.plotter.add_point_labels([[left + length / 2, y + 4 / self.scale, z]], [f"{length:g} m"],
                                      font_size=max(12, width // 60), text_color=TEXT, shape=None,
                                      show_points=False, always_visible=True, justification_horizontal="center",
                                      justification_vertical="bottom")

    def captions(self, points, texts):
        """Texts centred below points of the plan (the floors of a building under their panels)."""
        self.plotter.add_point_labels([[x, y - 6 / self.scale, 3e-3 * self.size] for x, y in points], texts,
                                      font_size=max(10, self.width // 70), text_color=TEXT, shape=None,
                                      show_points=False, always_visible=True, justification_horizontal="center",
                                      justification_vertical="top")

    def doors(self, walls, exits, labels):
        """Draw walls (grey) and exits (green), replacing those drawn before unless the labels are the same: closed
        doors are walls (their facets are among ``walls``); labels [(name, midpoint, outward normal)] name the
        exits when there are several."""
        drawn = [label[0] for label in labels]   # the names say which exits are closed
        if self.boundary and drawn == self.drawn:
            return
        self.drawn = drawn
        p, width, scale, size = self.plotter, self.width, self.scale, self.size
        for actor in self.boundary:
            p.remove_actor(actor)
        self.boundary = []
        for segments, colour, z, line in [(walls, WALL, 1e-3, width / 300), (exits, EXIT, 2e-3, width / 120)]:
            if len(segments):  # tubes: round joints, no gaps between segments
                self.boundary.append(p.add_mesh(_lines(segments, z * size), color=colour, line_width=max(2, line),
                                                render_lines_as_tubes=True, lighting=False))
        for name, middle, normal in labels if len(labels) > 1 else ():  # name the exits when there are several
            inward = middle - normal * 14 / scale
            across = abs(normal[0]) > abs(normal[1])
            self.boundary.append(p.add_point_labels(
                [[*inward, 3e-3 * size]], [name], font_size=max(8, width // 60), text_color=EXIT,
                bold=True, shape=None, background_color="white", background_opacity=0.8,
                show_points=False, always_visible=True,
                justification_horizontal=("right" if normal[0] > 0 else "left") if across else "center",
                justification_vertical="center" if across else ("top" if normal[1] > 0 else "bottom")))

    def show(self, mesh, name, clim, cmap, bar_title):
        """Colour ``mesh`` by its array ``name`` (first call adds the layer, later calls replace its data)."""
        if self.layer is None:
            w, h, bar_height = self.width, self.height, 50
            bar = dict(title=bar_title, vertical=False, n_labels=tick_count(clim[1]), fmt="%.3g", color=TEXT,
                       position_x=0.2, width=0.6, position_y=8 / h, height=bar_height / h,
                       label_font_size=max(10, w // 45), unconstrained_font_size=True)
            self.layer = self.plotter.add_mesh(mesh, scalars=name, clim=clim, cmap=cmap, lighting=False,
                                               scalar_bar_args=bar, interpolate_before_map=False)
            # VTK lays the bar title over the labels: labels go below the bar, the title is our own text
            scalar_bar = self.plotter.scalar_bars[bar_title]
            scalar_bar.SetTitle("")
            scalar_bar.SetTextPositionToPrecedeScalarBar()
            scalar_bar.SetBarRatio(0.45)
            title = self.plotter.add_text(bar_title, position=(w / 2, 8 + bar_height + 6),
                                          font_size=max(9, w // 90), color=TEXT)
            title.prop.justification_horizontal = "center"
        else:
            self.layer.mapper.dataset = mesh
            self.layer.mapper.SetScalarRange(*clim)

    def show_populations(self, mesh, names, top, bar_title):
        """Colour each cell by its populations, each in its own colour map (POPULATION_CMAPS) at its own
        density in [0, top], mixed in proportion to their shares of the cell's density (empty cells show the
        floor); one colour bar per population. First call adds the layers, later calls replace the data."""
        import matplotlib

        rho = np.column_stack([np.asarray(mesh.cell_data[f"density_{name}"], float) for name in names])
        total = rho.sum(axis=1)
        share = np.divide(rho, total[:, None], out=np.zeros_like(rho), where=total[:, None] > 0)
        colour = sum(share[:, [k]] * matplotlib.colormaps[POPULATION_CMAPS[k % len(POPULATION_CMAPS)]](
            np.clip(rho[:, k] / top, 0, 1))[:, :3] for k in range(len(names)))
        shown = mesh.extract_cells(np.flatnonzero(total > 1e-3 * top))
        shown.cell_data["rgb"] = np.round(255 * colour[shown.cell_data["vtkOriginalCellIds"]]).astype(np.uint8)
        if self.layer is not None:
            self.plotter.remove_actor(self.layer)
        self.layer = self.plotter.add_mesh(shown, scalars="rgb", rgb=True, lighting=False) if shown.n_cells else None
        if self.outline is None:  # the colour bars, once: hidden layers that only carry a colour map each
            w, h, bar_height = self.width, self.height, 50
            self.outline = []
            for k, name in enumerate(names):
                width = 0.8 / len(names)
                bar = dict(title=f"{name}: {bar_title}", vertical=False, n_labels=tick_count(top), fmt="%.3g",
                           color=TEXT, position_x=0.1 + k * width + 0.1 * width, width=0.8 * width,
                           position_y=8 / h, height=bar_height / h, label_font_size=max(10, w // 60),
                           unconstrained_font_size=True)
                hidden = self.plotter.add_mesh(mesh, scalars=f"density_{name}", clim=(0, top), lighting=False,
                                               cmap=POPULATION_CMAPS[k % len(POPULATION_CMAPS)], scalar_bar_args=bar)
                hidden.SetVisibility(False)
                scalar_bar = self.plotter.scalar_bars[bar["title"]]   # labels below the bar, our title above
                scalar_bar.SetTitle("")
                scalar_bar.SetTextPositionToPrecedeScalarBar()
                scalar_bar.SetBarRatio(0.45)
                title = self.plotter.add_text(bar["title"], position=(w * (bar["position_x"] + bar["width"] / 2),
                                                                      8 + bar_height + 6),
                                              font_size=max(9, w // 90), color=TEXT)
                title.prop.justification_horizontal = "center"
                self.outline.append(hidden)

    def show_disc_populations(self, frame, names):
        """Discs of a micro frame coloured by their population (a colour of POPULATION_CMAPS each, a legend)."""
        import matplotlib

        for actor in (self.layer, self.outline):
            if actor is not None:
                self.plotter.remove_actor(actor)
        self.layer = self.outline = None
        colours = np.array([matplotlib.colormaps[POPULATION_CMAPS[k % len(POPULATION_CMAPS)]](0.75)[:3]
                            for k in range(len(names))])
        if self.legend is None:
            # in the bottom band, below the floor plan (no colour bar here): it never covers a door
            self.legend = self.plotter.add_legend([[name, tuple(c)] for name, c in zip(names, colours)],
                                                  bcolor="white", loc=None, face="circle")
            tall, wide = min(self.BOTTOM - 10, 14 + 20 * len(names)), 0.12 + 0.08 * len(names)
            self.legend.SetPosition(0.5 - wide / 2, 8 / self.height)
            self.legend.SetPosition2(wide, tall / self.height)
        if not frame.n_points:
            return
        fill, outline = disc_glyphs(frame)
        fill.point_data["rgb"] = np.round(255 * colours[fill.point_data["population"].astype(int)]).astype(np.uint8)
        self.layer = self.plotter.add_mesh(fill, scalars="rgb", rgb=True, lighting=False)
        self.outline = self.plotter.add_mesh(outline, color=TEXT, line_width=1, lighting=False)

    def show_discs(self, frame, clim):
        """Discs of a micro frame coloured by their pressure, with outlines (none: the room is empty)."""
        if self.outline is not None:
            self.plotter.remove_actor(self.outline)
            self.outline = None
        if not frame.n_points:
            if self.layer is not None:
                self.layer.SetVisibility(False)
            return
        fill, outline = disc_glyphs(frame)
        self.show(fill, "pressure", clim, CMAPS["pressure"], DISC_PRESSURE_TITLE)
        self.layer.SetVisibility(True)
        self.outline = self.plotter.add_mesh(outline, color=TEXT, line_width=1, lighting=False)

    def title(self, text):
        self.text.input = text

    def image(self):
        self.plotter.render()
        return self.plotter.screenshot(return_img=True)

    def save(self, path):
        """The picture as a PNG, whole or not at all (files.replaced)."""
        self.plotter.render()
        with replaced(path) as tmp:
            self.plotter.screenshot(str(tmp))

    def close(self):
        self.plotter.close()


#: colour-bar maxima (mantissa) and their number of round intervals
NICE = ((1, 4), (1.2, 4), (1.5, 3), (2, 4), (2.5, 5), (3, 3), (4, 4), (5, 5), (6, 3), (8, 4), (10, 4))


def nice_top(value):
    """The smallest colour-bar maximum >= value with round ticks (1, 1.2, 1.5, 2, 2.5, ... x 10^k)."""
    if not value > 0:
        return 1.0
    unit = 10.0 ** np.floor(np.log10(value))
    return next(m * unit for m, _ in NICE if m * unit >= value * (1 - 1e-12))


def tick_count(top):
    """Number of colour-bar labels on [0, top]: round steps when top is a nice number, else 5."""
    mantissa = top / 10.0 ** np.floor(np.log10(top))
    return next((n + 1 for m, n in NICE if np.isclose(mantissa, m)), 5)


def bounds(points):
    return (points[:, 0].min(), points[:, 0].max()), (points[:, 1].min(), points[:, 1].max())


def disc_glyphs(frame):
    """Disc fill (coloured by pressure) and outlines as glyphs of a unit polygon scaled by the radius."""
    centres = pv.PolyData(np.asarray(frame.points, float))
    for name in ("radius", "pressure", "population"):
        centres.point_data[name] = (np.asarray(frame.point_data[name], float) if name in frame.point_data
                                    else np.zeros(frame.n_points))
    unit = pv.Polygon(center=(0, 0, 0), radius=1.0, normal=(0, 0, 1), n_sides=24)
    fill = centres.glyph(geom=unit.triangulate(), scale="radius", orient=False, factor=1.0)
    outline = centres.glyph(geom=unit.extract_feature_edges(), scale="radius", orient=False, factor=1.0)
    return fill, outline
