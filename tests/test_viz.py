"""The browser view of a run (``python -m viz``), checked in a real headless Chromium.

One small simulated run is made with ``python -m pinquad.offline``; the viewer serves it
in this process on a free port; Chromium, driven through the DevTools protocol, loads
the page and takes screenshots. The 3D canvas must show the scene (vehicle included,
located by projecting its position through the browser's own camera), and moving the
time slider must move the vehicle both in the scene state and on screen.

Chromium is required, not optional: without it the test fails and says how to install
it (Debian: ``apt-get install -y chromium``).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pinquad.core.conventions import rotation_from_quat_wxyz
from viz.browser import CHROMIUM_NAMES, HEIGHT, WIDTH, Chromium, find_chromium, wait_for

PANEL_LEFT = 860
"""Pixels right of this may be covered by viser's floating control panel."""


# ----------------------------------------------------------------------------- helpers

def _chromium_executable() -> str:
    path = find_chromium()
    if path:
        return path
    pytest.fail("headless Chromium is required for the viewer test but none was found "
                f"(looked for {', '.join(CHROMIUM_NAMES)}); on Debian/Ubuntu: "
                "apt-get update && apt-get install -y chromium")


def _project(camera: Any, point: np.ndarray) -> tuple[float, float, float]:
    """Pixel (u, v) and depth of a world point in the browser's canvas, from the camera
    the client reports (OpenCV convention: x right, y down, z forward; vertical fov)."""
    rot = rotation_from_quat_wxyz(np.asarray(camera.wxyz))
    p_cam = rot.T @ (np.asarray(point, float) - np.asarray(camera.position))
    h, w = camera.image_height, camera.image_width
    f = 0.5 * h / math.tan(0.5 * camera.fov)
    return (0.5 * w + f * p_cam[0] / p_cam[2], 0.5 * h + f * p_cam[1] / p_cam[2],
            float(p_cam[2]))


def _box(img: np.ndarray, u: float, v: float, half: int) -> np.ndarray:
    u0, v0 = max(int(u) - half, 0), max(int(v) - half, 0)
    return img[v0:int(v) + half, u0:int(u) + half].astype(int)


def _rotor_blue(img: np.ndarray) -> np.ndarray:
    """Pixels of the paper vehicle's light-blue rotors (URDF rgba 0.2 0.5 0.85, shaded):
    nothing else in the scene has this colour, so they locate the URDF geometry."""
    r, g, b = img[..., 0].astype(int), img[..., 1].astype(int), img[..., 2].astype(int)
    return (b > 190) & (g > 120) & (b - r > 50) & (b - g > 15)


def _non_background(img: np.ndarray) -> np.ndarray:
    """Pixels that are neither the white background nor the light grey floor grid."""
    return img.min(axis=2) < 170


# ----------------------------------------------------------------------------- fixtures

