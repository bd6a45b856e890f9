"""The view of one run directory: a :class:`Viewer` holds the viser server, the scene
(:mod:`viz.scene`), the GUI panels (:mod:`viz.panels`) and plots (:mod:`viz.plots`),
and drives them: sensor and cycle choice, playback, the vehicle's pose.

``serve(run_dir, host, port)`` loads the run, starts a viser server (its own threads),
builds the scene and returns a :class:`Viewer` at once; ``Viewer.stop()`` shuts it down.
All drawing data is loaded and decimated up front, so GUI callbacks only index arrays
and a 60 s, 500 Hz log costs no more per frame than a short one.
"""

from __future__ import annotations

import math
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import quat_wxyz_from_euler
from viz.geometry import body_radius, default_scale, resized, stand_in, vehicle_parts
from viz.panels import (
    add_discovery_panel,
    add_figures_panel,
    add_warnings_panel,
    cycle_label,
    header_markdown,
    headline_markdown,
    parameter_markdown,
    residual_legend,
    status_markdown,
)
from viz.plots import add_loglik_plot, add_parameter_plots, loglik_columns, plot_data
from viz.recorded import RESIDUAL_CHOICES
from viz.run import CycleRecord, Flight, Run, load_run
from viz.scene import build_scene, scene_bounds, urdf_for

if TYPE_CHECKING:
    import viser

Array = NDArray[np.float64]

FRAME_RATE = 30.0
"""Playback updates per second of wall time."""
PATH_CHOICES = ("truth and estimate", "truth", "estimate", "none")
"""The Paths dropdown's choices."""
SPEEDS = ("0.1x", "0.25x", "0.5x", "1x", "2x", "4x", "8x")
"""Playback speeds, relative to the flight's own time."""
PLAIN_PATH = "plain (no residual colour)"
"""The Path colour selector's first entry; the others are ``RESIDUAL_CHOICES``'."""


def drawn_vehicle(run: Run) -> tuple[str, float]:
    """The vehicle drawn for ``run`` and its size factor: the log's own at its size; for
    a log that names none, a quad of the identified mass (``geometry.stand_in``)."""
    if run.vehicle_named:
        return run.vehicle, 1.0
    mass = (run.headline.final.mass if run.headline is not None
            else run.cycles[0].est_mass if run.cycles else None)
    return stand_in(mass)


def _nice_step(flight: Flight) -> float:
    """Slider step: the log's sample interval, coarsened so the slider has at most a
    few thousand positions, rounded to a power of ten for readable values."""
    dt = float(np.median(np.diff(flight.t))) if flight.t.shape[0] > 1 else 0.01
    raw = max(dt, flight.duration / 5000.0, 1e-4)
    return 10.0 ** math.floor(math.log10(raw))


