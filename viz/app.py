"""The viser scene and GUI of one run directory.

``serve(run_dir, host, port)`` loads the run, starts a viser server (its own threads),
builds the scene and returns a :class:`Viewer` at once; ``Viewer.stop()`` shuts it down.
All drawing data is loaded and decimated up front, so GUI callbacks only index arrays
and a 60 s, 500 Hz log costs no more per frame than a short one.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import quat_wxyz_from_euler, rotation_from_euler
from viz.geometry import VisualPart, body_radius, default_scale, vehicle_parts
from viz.run import CycleRecord, Flight, Run, decimate_indices, load_run

if TYPE_CHECKING:
    import viser

Array = NDArray[np.float64]

TRUTH_RGB = (25, 140, 60)
ESTIMATE_RGB = (235, 110, 20)
WAYPOINT_RGB = (120, 60, 200)
START_RGB = (110, 110, 110)
TRUTH_CSS = "#198c3c"
ESTIMATE_CSS = "#eb6e14"
AXIS_CSS = ("#d6336c", "#1c7ed6", "#7048e8")

MAX_LINE_POINTS = 2000
"""Vertices per drawn trajectory; more adds nothing visible and slows the browser."""
MAX_PLOT_POINTS = 2000
"""Samples per parameter-history series (online runs may have thousands of updates)."""
FRAME_RATE = 30.0
"""Playback updates per second of wall time."""
PATH_CHOICES = ("truth and estimate", "truth", "estimate", "none")
SPEEDS = ("0.1x", "0.25x", "0.5x", "1x", "2x", "4x", "8x")
MAX_FIGURE_WIDTH = 1400
"""Figures wider than this are subsampled before sending: the panel is narrower."""


@dataclass(frozen=True)
class SceneBounds:
    """Axis-aligned box [m] around everything drawn; frames the camera and the floor."""

    low: Array
    high: Array

    @property
    def center(self) -> Array:
        return 0.5 * (self.low + self.high)

    @property
    def radius(self) -> float:
        return max(0.5 * float(np.linalg.norm(self.high - self.low)), 0.5)


def _bounds(run: Run, margin: float) -> SceneBounds:
    """Box around the flights, waypoints and start, grown by ``margin`` [m] (the drawn
    vehicle's reach) so a vehicle at the edge stays in view."""
    pts = []
    for f in run.flights:
        for arr in (f.true_pos, f.est_pos):
            if arr is not None:
                pts.append(arr[np.isfinite(arr).all(axis=1)])
    if run.waypoints is not None:
        pts.append(run.waypoints)
    if run.start is not None:
        pts.append(run.start[None, :])
    allp = np.concatenate(pts) if pts else np.zeros((1, 3))
    if allp.size == 0:
        allp = np.zeros((1, 3))
    return SceneBounds(low=allp.min(axis=0) - margin, high=allp.max(axis=0) + margin)


def _segments(points: Array, rgb: tuple[int, int, int], dash: int = 0
              ) -> tuple[Array, NDArray[np.uint8]]:
    """Polyline (M, 3) as viser line segments (K, 2, 3) with per-vertex colours.

    dash > 0 keeps alternate runs of ``dash`` segments: a dashed line, so the estimate
    stays readable where it lies on top of the true path.
    """
    pts = points[np.isfinite(points).all(axis=1)]
    if pts.shape[0] < 2:
        pts = np.repeat(pts[:1] if pts.size else np.zeros((1, 3)), 2, axis=0)
    segs = np.stack([pts[:-1], pts[1:]], axis=1).astype(np.float32)
    if dash > 0 and segs.shape[0] > 2 * dash:
        segs = segs[(np.arange(segs.shape[0]) // dash) % 2 == 0]
    colors = np.broadcast_to(_linear_rgb(rgb), segs.shape).copy()
    return segs, colors


def _linear_rgb(rgb: tuple[int, int, int]) -> NDArray[np.uint8]:
    """sRGB colour as the linear value viser's line shader expects: its vertex colours
    skip the sRGB decoding meshes get, so without this lines look washed out."""
    c = np.asarray(rgb, dtype=float) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return np.round(255.0 * lin).astype(np.uint8)


def _nice_step(flight: Flight) -> float:
    """Slider step: the log's sample interval, coarsened so the slider has at most a
    few thousand positions, rounded to a power of ten for readable values."""
    dt = float(np.median(np.diff(flight.t))) if flight.t.shape[0] > 1 else 0.01
    raw = max(dt, flight.duration / 5000.0, 1e-4)
    return 10.0 ** math.floor(math.log10(raw))


def _read_png(path: Path) -> NDArray[np.uint8] | None:
    """RGB image of a PNG file, or None if it cannot be read."""
    try:
        import imageio.v3 as iio

        img = np.asarray(iio.imread(path))
    except Exception:  # imageio raises many types for damaged files; skip the figure
        return None
    if img.dtype != np.uint8:
        img = (np.clip(img.astype(float) / (np.iinfo(img.dtype).max if img.dtype.kind in "ui"
                                            else 1.0), 0, 1) * 255).astype(np.uint8)
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    if img.shape[2] == 4:
        # Composite on white: matplotlib figures may be transparent.
        alpha = img[:, :, 3:4].astype(float) / 255.0
        img = (img[:, :, :3] * alpha + 255.0 * (1.0 - alpha)).astype(np.uint8)
    step = int(math.ceil(img.shape[1] / MAX_FIGURE_WIDTH))
    return np.ascontiguousarray(img[::step, ::step, :3])


def _fmt_pct(est: float, truth: float | None) -> str:
    if truth is None or truth == 0:
        return "-"
    return f"{100.0 * (est - truth) / truth:+.2f} %"


class Viewer:
    """A running browser view of one run: the viser server plus its scene and GUI
    handles. Build it with :func:`serve`; ``set_time`` / ``select`` drive it from code
    (tests) exactly as the GUI does."""

    def __init__(self, run: Run, server: viser.ViserServer, scale: float | None = None
                 ) -> None:
        self.run = run
        self.server = server
        urdf = _urdf_for(run.vehicle)
        self.parts = vehicle_parts(urdf)
        path_bounds = _bounds(run, 0.0)
        self.scale = float(scale) if scale else default_scale(
            run.vehicle, self.parts, path_bounds.radius)
        self.bounds = _bounds(run, self.scale * body_radius(self.parts))
        # Simulated flights start on the floor at z = 0; a log may sit lower.
        self.floor_z = min(0.0, float(path_bounds.low[2]))
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._playing = False
        self._flight: Flight | None = None
        self._cycle: CycleRecord | None = None
        self._quiet = False  # set while code changes controls, so callbacks do not cascade

        self._build_scene()
        self._build_gui()
        self._select_sensor(self.sensor_dropdown.value if self.sensor_dropdown else None)
        self._player = threading.Thread(target=self._play_loop, name="viz-playback",
                                        daemon=True)
        self._player.start()

    # --------------------------------------------------------------------- properties

    @property
    def url(self) -> str:
        """Address a browser opens (loopback name when bound to all interfaces)."""
        host = self.server.get_host()
        if host in ("0.0.0.0", "::", ""):
            host = "127.0.0.1"
        return f"http://{host}:{self.server.get_port()}"

    @property
    def flight(self) -> Flight | None:
        """The flight currently drawn."""
        return self._flight

    # ----------------------------------------------------------------------- building

    def _build_scene(self) -> None:
        scene = self.server.scene
        scene.set_up_direction("+z")
        b = self.bounds
        floor_z = self.floor_z
        size = np.ceil(b.high[:2] - b.low[:2] + 2.0)
        scene.add_grid("/floor", width=float(size[0]), height=float(size[1]), plane="xy",
                       cell_size=0.5, section_size=1.0,
                       position=(float(b.center[0]), float(b.center[1]), floor_z))
        marker = float(np.clip(0.02 * b.radius, 0.04, 0.2))
        if self.run.waypoints is not None:
            for i, wp in enumerate(self.run.waypoints):
                scene.add_icosphere(f"/waypoints/w{i + 1}", radius=marker, color=WAYPOINT_RGB,
                                    position=tuple(wp), cast_shadow=False)
                scene.add_label(f"/waypoints/w{i + 1}/label", f"W{i + 1}",
                                position=(0.0, 0.0, 2.0 * marker))
        if self.run.start is not None:
            scene.add_icosphere("/waypoints/start", radius=marker, color=START_RGB,
                                position=tuple(self.run.start), cast_shadow=False)
            scene.add_label("/waypoints/start/label", "start", position=(0.0, 0.0, 2.0 * marker))

        # Each flight's lines are added once and toggled, so switching sensors is instant.
        self._lines: dict[str, tuple[viser.LineSegmentsHandle | None,
                                     viser.LineSegmentsHandle | None]] = {}
        for f in self.run.flights:
            idx = decimate_indices(f.t.shape[0], MAX_LINE_POINTS)
            truth = est = None
            if f.true_pos is not None:
                segs, cols = _segments(f.true_pos[idx], TRUTH_RGB)
                truth = scene.add_line_segments(f"/flights/{f.name}/truth", segs, cols,
                                                thickness=3.0, thickness_units="screen",
                                                visible=False)
            if f.est_pos is not None:
                segs, cols = _segments(f.est_pos[idx], ESTIMATE_RGB,
                                       dash=max(idx.shape[0] // 300, 1))
                est = scene.add_line_segments(f"/flights/{f.name}/estimate", segs, cols,
                                              thickness=6.0, thickness_units="screen",
                                              visible=False)
            self._lines[f.name] = (truth, est)

        self.vehicle = self._add_vehicle("/vehicle", opacity=None)
        self.ghost = self._add_vehicle("/ghost", opacity=0.3)
        self.ghost.visible = False
        if self.run.start is not None:
            self.vehicle.position = tuple(self.run.start)

        cam = self.server.initial_camera
        cam.fov = math.radians(50.0)
        # From -x, -y and above: scenarios spread towards +x, +y, so nothing hides.
        direction = np.array([-0.55, -1.0, 0.65])
        direction /= np.linalg.norm(direction)
        # Aim right of the centre so the scene sits left of the control panel.
        right = np.cross(-direction, np.array([0.0, 0.0, 1.0]))
        right /= np.linalg.norm(right)
        look_at = b.center + b.radius * (0.35 * right - np.array([0.0, 0.0, 0.2]))
        cam.look_at = tuple(look_at)
        cam.position = tuple(look_at + direction * 2.0 * b.radius)
        cam.up = (0.0, 0.0, 1.0)

    def _add_vehicle(self, name: str, opacity: float | None) -> viser.FrameHandle:
        """The URDF's primitives, magnified by the display scale, under one frame.

        viser's node ``scale`` does not reach child nodes, so each part's size and
        offset are scaled here instead.
        """
        scene = self.server.scene
        k = self.scale
        reach = k * body_radius(self.parts)
        frame = scene.add_frame(name, show_axes=True, axes_length=0.5 * reach,
                                axes_radius=0.025 * reach, origin_radius=0.03 * reach)
        for p in self.parts:
            self._add_part(f"{name}/{p.name}", p, opacity)
        return frame

    def _add_part(self, name: str, p: VisualPart, opacity: float | None) -> None:
        scene = self.server.scene
        k = self.scale
        alpha = opacity if opacity is not None else (p.opacity if p.opacity < 1.0 else None)
        kw = dict(color=p.rgb, opacity=alpha, wxyz=tuple(p.wxyz),
                  position=tuple(k * p.position), cast_shadow=opacity is None)
        if p.kind == "box":
            scene.add_box(name, dimensions=tuple(k * np.asarray(p.dims)), **kw)
        elif p.kind == "cylinder":
            scene.add_cylinder(name, radius=k * p.dims[0], height=k * p.dims[1], **kw)
        else:
            scene.add_icosphere(name, radius=k * p.dims[0], **kw)

    def _build_gui(self) -> None:
        gui = self.server.gui
        run = self.run
        gui.configure_theme(control_width="large", show_share_button=False)
        legend = []
        if any(f.true_pos is not None for f in run.flights):
            legend.append(f"<span style='color:{TRUTH_CSS}'>&#9644;</span> true path")
        if any(f.est_pos is not None for f in run.flights):
            legend.append(f"<span style='color:{ESTIMATE_CSS}'>&#9644;</span> estimated path "
                          "(dashed)")
        gui.add_markdown(
            f"**{run.path.name}** &middot; {run.kind} run &middot; vehicle `{run.vehicle}` "
            f"(drawn x{self.scale:.3g})  \n" + " &nbsp; ".join(legend))

        sensors = list(run.sensors)
        self.sensor_dropdown = self.cycle_dropdown = self.mstep_dropdown = None
        with gui.add_folder("Data"):
            if sensors:
                self.sensor_dropdown = gui.add_dropdown(
                    "Sensor", sensors, initial_value=sensors[0],
                    hint="Observation source: selects the flight drawn and the histories plotted")
                self.cycle_dropdown = gui.add_dropdown("Cycle", ["-"],
                                                       hint="Monte Carlo cycle of the plots")
                self.mstep_dropdown = gui.add_dropdown("M-step", ["-"])
                self.sensor_dropdown.on_update(lambda _: self._guarded(
                    lambda: self._select_sensor(self.sensor_dropdown.value)))
                self.cycle_dropdown.on_update(lambda _: self._guarded(self._select_cycle))
                self.mstep_dropdown.on_update(lambda _: self._guarded(self._select_cycle))
            self.paths_dropdown = gui.add_dropdown(
                "Paths", PATH_CHOICES, initial_value=PATH_CHOICES[0],
                hint="Which trajectories to draw (the estimate is dashed)")
            self.paths_dropdown.on_update(lambda _: self._update_path_visibility())
            self.flight_note = gui.add_markdown("")

        with gui.add_folder("Playback"):
            self.time_slider = gui.add_slider("Time [s]", min=0.0, max=1.0, step=0.01,
                                              initial_value=0.0)
            self.play_button = gui.add_button("Play", icon=None,
                                              hint="Play or pause the flight")
            self.speed_dropdown = gui.add_dropdown("Speed", SPEEDS, initial_value="1x")
            self.pose_dropdown = gui.add_dropdown(
                "Vehicle pose", ("truth", "estimate"), initial_value="truth",
                hint="Pose the vehicle by the simulator's truth or by the smoothed estimate")
            self.ghost_checkbox = gui.add_checkbox(
                "Ghost of the other pose", False,
                hint="Also draw the other pose, translucent")
            self.status = gui.add_markdown("")
            self.time_slider.on_update(lambda _: self.set_time(self.time_slider.value))
            self.play_button.on_click(lambda _: self.set_playing(not self._playing))
            self.pose_dropdown.on_update(lambda _: self.set_time(self.time_slider.value))
            self.ghost_checkbox.on_update(lambda _: self.set_time(self.time_slider.value))

        with gui.add_folder("Parameters"):
            self.param_table = gui.add_markdown("")
            self.mass_plot = None
            self.inertia_plot = None
            if run.cycles:
                self._add_plots(run.cycles[0])

        disc = run.discovery
        self.discovery_text = None
        self.discovery_images = []
        if disc is not None and (disc.selected or disc.rms_before or disc.figures):
            with gui.add_folder("Effect discovery"):
                self.discovery_text = gui.add_markdown(_discovery_markdown(disc))
                for fig in disc.figures:
                    img = _read_png(fig)
                    if img is not None:
                        self.discovery_images.append(
                            gui.add_image(img, label=fig.name, format="png"))

        if run.figures:
            with gui.add_folder("Run figures", expand_by_default=False):
                names = [f.name for f in run.figures]
                choice = gui.add_dropdown("Figure", names, initial_value=names[0])
                first = _read_png(run.figures[0])
                image = gui.add_image(first if first is not None else np.full((8, 8, 3), 255,
                                      np.uint8), format="png")

                def show_figure(_) -> None:
                    img = _read_png(run.path / "figures" / choice.value)
                    if img is not None:
                        image.image = img
                choice.on_update(show_figure)

        if run.warnings:
            with gui.add_folder("Warnings", expand_by_default=False):
                gui.add_markdown("\n".join(f"- {w}" for w in run.warnings))

    def _add_plots(self, rec: CycleRecord) -> None:
        from viser import uplot

        gui = self.server.gui
        d = _plot_data(rec)
        xs: uplot.Series = {"label": rec.x_label}
        mass_series: list[uplot.Series] = [xs, {"label": "mass", "stroke": ESTIMATE_CSS,
                                                "width": 2}]
        if d.true_mass is not None:
            mass_series.append({"label": "true", "stroke": TRUTH_CSS, "width": 1.5,
                                "dash": (6.0, 4.0)})
        self.mass_plot = gui.add_uplot(d.mass_columns(), tuple(mass_series),
                                       title="mass [g]", scales=d.mass_scales(), aspect=2.2)
        in_series: list[uplot.Series] = [xs]
        for k, axis in enumerate(("xx", "yy", "zz")):
            in_series.append({"label": f"I{axis}", "stroke": AXIS_CSS[k], "width": 2})
        if d.true_inertia is not None:
            for k, axis in enumerate(("xx", "yy", "zz")):
                in_series.append({"label": f"true I{axis}", "stroke": AXIS_CSS[k],
                                  "width": 1.2, "dash": (6.0, 4.0)})
        self.inertia_plot = gui.add_uplot(d.inertia_columns(), tuple(in_series),
                                          title="inertia diagonal [1e-6 kg m²]",
                                          scales=d.inertia_scales(), aspect=1.8)

    # ------------------------------------------------------------------------ control

    def _guarded(self, action) -> None:
        if not self._quiet:
            action()

    def _cycles_of(self, sensor: str | None) -> list[CycleRecord]:
        return [c for c in self.run.cycles if c.sensor == sensor] or list(self.run.cycles)

    def _select_sensor(self, sensor: str | None) -> None:
        """Show the flight logged with ``sensor`` and offer its cycles and M-steps."""
        with self._lock:
            self._quiet = True
            try:
                cycles = self._cycles_of(sensor)
                if self.cycle_dropdown is not None and self.mstep_dropdown is not None:
                    labels = list(dict.fromkeys(_cycle_label(c) for c in cycles)) or ["-"]
                    self.cycle_dropdown.options = labels
                    self.cycle_dropdown.value = labels[0]
                    msteps = list(dict.fromkeys(c.mstep for c in cycles)) or ["-"]
                    self.mstep_dropdown.options = msteps
                    self.mstep_dropdown.value = msteps[0]
            finally:
                self._quiet = False
            flight = self.run.flight(sensor) if sensor is not None else None
            self._show_flight(flight)
            self._select_cycle()

    def _select_cycle(self) -> None:
        with self._lock:
            rec = None
            if self.cycle_dropdown is not None and self.mstep_dropdown is not None:
                sensor = self.sensor_dropdown.value if self.sensor_dropdown else None
                rec = next((c for c in self._cycles_of(sensor)
                            if _cycle_label(c) == self.cycle_dropdown.value
                            and c.mstep == self.mstep_dropdown.value), None)
            self._cycle = rec
            if rec is None:
                self.param_table.content = "_No parameter history for this choice._"
                return
            d = _plot_data(rec)
            if self.mass_plot is not None:
                self.mass_plot.data = d.mass_columns()
                self.mass_plot.scales = d.mass_scales()
            if self.inertia_plot is not None:
                self.inertia_plot.data = d.inertia_columns()
                self.inertia_plot.scales = d.inertia_scales()
            self.param_table.content = _parameter_markdown(rec)
            self._update_flight_note()

    def _show_flight(self, flight: Flight | None) -> None:
        """Draw ``flight``'s paths and fit the time slider to it (None hides them)."""
        with self._lock:
            self._flight = flight
            self._update_path_visibility()
            self.vehicle.visible = flight is not None
            has_truth = flight is not None and flight.true_pos is not None
            has_est = flight is not None and flight.est_pos is not None
            options = [o for o, ok in (("truth", has_truth), ("estimate", has_est)) if ok]
            self._quiet = True
            try:
                self.pose_dropdown.options = options or ["truth"]
                self.ghost_checkbox.disabled = len(options) < 2
                if flight is not None:
                    # Keep the time when switching flights: comparing sensors at the same
                    # moment of the same scenario is the point of switching.
                    now = float(np.clip(self.time_slider.value, flight.t[0], flight.t[-1]))
                    self.time_slider.disabled = False
                    self.time_slider.min = float(flight.t[0])
                    self.time_slider.max = float(flight.t[-1])
                    self.time_slider.step = _nice_step(flight)
                    self.time_slider.value = now
                else:
                    self.time_slider.disabled = True
                    self.set_playing(False)
            finally:
                self._quiet = False
            self._update_flight_note()
            if flight is not None:
                self.set_time(float(self.time_slider.value))
            else:
                self.ghost.visible = False
                self.status.content = ""

    def _update_path_visibility(self) -> None:
        f = self._flight
        choice = self.paths_dropdown.value
        for name, (truth, est) in self._lines.items():
            shown = f is not None and name == f.name
            if truth is not None:
                truth.visible = shown and "truth" in choice
            if est is not None:
                est.visible = shown and "estimate" in choice

    def _update_flight_note(self) -> None:
        f = self._flight
        sensor = self.sensor_dropdown.value if self.sensor_dropdown else None
        if f is None:
            self.flight_note.content = (f"_No flight log kept for {sensor}; only its parameter "
                                        "history is shown._" if sensor else "_No flight log._")
            return
        text = (f"Flight `{f.name}`" + ("" if f.cycle is None else f", cycle {f.cycle}")
                + f": {f.duration:.1f} s, {f.t.shape[0]} samples; estimate = "
                + ("E-step smoothed mean" if f.est_source == "smoothed" else "measured pose"))
        rec = self._cycle
        if rec is not None and f.cycle is not None and rec.cycle != f.cycle:
            text += (f"  \n_The run kept the log of cycle {f.cycle} only; the plots show "
                     f"cycle {rec.cycle}._")
        self.flight_note.content = text

    def set_playing(self, playing: bool) -> None:
        """Start or pause playback."""
        self._playing = bool(playing) and self._flight is not None
        self.play_button.label = "Pause" if self._playing else "Play"

    def select(self, sensor: str) -> None:
        """Choose the sensor as the GUI's dropdown does."""
        if self.sensor_dropdown is None or sensor not in self.sensor_dropdown.options:
            raise ValueError(f"no sensor {sensor!r} in this run")
        self.sensor_dropdown.value = sensor

    def pose_at(self, t: float, source: str) -> tuple[Array, Array] | None:
        """Position (3,) [m] and body-to-world quaternion (w, x, y, z) of the drawn flight
        at time ``t`` [s] by ``source`` ("truth" or "estimate"); None if unavailable."""
        f = self._flight
        if f is None:
            return None
        pos, eul = (f.true_pos, f.true_euler) if source == "truth" else (f.est_pos, f.est_euler)
        if pos is None or eul is None:
            return None
        i = f.index_at(t)
        return pos[i].copy(), quat_wxyz_from_euler(eul[i])

    def set_time(self, t: float) -> None:
        """Pose the vehicle (and the ghost) at time ``t`` [s] of the drawn flight."""
        if self._quiet:
            return
        with self._lock:
            f = self._flight
            if f is None:
                return
            main_src = self.pose_dropdown.value
            other_src = "estimate" if main_src == "truth" else "truth"
            main = self.pose_at(t, main_src)
            other = self.pose_at(t, other_src)
            with self.server.atomic():
                if main is not None:
                    self.vehicle.position, self.vehicle.wxyz = main
                show_ghost = bool(self.ghost_checkbox.value) and other is not None
                if show_ghost and other is not None:
                    self.ghost.position, self.ghost.wxyz = other
                self.ghost.visible = show_ghost
            self.status.content = _status_markdown(f, t, self.pose_at(t, "truth"),
                                                   self.pose_at(t, "estimate"))

    def _play_loop(self) -> None:
        last = time.perf_counter()
        while not self._stop.wait(1.0 / FRAME_RATE):
            now = time.perf_counter()
            elapsed, last = now - last, now
            f = self._flight
            if not self._playing or f is None:
                continue
            speed = float(self.speed_dropdown.value.rstrip("x"))
            t = float(self.time_slider.value) + speed * elapsed
            if t > f.t[-1]:
                t = float(f.t[0])  # loop, so an unattended view keeps moving
            try:
                self.time_slider.value = t  # its callback poses the vehicle
            except Exception:  # the server is shutting down under us
                return

    def stop(self) -> None:
        """Stop playback and the server."""
        self._stop.set()
        self._player.join(timeout=2.0)
        self.server.stop()


# ---------------------------------------------------------------------------- helpers

def _urdf_for(vehicle: str) -> str:
    from pinquad.vehicle.model import urdf_path

    try:
        return urdf_path(vehicle)
    except FileNotFoundError:
        # An unknown vehicle name should not stop the view; draw the paper's frame.
        return urdf_path("paper")


def _cycle_label(rec: CycleRecord) -> str:
    return f"{rec.cycle}" + ("" if rec.seed is None else f" (seed {rec.seed})")


@dataclass(frozen=True)
class PlotData:
    """A parameter history in display units, decimated: x (K,); mass (K,) [g];
    inertia (K, 3) [1e-6 kg m^2]; the truth as constant series (None if unknown)."""

    x: Array
    mass: Array
    inertia: Array
    true_mass: Array | None
    true_inertia: Array | None

    def mass_columns(self) -> tuple[Array, ...]:
        return (self.x, self.mass) + (() if self.true_mass is None else (self.true_mass,))

    def inertia_columns(self) -> tuple[Array, ...]:
        cols = tuple(self.inertia[:, k] for k in range(3))
        true = () if self.true_inertia is None else tuple(self.true_inertia[:, k]
                                                          for k in range(3))
        return (self.x, *cols, *true)

    def mass_scales(self) -> dict:
        return {"x": {"time": False}, "y": {"range": _focus_range(self.mass, self.true_mass)}}

    def inertia_scales(self) -> dict:
        return {"x": {"time": False},
                "y": {"range": _focus_range(self.inertia, self.true_inertia)}}


def _focus_range(values: Array, truth: Array | None) -> tuple[float, float]:
    """y range of a history that leaves out the first tenth (at least the initial guess):
    EM starts far off (m0 = 1 g against 180 g), and auto-ranging on that start would
    flatten the convergence the plot is for."""
    n = values.shape[0]
    tail = values[min(max(1, n // 10), n - 1):] if n > 1 else values
    parts = [tail.reshape(-1)] + ([] if truth is None else [truth.reshape(-1)])
    data = np.concatenate(parts)
    data = data[np.isfinite(data)]
    if data.size == 0:
        return (0.0, 1.0)
    lo, hi = float(data.min()), float(data.max())
    pad = max(0.15 * (hi - lo), 0.03 * max(abs(lo), abs(hi)), 1e-9)
    return (lo - pad, hi + pad)


def _plot_data(rec: CycleRecord) -> PlotData:
    """History in display units (g, 1e-6 kg m^2), decimated; truth as constant series."""
    idx = decimate_indices(rec.x.shape[0], MAX_PLOT_POINTS)
    x = rec.x[idx]
    if x.shape[0] < 2:
        # uPlot needs two points to draw a line; repeat the single estimate.
        idx = np.array([idx[0], idx[0]])
        x = np.array([x[0], x[0] + 1.0])
    n = x.shape[0]
    return PlotData(
        x=x, mass=rec.mass[idx] * 1e3, inertia=rec.inertia_diag[idx] * 1e6,
        true_mass=None if rec.true_mass is None else np.full(n, rec.true_mass * 1e3),
        true_inertia=(None if rec.true_inertia_diag is None
                      else np.broadcast_to(rec.true_inertia_diag * 1e6, (n, 3)).copy()),
    )


def _parameter_markdown(rec: CycleRecord) -> str:
    rows = ["| | estimate | truth | error |", "|---|---|---|---|"]
    truth = [rec.true_mass] + ([None] * 3 if rec.true_inertia_diag is None
                               else list(rec.true_inertia_diag))
    ests = [rec.est_mass, *rec.est_inertia_diag]
    for name, unit, k, est, tru in zip(("mass", "Ixx", "Iyy", "Izz"),
                                       ("g", "1e-6 kg m²", "1e-6 kg m²", "1e-6 kg m²"),
                                       (1e3, 1e6, 1e6, 1e6), ests, truth, strict=True):
        tru_txt = "-" if tru is None else f"{tru * k:.4g}"
        rows.append(f"| {name} [{unit}] | {est * k:.4g} | {tru_txt} | {_fmt_pct(est, tru)} |")
    n = rec.x.shape[0]
    return (f"Sensor {rec.sensor}, cycle {rec.cycle}, {rec.mstep} M-step, "
            f"{n} {'updates' if rec.x_label != 'EM iteration' else 'iterations'}\n\n"
            + "\n".join(rows))


def _status_markdown(f: Flight, t: float, truth: tuple[Array, Array] | None,
                     est: tuple[Array, Array] | None) -> str:
    i = f.index_at(t)
    text = f"t = {f.t[i]:.2f} s"
    if truth is not None and est is not None:
        dp = 1e3 * float(np.linalg.norm(truth[0] - est[0]))
        r_true = rotation_from_euler(f.true_euler[i])  # type: ignore[index]
        r_est = rotation_from_euler(f.est_euler[i])  # type: ignore[index]
        cos = (np.trace(r_true.T @ r_est) - 1.0) / 2.0
        dang = math.degrees(math.acos(float(np.clip(cos, -1.0, 1.0))))
        text += f" &middot; estimate off by {dp:.1f} mm, {dang:.2f}°"
    pose = truth or est
    if pose is not None:
        p = pose[0]
        text += f"  \nposition ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m"
    return text


def _discovery_markdown(disc) -> str:
    lines = []
    if disc.selected:
        lines.append("Selected effects:\n")
        lines += [f"- **{name}**" + (f": {coef}" if coef else "") for name, coef in disc.selected]
    else:
        lines.append("No significant unmodelled effect.")
    before, after = dict(disc.rms_before), dict(disc.rms_after)
    channels = list(dict.fromkeys([*before, *after]))
    if channels:
        lines += ["", "| residual RMS | before | after |", "|---|---|---|"]
        for ch in channels:
            b = f"{before[ch]:.4g}" if ch in before else "-"
            a = f"{after[ch]:.4g}" if ch in after else "-"
            lines.append(f"| {ch} | {b} | {a} |")
    if disc.validation:
        lines += ["", f"_{disc.validation}_"]
    return "\n".join(lines)


def serve(run_dir: str | Path, host: str = "127.0.0.1", port: int = 8080, *,
          scale: float | None = None, verbose: bool = False) -> Viewer:
    """Load ``run_dir`` and serve its view on ``host:port`` without blocking.

    Raises viz.run.RunError if the directory is not a run. port 0 picks a free port;
    a busy port moves to the next free one (``Viewer.url`` tells which).
    """
    run = load_run(run_dir)
    import viser

    server = viser.ViserServer(host=host, port=port, label=f"pinquad: {run.path.name}",
                               verbose=verbose)
    try:
        return Viewer(run, server, scale=scale)
    except BaseException:
        server.stop()
        raise