@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One short simulated flight with sensor B, EM cut at 8 iterations (~10 s)."""
    out = tmp_path_factory.mktemp("viz") / "run"
    proc = subprocess.run(
        [sys.executable, "-m", "pinquad.offline", "--cycles", "1", "--sensor", "B",
         "--mstep", "regressor", "--no-information", "--jobs", "1", "--max-iterations", "8",
         "--out", str(out)],
        capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return out


@pytest.fixture(scope="module")
def viewer(run_dir: Path) -> Iterator[Any]:
    from viz.app import serve

    v = serve(run_dir, host="127.0.0.1", port=0)
    try:
        yield v
    finally:
        v.stop()


@pytest.fixture(scope="module")
def browser() -> Iterator[Chromium]:
    page = Chromium(_chromium_executable())
    try:
        yield page
    finally:
        page.close()


# ----------------------------------------------------------------------------- tests

def test_viewer_renders_and_time_slider_moves_vehicle(viewer: Any, browser: Chromium) -> None:
    browser.call("Page.navigate", url=viewer.url)
    server = viewer.server
    clients = wait_for(lambda: list(server.get_clients().values()), 30.0, "the page to connect")
    camera = clients[0].camera
    initial = np.asarray(server.initial_camera.position)
    # The client first reports its default camera, then the run's initial one.
    wait_for(lambda: camera.image_width > 0 and np.allclose(camera.position, initial, atol=1e-3),
          30.0, "the browser's camera to take the viewer's initial pose")
    assert (camera.image_width, camera.image_height) == (WIDTH, HEIGHT)

    def vehicle_pixel() -> tuple[float, float]:
        u, v, depth = _project(camera, viewer.vehicle.position)
        assert depth > 0 and 0 <= u < PANEL_LEFT and 0 <= v < HEIGHT, (
            f"vehicle at {viewer.vehicle.position} projects to ({u:.0f}, {v:.0f}), "
            "outside the visible canvas")
        return u, v

    u0, v0 = vehicle_pixel()
    scene_area = (slice(0, HEIGHT), slice(0, PANEL_LEFT))

    def red_rotor(img: np.ndarray) -> np.ndarray:
        # The red front rotor of the URDF (shaded to salmon; the orange path differs by
        # its low blue).
        r, g, b = img[..., 0], img[..., 1], img[..., 2]
        return (r > 190) & (r - g > 70) & (np.abs(g - b) < 40)

    def rendered() -> np.ndarray | None:
        # the URDF's meshes arrive one by one: wait for the blue rotors and the red one
        img = browser.screenshot()
        near = _box(img, u0, v0, 60)
        ok = (_non_background(img[scene_area]).mean() > 0.01
              and _rotor_blue(near).sum() > 150 and red_rotor(near).sum() > 20)
        return img if ok else None

    first = wait_for(rendered, 40.0, "the 3D scene (blue and red rotors where the vehicle "
                  "projects) to render", interval=1.0)
    scene = first[scene_area].reshape(-1, 3)
    colours = np.unique(scene // 8, axis=0).shape[0]
    assert colours > 100, f"the canvas has only {colours} distinct colours: nothing rendered?"
    near = _box(first, u0, v0, 60)
    assert _rotor_blue(first[scene_area]).sum() < 1.5 * _rotor_blue(near).sum(), (
        "rotor-coloured pixels far from where the vehicle projects")

    # Move the time slider from the server side, as a GUI drag does.
    f = viewer.flight
    assert f is not None and f.t.shape[0] > 100
    before_pos = np.array(viewer.vehicle.position)
    before_wxyz = np.array(viewer.vehicle.wxyz)
    for frac in (0.5, 0.35, 0.65, 0.25, 0.8):
        t = float(f.t[0] + frac * f.duration)
        pos, _ = viewer.pose_at(t, "truth")
        u, v, depth = _project(camera, pos)
        if depth > 0 and 60 <= u < PANEL_LEFT - 60 and 60 <= v < HEIGHT - 60:
            break
    else:
        pytest.fail("no sample time where the vehicle is in view")
    viewer.time_slider.value = t
    after_pos = np.array(viewer.vehicle.position)
    assert np.linalg.norm(after_pos - before_pos) > 0.5
    assert not np.allclose(np.array(viewer.vehicle.wxyz), before_wxyz)
    expected_pos, expected_wxyz = viewer.pose_at(t, "truth")
    np.testing.assert_allclose(after_pos, expected_pos)
    np.testing.assert_allclose(np.array(viewer.vehicle.wxyz), expected_wxyz)
    u1, v1 = vehicle_pixel()

    def moved() -> np.ndarray | None:
        img = browser.screenshot()
        ok = (_rotor_blue(_box(img, u1, v1, 60)).sum() > 50
              and _rotor_blue(_box(img, u0, v0, 60)).sum()
              < 0.2 * _rotor_blue(_box(first, u0, v0, 60)).sum())
        return img if ok else None

    second = wait_for(moved, 20.0, "the vehicle to move on screen", interval=0.5)
    changed = np.abs(second[scene_area].astype(int) - first[scene_area]).max(axis=2) > 40
    assert changed.sum() > 500, "the screenshots barely differ after moving the slider"


def test_viewer_controls(viewer: Any) -> None:
    """Sensor, cycle, pose-source and playback controls exist and act on the scene."""
    run = viewer.run
    assert viewer.sensor_dropdown.options == ("B",)
    assert viewer.cycle_dropdown.options and viewer.mstep_dropdown.value == "regressor"
    assert set(viewer.pose_dropdown.options) == {"truth", "estimate"}
    rec = run.cycles[0]
    assert rec.true_mass == pytest.approx(0.18)
    assert viewer.mass_plot is not None and len(viewer.mass_plot.data[0]) == rec.x.shape[0]
    assert viewer.inertia_plot is not None and len(viewer.inertia_plot.data) == 7

    t = float(viewer.flight.t[len(viewer.flight.t) // 2])
    viewer.time_slider.value = t
    viewer.pose_dropdown.value = "estimate"
    est_pos, _ = viewer.pose_at(t, "estimate")
    np.testing.assert_allclose(viewer.vehicle.position, est_pos)
    viewer.ghost_checkbox.value = True
    assert viewer.ghost.visible
    np.testing.assert_allclose(viewer.ghost.position, viewer.pose_at(t, "truth")[0])
    viewer.pose_dropdown.value = "truth"
    viewer.ghost_checkbox.value = False
    assert not viewer.ghost.visible

    viewer.select("B")
    assert float(viewer.time_slider.value) == pytest.approx(t)
    with pytest.raises(ValueError):
        viewer.select("Z")

    viewer.set_playing(True)
    start = float(viewer.time_slider.value)
    wait_for(lambda: float(viewer.time_slider.value) != start, 5.0, "playback to advance")
    viewer.set_playing(False)


def test_not_a_run_is_a_clear_error(tmp_path: Path) -> None:
    for bad in (tmp_path / "not_a_run", tmp_path):
        proc = subprocess.run([sys.executable, "-m", "viz", str(bad), "--port", "0"],
                              capture_output=True, text=True, timeout=60)
        assert proc.returncode == 2, proc.stderr
        assert str(bad) in proc.stderr and "Traceback" not in proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1
    (tmp_path / "report.json").write_text("{not json")
    proc = subprocess.run([sys.executable, "-m", "viz", str(tmp_path)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and "report.json" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_help() -> None:
    proc = subprocess.run([sys.executable, "-m", "viz", "--help"], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0
    assert "RUN_DIR" in proc.stdout and "--port" in proc.stdout and "--host" in proc.stdout


def test_urdf_geometry() -> None:
    from pinquad.vehicle.model import urdf_path
    from viz.geometry import default_scale, vehicle_parts

    parts = vehicle_parts(urdf_path("paper"))
    rotors = [p for p in parts if p.kind == "cylinder"]
    assert len(parts) == 9 and len(rotors) == 4
    np.testing.assert_allclose(sorted(np.abs(r.position[:2]).max() for r in rotors), [0.086] * 4)
    assert all(r.position[2] == pytest.approx(0.01) for r in rotors)
    assert default_scale("paper", parts) == 5.0
    cf = vehicle_parts(urdf_path("crazyflie21"))
    assert default_scale("crazyflie21", cf) == 15.0


def test_recorded_log_run_without_truth(tmp_path: Path) -> None:
    """A run of a long recorded log (no truth, no scenario, no cycles) still serves,
    with the drawn path decimated, its final estimate and its discovery outcome."""
    from PIL import Image

    from pinquad.io.logs import FlightLog, write_log
    from viz.app import serve
    from viz.scene import MAX_LINE_POINTS

    n = 30000  # 60 s at 500 Hz
    t = np.arange(n) / 500.0
    pos = np.column_stack([np.cos(0.2 * t), np.sin(0.2 * t), 1.0 + 0.1 * t / 60])
    euler = np.column_stack([0.05 * np.sin(t), 0.05 * np.cos(t), 0.2 * t])
    log = FlightLog(t=t, position=pos, velocity=np.zeros((n, 3)), euler=euler,
                    gyro=np.zeros((n, 3)), accel=np.zeros((n, 3)), thrust=np.full(n, 0.3),
                    torque=np.zeros((n, 3)))
    (tmp_path / "logs").mkdir()
    write_log(log, tmp_path / "logs" / "flight.parquet")
    report = {"schema": "pinquad.report/1",
              "source": {"kind": "log", "path": "flight.parquet", "vehicle": "crazyflie21"},
              "estimates": {"mass": 0.035, "inertia": np.diag([1.7e-5, 1.7e-5, 2.9e-5]).tolist()},
              "em": {"iterations": 1, "loglik": [0.0], "converged": True},
              "run_logs": {"log": {"log": "logs/flight.parquet"}},
              "discovery": {"selected": [{"effect": "drag", "coefficients": {"k_xy": 0.012}}],
                            "residual_rms_before": {"acc_x": 0.31},
                            "residual_rms_after": {"acc_x": 0.12},
                            "validation": "held-out second half",
                            "figures": ["figures/residuals.png"]}}
    (tmp_path / "figures").mkdir()
    figure = np.full((60, 90, 4), 255, np.uint8)
    figure[20:40, 10:80, :3] = (200, 30, 30)
    Image.fromarray(figure).save(tmp_path / "figures" / "residuals.png")
    (tmp_path / "report.json").write_text(json.dumps(report))
    started = time.perf_counter()
    v = serve(tmp_path, port=0)
    elapsed = time.perf_counter() - started
    try:
        assert 1.0 <= v.scale < 15.0  # x15 would hide a 1 m circle; capped to the scene
        assert v.pose_dropdown.options == ("estimate",)
        f = v.flight
        assert f is not None and f.true_pos is None and f.est_source == "measured"
        _, est_line = v._lines["log"]
        assert est_line is not None and est_line.points.shape[0] < MAX_LINE_POINTS
        v.time_slider.value = 30.0
        np.testing.assert_allclose(v.vehicle.position, pos[15000], atol=1e-9)
        assert v.mass_plot is not None and v.param_table.content
        assert v.discovery_text is not None and "drag" in v.discovery_text.content
        assert "0.31" in v.discovery_text.content and "0.12" in v.discovery_text.content
        assert len(v.discovery_images) == 1
        assert v.discovery_images[0].image.shape == (60, 90, 3)
    finally:
        v.stop()
    print(f"served a 60 s, 500 Hz log in {elapsed:.2f} s")


# ------------------------------------------------------------- a recorded real flight

# jana02: a figure-8 on which discovery selects drag (held-out gain 22 %; on jana00, 9 s,
# drag falls just under the 10 % bar since stop 28)
JANA02 = Path(__file__).resolve().parents[2] / "shared" / "data" / "crazyflie" / "imrc_brushed" / "jana02"


@pytest.fixture(scope="module")
def jana_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The shared real Crazyflie log jana02 through ``offline --log`` in-process (~6 s):
    regressor M-step, discovery on (it selects drag on this log)."""
    from pinquad.cli.offline import main as offline_main

    assert JANA02.is_file(), f"the shared Crazyflie log is missing: expected {JANA02}"
    out = tmp_path_factory.mktemp("viz_log") / "run"
    code = offline_main(["--log", str(JANA02), "--mstep", "regressor", "--no-information",
                         "--out", str(out)])
    assert code in (0, 3) and (out / "report.json").is_file()  # 3: an untrusted headline
    return out