class Viewer:
    """A running browser view of one run: the viser server plus its scene and GUI
    handles. Build it with :func:`serve`; ``set_time`` / ``select`` drive it from code
    (tests) exactly as the GUI does."""

    def __init__(self, run: Run, server: viser.ViserServer, scale: float | None = None
                 ) -> None:
        self.run = run
        self.server = server
        drawn, size = drawn_vehicle(run)
        self.parts = resized(vehicle_parts(urdf_for(drawn)), size)
        path_bounds = scene_bounds(run, 0.0)
        # A recorded flight is drawn at its real size: beside the floor and its own path,
        # a magnified vehicle would misstate how close to the ground it flew.
        self.scale = float(scale) if scale else 1.0 if run.kind == "log" else default_scale(
            drawn, self.parts, path_bounds.radius)
        self.bounds = scene_bounds(run, self.scale * body_radius(self.parts))
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
        scene = build_scene(self.server, self.run, self.bounds, self.floor_z, self.parts,
                            self.scale)
        # Each flight's lines are added once and toggled, so switching sensors is instant.
        self._lines = scene.lines
        self.vehicle = scene.vehicle
        self.ghost = scene.ghost
        self.residual_lines = scene.residual_lines
        self.residual_tops = scene.residual_tops
        self.mocap_points = scene.mocap

    def _build_gui(self) -> None:
        gui = self.server.gui
        run = self.run
        gui.configure_theme(control_width="large", show_share_button=False)
        gui.add_markdown(header_markdown(run, self.scale))

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
            self.colour_dropdown = self.mocap_checkbox = self.colour_legend = None
            if self.residual_lines:
                self.colour_dropdown = gui.add_dropdown(
                    "Path colour", (PLAIN_PATH, *(label for label, _ in RESIDUAL_CHOICES)),
                    initial_value=PLAIN_PATH,
                    hint="Colour the smoothed path by the size of the identified model's "
                         "residual: where the model fails")
                self.colour_legend = gui.add_markdown("")
                self.colour_dropdown.on_update(lambda _: self._update_path_visibility())
            if self.mocap_points:
                self.mocap_checkbox = gui.add_checkbox(
                    "Raw motion capture", False,
                    hint="Draw the motion-capture samples as recorded beside the path")
                self.mocap_checkbox.on_update(lambda _: self._update_path_visibility())
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
            self.headline_text = (None if run.headline is None
                                  else gui.add_markdown(headline_markdown(run.headline)))
            self.param_table = gui.add_markdown("")
            self.mass_plot = None
            self.inertia_plot = None
            self.loglik_plot = None
            if run.cycles:
                self.mass_plot, self.inertia_plot = add_parameter_plots(gui, run.cycles[0])
                if any(c.loglik is not None for c in run.cycles):
                    self.loglik_plot = add_loglik_plot(gui, run.cycles[0])

        self.discovery_text, self.discovery_images = add_discovery_panel(gui, run.discovery)
        add_figures_panel(gui, run)
        add_warnings_panel(gui, run.warnings)

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
                    labels = list(dict.fromkeys(cycle_label(c) for c in cycles)) or ["-"]
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
                            if cycle_label(c) == self.cycle_dropdown.value
                            and c.mstep == self.mstep_dropdown.value), None)
            self._cycle = rec
            if rec is None:
                self.param_table.content = "_No parameter history for this choice._"
                return
            d = plot_data(rec)
            if self.mass_plot is not None:
                self.mass_plot.data = d.mass_columns()
                self.mass_plot.scales = d.mass_scales()
            if self.inertia_plot is not None:
                self.inertia_plot.data = d.inertia_columns()
                self.inertia_plot.scales = d.inertia_scales()
            if self.loglik_plot is not None:
                self.loglik_plot.data = loglik_columns(rec)
            self.param_table.content = parameter_markdown(rec)
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

    @property
    def residual_column(self) -> str | None:
        """The residual column the path is coloured by (None: plain)."""
        if self.colour_dropdown is None:
            return None
        return dict(RESIDUAL_CHOICES).get(self.colour_dropdown.value)

    def _update_path_visibility(self) -> None:
        f = self._flight
        choice = self.paths_dropdown.value
        column = self.residual_column
        for name, (truth, est) in self._lines.items():
            shown = f is not None and name == f.name
            coloured = shown and column is not None and name in self.residual_lines
            if truth is not None:
                truth.visible = shown and "truth" in choice
            if est is not None:
                est.visible = shown and "estimate" in choice and not coloured
            for col, handle in self.residual_lines.get(name, {}).items():
                handle.visible = coloured and "estimate" in choice and col == column
            if name in self.mocap_points:
                self.mocap_points[name].visible = bool(
                    shown and self.mocap_checkbox is not None and self.mocap_checkbox.value)
        if self.colour_legend is not None:
            track = None if f is None else f.residuals
            self.colour_legend.content = ("" if column is None or track is None else
                                          residual_legend(column, self.residual_tops[f.name][column],
                                                          track.note))

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
            self.status.content = status_markdown(f, t, self.pose_at(t, "truth"),
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


def serve(run_dir: str | Path, host: str = "127.0.0.1", port: int = 8080, *,
          scale: float | None = None, verbose: bool = False) -> Viewer:
    """Load ``run_dir`` and serve its view on ``host:port`` without blocking.

    Raises viz.run.RunError if the directory is not a run. port 0 picks a free port;
    a busy port moves to the next free one (``Viewer.url`` tells which).
    """
    run = load_run(run_dir)
    # deferred on purpose: viser is heavy (a web server and its assets); a directory that
    # is not a run fails before it is imported
    import viser

    server = viser.ViserServer(host=host, port=port, label=f"pinquad: {run.path.name}",
                               verbose=verbose)
    try:
        return Viewer(run, server, scale=scale)
    except BaseException:
        server.stop()
        raise
