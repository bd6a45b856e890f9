"""The 3-D scene of a run's view: the floor, the waypoints, each flight's true and
estimated paths (added once, toggled when the sensor changes), the vehicle and its
translucent ghost drawn from the URDF's primitives, and the initial camera.

Positions in metres, world z up; colours sRGB 0-255.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from pinquad.vehicle.model import urdf_path
from viz.geometry import VisualPart, body_radius
from viz.recorded import RESIDUAL_CHOICES
from viz.run import Flight, Run, decimate_indices

if TYPE_CHECKING:
    import viser

Array = NDArray[np.float64]

TRUTH_RGB = (25, 140, 60)
ESTIMATE_RGB = (235, 110, 20)
WAYPOINT_RGB = (120, 60, 200)
START_RGB = (110, 110, 110)

MAX_LINE_POINTS = 2000
"""Vertices per drawn trajectory; more adds nothing visible and slows the browser."""
MOCAP_RGB = (90, 90, 90)
NAN_RGB = (170, 170, 170)
COLORMAP = np.array([(13, 8, 135), (126, 3, 168), (204, 71, 120), (248, 149, 64),
                     (240, 249, 33)], dtype=float)
"""Residual colour scale, small to large (plasma's stops): dark blue, purple, pink,
orange, yellow."""
SCALE_PERCENTILE = 95.0
"""The top of the colour scale: this percentile of the residual sizes (base fit and final
model together, so both are coloured alike), so a few spikes do not flatten the rest."""


def residual_scale(values: Array) -> float:
    """Top of the colour scale of ``values`` (``SCALE_PERCENTILE``; 1 if none finite)."""
    ok = values[np.isfinite(values)]
    top = float(np.percentile(ok, SCALE_PERCENTILE)) if ok.size else 1.0
    return top if top > 0 else 1.0


def residual_rgb(values: Array, top: float) -> NDArray[np.uint8]:
    """(K, 3) sRGB colours of ``values`` on ``COLORMAP`` from 0 to ``top`` (clipped;
    NaN grey)."""
    x = np.clip(np.nan_to_num(values, nan=0.0) / top, 0.0, 1.0) * (COLORMAP.shape[0] - 1)
    lo = np.minimum(np.floor(x).astype(int), COLORMAP.shape[0] - 2)
    frac = (x - lo)[:, None]
    rgb = COLORMAP[lo] * (1 - frac) + COLORMAP[lo + 1] * frac
    rgb[~np.isfinite(values)] = NAN_RGB
    return np.round(rgb).astype(np.uint8)


@dataclass(frozen=True)
class SceneBounds:
    """Axis-aligned box [m] around everything drawn; frames the camera and the floor."""

    low: Array
    high: Array

    @property
    def center(self) -> Array:
        """Centre of the box (3,) [m]."""
        return 0.5 * (self.low + self.high)

    @property
    def radius(self) -> float:
        """Half the box's diagonal [m], at least 0.5."""
        return max(0.5 * float(np.linalg.norm(self.high - self.low)), 0.5)


def scene_bounds(run: Run, margin: float) -> SceneBounds:
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


def line_segments(points: Array, rgb: tuple[int, int, int], dash: int = 0
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
    colors = np.broadcast_to(linear_rgb(rgb), segs.shape).copy()
    return segs, colors


def linear_rgb(rgb: tuple[int, int, int] | NDArray[np.uint8]) -> NDArray[np.uint8]:
    """sRGB colour (or (K, 3) colours) as the linear value viser's line shader expects:
    its vertex colours skip the sRGB decoding meshes get, so without this lines look
    washed out."""
    c = np.asarray(rgb, dtype=float) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return np.round(255.0 * lin).astype(np.uint8)


def urdf_for(vehicle: str) -> str:
    """The URDF file drawn for ``vehicle``; the paper's frame for an unknown name."""
    try:
        return urdf_path(vehicle)
    except FileNotFoundError:
        # An unknown vehicle name should not stop the view; draw the paper's frame.
        return urdf_path("paper")


@dataclass(frozen=True)
class Scene:
    """Handles of the drawn scene: ``lines`` maps each flight's name to its (truth,
    estimate) path handles (None where the run has no such path); ``vehicle`` and
    ``ghost`` are the frames the vehicle's parts hang under."""

    lines: dict[str, tuple[viser.LineSegmentsHandle | None, viser.LineSegmentsHandle | None]]
    vehicle: viser.FrameHandle
    ghost: viser.FrameHandle
    residual_lines: dict[str, dict[str, viser.LineSegmentsHandle]]
    residual_tops: dict[str, dict[str, float]]
    mocap: dict[str, viser.PointCloudHandle]


def build_scene(server: viser.ViserServer, run: Run, bounds: SceneBounds, floor_z: float,
                parts: tuple[VisualPart, ...], scale: float) -> Scene:
    """Draw ``run`` in ``server``'s scene: the floor at height ``floor_z`` [m] under
    ``bounds``, the waypoints and start, every flight's paths (hidden until shown), the
    vehicle (its ``parts`` magnified ``scale`` times) at the start and its hidden ghost;
    and aim the initial camera at ``bounds``."""
    scene = server.scene
    scene.set_up_direction("+z")
    b = bounds
    size = np.ceil(b.high[:2] - b.low[:2] + 2.0)
    scene.add_grid("/floor", width=float(size[0]), height=float(size[1]), plane="xy",
                   cell_size=0.5, section_size=1.0,
                   position=(float(b.center[0]), float(b.center[1]), floor_z))
    marker = float(np.clip(0.02 * b.radius, 0.04, 0.2))
    if run.waypoints is not None:
        for i, wp in enumerate(run.waypoints):
            scene.add_icosphere(f"/waypoints/w{i + 1}", radius=marker, color=WAYPOINT_RGB,
                                position=tuple(wp), cast_shadow=False)
            scene.add_label(f"/waypoints/w{i + 1}/label", f"W{i + 1}",
                            position=(0.0, 0.0, 2.0 * marker))
    if run.start is not None:
        scene.add_icosphere("/waypoints/start", radius=marker, color=START_RGB,
                            position=tuple(run.start), cast_shadow=False)
        scene.add_label("/waypoints/start/label", "start", position=(0.0, 0.0, 2.0 * marker))

    # Each flight's lines are added once and toggled, so switching sensors is instant.
    lines: dict[str, tuple[viser.LineSegmentsHandle | None,
                            viser.LineSegmentsHandle | None]] = {}
    for f in run.flights:
        idx = decimate_indices(f.t.shape[0], MAX_LINE_POINTS)
        truth = est = None
        if f.true_pos is not None:
            segs, cols = line_segments(f.true_pos[idx], TRUTH_RGB)
            truth = scene.add_line_segments(f"/flights/{f.name}/truth", segs, cols,
                                            thickness=3.0, thickness_units="screen",
                                            visible=False)
        if f.est_pos is not None:
            segs, cols = line_segments(f.est_pos[idx], ESTIMATE_RGB,
                                       dash=max(idx.shape[0] // 300, 1))
            est = scene.add_line_segments(f"/flights/{f.name}/estimate", segs, cols,
                                          thickness=6.0, thickness_units="screen",
                                          visible=False)
        lines[f.name] = (truth, est)
    residual_lines, residual_tops, mocap = add_residual_paths(scene, run, b.radius)

    vehicle = add_vehicle(scene, "/vehicle", parts, scale, opacity=None)
    ghost = add_vehicle(scene, "/ghost", parts, scale, opacity=0.3)
    ghost.visible = False
    if run.start is not None:
        vehicle.position = tuple(run.start)

    cam = server.initial_camera
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
    return Scene(lines, vehicle, ghost, residual_lines, residual_tops, mocap)


def residual_segments(f: Flight, column: str, top: float) -> tuple[Array, NDArray[np.uint8]]:
    """The smoothed path of ``f`` as segments (K, 2, 3) coloured (K, 2, 3) by the residual
    size in ``column`` at each segment's start (``residual_rgb`` up to ``top``)."""
    assert f.residuals is not None and f.est_pos is not None
    idx = decimate_indices(f.t.shape[0], MAX_LINE_POINTS)
    pts, t = f.est_pos[idx], f.t[idx]
    ok = np.isfinite(pts).all(axis=1)
    pts, t = pts[ok], t[ok]
    segs = np.stack([pts[:-1], pts[1:]], axis=1).astype(np.float32)
    rgb = residual_rgb(f.residuals.at(column, t[:-1]), top)
    colors = np.repeat(linear_rgb(rgb)[:, None, :], 2, axis=1)
    return segs, colors


def add_residual_paths(scene: viser.SceneApi, run: Run, radius: float
                       ) -> tuple[dict[str, dict[str, viser.LineSegmentsHandle]],
                                  dict[str, dict[str, float]],
                                  dict[str, viser.PointCloudHandle]]:
    """Each flight's smoothed path coloured by every residual column
    (``/flights/<name>/residual/<column>``, hidden) with the top of each colour scale
    (force columns share one, torque columns another), and its raw motion-capture samples
    (``/flights/<name>/mocap``, hidden)."""
    lines: dict[str, dict[str, viser.LineSegmentsHandle]] = {}
    tops: dict[str, dict[str, float]] = {}
    mocap: dict[str, viser.PointCloudHandle] = {}
    for f in run.flights:
        if f.residuals is not None and f.est_pos is not None:
            cols = f.residuals.columns
            kinds = {c: c.split("_")[0] for _, c in RESIDUAL_CHOICES}
            top = {k: residual_scale(np.concatenate([cols[c] for c in cols if kinds[c] == k]))
                   for k in set(kinds.values())}
            tops[f.name] = {c: top[kinds[c]] for _, c in RESIDUAL_CHOICES}
            lines[f.name] = {}
            for _, column in RESIDUAL_CHOICES:
                segs, colors = residual_segments(f, column, tops[f.name][column])
                lines[f.name][column] = scene.add_line_segments(
                    f"/flights/{f.name}/residual/{column}", segs, colors, thickness=6.0,
                    thickness_units="screen", visible=False)
        if f.mocap is not None:
            pts = f.mocap[:, 1:4].astype(np.float32)
            mocap[f.name] = scene.add_point_cloud(
                f"/flights/{f.name}/mocap", pts, np.broadcast_to(
                    np.asarray(MOCAP_RGB, np.uint8), pts.shape).copy(),
                point_size=float(np.clip(0.004 * radius, 0.003, 0.02)), point_shape="circle",
                point_shading="flat", visible=False)
    return lines, tops, mocap


def add_vehicle(scene: viser.SceneApi, name: str, parts: tuple[VisualPart, ...], scale: float,
                opacity: float | None) -> viser.FrameHandle:
    """The URDF's primitives ``parts``, magnified ``scale`` times, under one frame
    ``name`` (all of them ``opacity`` if given, else their own).

    viser's node ``scale`` does not reach child nodes, so each part's size and
    offset are scaled here instead.
    """
    k = scale
    reach = k * body_radius(parts)
    frame = scene.add_frame(name, show_axes=True, axes_length=0.5 * reach,
                            axes_radius=0.025 * reach, origin_radius=0.03 * reach)
    for p in parts:
        add_part(scene, f"{name}/{p.name}", p, scale, opacity)
    return frame


def add_part(scene: viser.SceneApi, name: str, p: VisualPart, scale: float,
             opacity: float | None) -> None:
    """One URDF primitive ``p`` (box, cylinder or sphere), magnified ``scale`` times."""
    k = scale
    alpha = opacity if opacity is not None else (p.opacity if p.opacity < 1.0 else None)
    kw = dict(color=p.rgb, opacity=alpha, wxyz=tuple(p.wxyz),
              position=tuple(k * p.position), cast_shadow=opacity is None)
    if p.kind == "box":
        scene.add_box(name, dimensions=tuple(k * np.asarray(p.dims)), **kw)
    elif p.kind == "cylinder":
        scene.add_cylinder(name, radius=k * p.dims[0], height=k * p.dims[1], **kw)
    else:
        scene.add_icosphere(name, radius=k * p.dims[0], **kw)