def _warm_share(img: np.ndarray) -> float:
    """Share of the path's coloured pixels in the scene that are on the warm (large
    residual: pink to yellow) end of the colour scale rather than the cool (dark blue,
    purple) end."""
    im = img[:, :PANEL_LEFT].astype(int)
    r, g, b = im[..., 0], im[..., 1], im[..., 2]
    warm = ((r > 180) & (b < 140) & (r - b > 80)).sum()
    cool = ((b > 90) & (g < 70) & (b - g > 60)).sum()
    assert warm + cool > 2000, f"only {warm + cool} coloured path pixels: path not drawn?"
    return float(warm / (warm + cool))


def test_recorded_log_view_in_browser(jana_run: Path, browser: Chromium) -> None:
    """A real flight's view: the log's vehicle at its size, the whole EM history, the
    headline with verdict, base fit and reference in the page; the path coloured by the
    force residual, warm on the base fit and cooler under the final model (drag)."""
    from viz.app import serve
    from viz.browser import NOTICE_JS, open_view, page_text, settled

    report = json.loads((jana_run / "report.json").read_text())
    assert report["source"]["vehicle_named"] is True and report["reference"]["mass"] == 0.0347
    v = serve(jana_run, port=0)
    try:
        assert v.scale == 1.0 and v.run.vehicle == "crazyflie21"
        rec = v.run.cycles[0]
        e_steps = report["runs"][0]["e_steps"]
        assert e_steps > 10 and rec.e_steps == e_steps
        assert rec.x.shape[0] == e_steps + 1  # the initial guess and one iterate per E-step
        assert len(v.mass_plot.data[0]) == e_steps + 1
        assert np.isfinite(v.loglik_plot.data[1]).sum() == e_steps
        assert set(v.residual_lines["log"]) == {"force_before", "force_after",
                                                "torque_before", "torque_after"}
        v.colour_dropdown.value = "force residual, base fit"
        assert v.residual_lines["log"]["force_before"].visible
        assert not v._lines["log"][1].visible  # the plain path gives way to the coloured one
        open_view(browser, v)
        wait_for(lambda: browser.evaluate(NOTICE_JS) is not None, 10.0, "the notices")
        text = page_text(browser)
        for label in ("crazyflie21", "drawn at its real size", "Path colour",
                      "Raw motion capture", f"{e_steps} E-steps", "Headline estimate",
                      report["verdict"]["overall"], "base fit", "reference", "34.700",
                      "force residual, base fit", "log-likelihood [nats]"):
            assert label in text, f"{label!r} not in the page"
        before = settled(browser, timeout=20.0)
        v.colour_dropdown.value = "force residual, final model"
        assert v.residual_lines["log"]["force_after"].visible
        assert not v.residual_lines["log"]["force_before"].visible
        after = wait_for(lambda: (img := settled(browser, timeout=20.0)) is not None
                         and not np.array_equal(img, before) and img, 20.0,
                         "the path's colours to change")
        assert _warm_share(after) < 0.67 * _warm_share(before)
        v.mocap_checkbox.value = True
        assert v.mocap_points["log"].visible
        assert v.mocap_points["log"].points.shape[0] > 400
    finally:
        v.stop()
