"""The benchmark's correctness checks on a tiny case (no timings are asserted).

Our compiled E-step must equal our generic RTS smoother on the linearised model (always
run), and every installed peer (filterpy, pykalman, dynamax, GTSAM) to 1e-8 of the
state scale; a peer that is not installed is skipped with its name in the reason (the
test extra does not install them).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time

import numpy as np
import pytest

from pinquad.experiments import bench
from pinquad.experiments.bench_cases import (
    TOLERANCE,
    EStepCase,
    base_observations,
    build_case,
    load_case,
    mean_error,
    tile_observations,
)
from pinquad.experiments.bench_estep import CONTESTANTS, check_all
from pinquad.io.runs import atomic_write_json

N_STEPS = 300


@pytest.fixture(scope="module")
def base():
    return base_observations()


@pytest.fixture(scope="module")
def case(base) -> EStepCase:
    # longer than the base flight would be slow; a tiled case crosses a seam instead
    return build_case(tile_observations(base, 200), N_STEPS)


def test_tiling_repeats_the_flight(base):
    tiled = tile_observations(base, base.n + 10)
    assert tiled.ys.shape == (base.n + 10, base.ys.shape[1])
    np.testing.assert_array_equal(tiled.inputs[base.n:], base.inputs[:10])
    np.testing.assert_array_equal(np.isnan(tiled.ys[base.n:]), np.isnan(base.ys[:10]))
    assert np.allclose(np.diff(tiled.t), base.dt)


def test_linearised_model_reproduces_ours(case):
    """The generic RTS on the linearisation is the EKF-RTS of the quadcopter model."""
    (res,) = check_all(case, ["generic"])
    assert res.status == "ok", res.message
    assert res.error is not None and res.error <= TOLERANCE


@pytest.mark.parametrize("name", ["filterpy", "pykalman", "dynamax", "gtsam"])
def test_installed_peer_agrees(case, name):
    peer = CONTESTANTS[name]
    missing = peer.missing()
    if missing:
        pytest.skip(f"peer {name} absent (not installed: {', '.join(missing)})")
    (res,) = check_all(case, [name])
    assert res.status == "ok", res.message
    assert res.error <= TOLERANCE


def test_case_round_trip(case, tmp_path):
    path = tmp_path / "case.npz"
    case.save(path)
    back = load_case(path)
    np.testing.assert_array_equal(back.ys, case.ys)
    np.testing.assert_array_equal(back.lin.f, case.lin.f)
    assert back.obs.channels == case.obs.channels
    np.testing.assert_array_equal(back.lin.m0, case.lin.m0)


def test_mean_error_against_a_hand_computed_case():
    """mean_error = max_k,i |mean - ref| / scale_i, scale_i = max_k |ref_ki| (1 where that
    is below 1e-3); the worked numbers below are computed by hand."""
    ref = np.array([[2.0, 1e-4, -10.0],
                    [-4.0, -5e-4, 5.0]])
    mean = ref + np.array([[0.4, 0.0, 0.0],
                           [0.0, 0.0, 0.0]])
    assert mean_error(mean, ref) == pytest.approx(0.4 / 4.0, rel=1e-15)
    mean[1, 1] += 0.3  # a near-zero component: scaled by 1, not by 5e-4
    assert mean_error(mean, ref) == pytest.approx(0.3, rel=1e-12)
    mean[0, 2] -= 5.0  # 5 / max|-10, 5| = 0.5
    assert mean_error(mean, ref) == pytest.approx(0.5, rel=1e-15)
    assert mean_error(ref, ref) == 0.0


def test_helpers():
    assert bench.loglog_slope([10, 100, 1000], [1.0, 10.0, 100.0]) == pytest.approx(1.0)
    assert bench.loglog_slope([10, 100], [1.0, None]) is None
    assert bench._clean({"a": math.nan, "b": [np.float64(2.0)]}) == {"a": None, "b": [2.0]}

    def spin() -> None:
        while True:
            time.sleep(0.001)

    with pytest.raises(bench.CallTimeout):
        bench.timed_call(spin, limit=0.05)


def test_json_is_written_whole(tmp_path):
    out = tmp_path / "sub" / "bench.json"
    atomic_write_json(out, {"estep": {"N": [1], "ours_s": [None]}})
    assert json.loads(out.read_text()) == {"estep": {"N": [1], "ours_s": [None]}}
    assert [p.name for p in out.parent.iterdir()] == ["bench.json"]


def test_check_command():
    """``python -m pinquad.bench --check N`` as a user runs it (without dynamax, which
    would compile for a while): exit 0, one line per peer."""
    proc = subprocess.run(
        [sys.executable, "-m", "pinquad.bench", "--check", "120", "--peers", "generic",
         "filterpy", "pykalman", "gtsam"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    for name in ("generic", "filterpy", "pykalman", "gtsam"):
        assert f"  {name}" in proc.stdout
