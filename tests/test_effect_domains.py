"""Effects fitted inside their physical domains, and the ground-effect law's floor.

* The refit's profiled fit holds a coefficient whose free fit is negative on its domain's
  edge (0), and the fit of the rest is then the fit of the model without it; the
  likelihood's Newton step is projected onto the box (worked by hand).
* A coefficient on the edge is reported as such (report.json's discovery entry and the
  printed line), and an effect whose every coefficient is on the edge is not kept.
* The ground-effect law measures the height above the floor the log shows: a flightgen
  flight (an independent generator, floor at z = 0) and the same flight with every
  height shifted up by 6 cm give the same floor-relative height and the same
  ground-effect regressor; a Neural-Swarm flight read natively (floor plane 0.06 m in
  its frame) and shifted to the floor likewise.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from flightgen import FlightSpec, generate, write_csv
from pinquad.discovery.calibrated import DiscoveryOutcome
from pinquad.discovery.domain import outside_domain, transition_heights
from pinquad.discovery.library import TransitionData, wrench_features
from pinquad.discovery.result import CandidateScore, DiscoveryResult
from pinquad.discovery.selection import profiled_fit
from pinquad.discovery.uncertainty import projected_newton
from pinquad.io.logs import write_log
from pinquad.io.read import read_log
from pinquad.models.contact import FloorLevel
from pinquad.models.sources import floor_contact, observations
from pinquad.models.ssm import Observations
from pinquad.report.recorded import discovery_summary

NEURAL_SWARM = Path(__file__).resolve().parents[1] / "../shared/data/neural_swarm/flights"


def _gram(c_true: float, seed: int = 3, k: int = 600) -> tuple[np.ndarray, np.ndarray]:
    """A summed Gram (6, q, q), q = 4 + 1 + 1, of rows z_k = [Y_k (4), phi_k, -tau_k]
    (residual Y pi + phi c - tau) for pi = [30 g, 20, 20, 40 e-6 kg m^2]: each wrench row
    a carries one parameter's regressor x_a (the mass on the force rows, I_aa on torque
    row a), the effect phi only on the vertical force row, tau = Y pi_true + phi c_true +
    noise, so the residual's effect part is phi (c - c_true). Returns (gram with the
    effect, gram without its column)."""
    rng = np.random.default_rng(seed)
    pi_true = np.array([0.03, 2e-5, 2e-5, 4e-5])
    gram = np.zeros((6, 6, 6))
    phi = rng.normal(size=k)
    for a in range(6):
        j = 0 if a < 3 else a - 2
        x = rng.normal(size=k) * (10.0 if a < 3 else 100.0)
        tau = pi_true[j] * x + 0.02 * pi_true[j] * x.std() * rng.normal(size=k)
        f = np.zeros(k)
        if a == 2:
            f = phi * 0.01
            tau = tau + c_true * f
        z = np.zeros((k, 6))
        z[:, j] = x
        z[:, 4] = f
        z[:, 5] = -tau
        gram[a] = z.T @ z
    keep = [0, 1, 2, 3, 5]
    return gram, gram[:, keep][:, :, keep]


def test_a_negative_free_fit_is_held_on_the_domain_edge():
    """Free fit c = -0.5 by construction (its residual is 0.01 phi (c + 0.5)): bounded at
    0 it sits on the edge, and mass and inertia are then the fit of the model without
    the effect (worked independently: the same Gram without its column). A positive
    truth is left alone by the bound."""
    gram, without = _gram(-0.5)
    pi0 = np.array([0.02, 1e-5, 1e-5, 3e-5])
    free = profiled_fit(gram, 600, pi0, 1)
    assert abs(free.c[0] + 0.5) < 0.05
    held = profiled_fit(gram, 600, pi0, 1, lower=np.array([0.0]))
    assert held.c[0] == 0.0
    assert abs(held.c_free[0] + 0.5) < 0.05
    alone = profiled_fit(without, 600, pi0, 0)
    np.testing.assert_allclose(held.pi, alone.pi, rtol=1e-5)
    inside = profiled_fit(_gram(0.5)[0], 600, pi0, 1, lower=np.array([0.0]))
    assert abs(inside.c[0] - 0.5) < 0.05 and inside.c[0] == inside.c_free[0]


def test_projected_newton_step_worked_by_hand():
    """Info = [[2, 1], [1, 2]], g = [-1, 0.5] at x0 = [0.1, 0.1], x_0 >= 0: the free step
    d = Info^-1 g = [-5/6, 2/3] crosses the bound; held at x_0 = 0 (d_0 = -0.1) the other
    is d_1 = (0.5 - 1 * (-0.1)) / 2 = 0.3, so x1 = [0, 0.4]. Without a bound: the free
    step."""
    info = np.array([[2.0, 1.0], [1.0, 2.0]])
    g = np.array([-1.0, 0.5])
    x0 = np.array([0.1, 0.1])
    np.testing.assert_allclose(projected_newton(x0, g, info, np.array([0.0, -np.inf])),
                               [0.0, 0.4], atol=1e-15)
    np.testing.assert_allclose(projected_newton(x0, g, info, np.full(2, -np.inf)),
                               x0 + np.array([-5 / 6, 2 / 3]), atol=1e-15)


def _found(drag, free, se):
    """A DiscoveryResult holding drag alone (its selection score, held-out RMS)."""
    return DiscoveryResult(
        ("drag",), {"drag": np.asarray(drag)}, {"drag": np.asarray(se)},
        (CandidateScore("drag", 0, 0.4, 30.0, 20.0, tuple(drag), True),),
        {"force_x": 0.01}, {"force_x": 0.006}, 0.035, np.diag([1.6e-5, 1.7e-5, 3e-5]),
        None, None, "v", coefficients_free={"drag": np.asarray(free)} if free else {})


def test_a_coefficient_on_the_edge_is_reported_as_such():
    """D_z held at 0 from a free -0.0040 ± 0.0026: report.json names it on the edge with
    its free fit and domain, and the printed line says so; D_x inside is printed as
    before."""
    found = _found([0.012, 0.013, 0.0], [0.012, 0.013, -0.0040], [0.001, 0.001, 0.0026])
    section = DiscoveryOutcome(found, floor=FloorLevel(0.064, "contact", 78)).to_report()
    entry = section["selected"][0]
    assert entry["on_domain_edge"] == ["D_z"]
    assert entry["domain"] == {"D_x": ">= 0", "D_y": ">= 0", "D_z": ">= 0"}
    assert entry["coefficients_without_domain"]["D_z"] == pytest.approx(-0.0040)
    assert section["ground_effect_floor"]["height"] == 0.064
    text = discovery_summary(section)
    assert ("D_z = 0 ± 0.0026 N s/m (on the edge of its domain D_z >= 0; without it -0.004)"
            in text)
    assert "D_x = 0.012 ± 0.001 N s/m," in text
    inside = DiscoveryOutcome(_found([0.012, 0.013, 0.002], None,
                                     [0.001, 0.001, 0.0026])).to_report()
    assert inside["selected"][0]["on_domain_edge"] == []
    assert inside["selected"][0]["coefficients_without_domain"] is None


def test_an_effect_wholly_on_the_edge_is_not_kept():
    """A drag held at 0 on all three axes (free fits within 2 standard errors below 0)
    adds nothing: not kept, with the reason; one with D_x and D_y inside is kept; a
    ground effect held at k_ge = 0 near the floor is not kept either."""
    low = np.full(20, 0.02)
    gone = _found([0.0, 0.0, 0.0], [-0.001, -0.0005, -0.004], [0.001, 0.001, 0.0026])
    why = outside_domain(gone, low, 0.046)
    assert set(why) == {"drag"} and "every coefficient is on its domain's edge" in why["drag"]
    kept = _found([0.012, 0.013, 0.0], [0.012, 0.013, -0.004], [0.001, 0.001, 0.0026])
    assert outside_domain(kept, low, 0.046) == {}
    ground = replace(kept, selected=("ground_effect",),
                     coefficients={"ground_effect": np.array([0.0])},
                     stderr={"ground_effect": np.array([0.2])},
                     coefficients_free={"ground_effect": np.array([-0.3])})
    assert "edge" in outside_domain(ground, low, 0.046)["ground_effect"]


def test_the_reach_check_takes_the_height_above_the_floor():
    """The smoothed path z = 0.07..0.47 m with v_z = 2 m/s over a floor at 0.06 m: the
    heights the reach check sees are z - 0.06 on the transitions the M-step uses (the
    excluded one left out), worked by hand; a flight that stays 1-2 cm above that floor
    keeps its ground effect, one 40 cm up does not."""
    n = 6
    mean = np.zeros((n, 12))
    mean[:, 2] = 0.07 + 0.08 * np.arange(n)
    mean[:, 5] = 2.0
    exclude = np.zeros(n, dtype=bool)
    exclude[2] = True
    obs = Observations(t=0.01 * np.arange(n), dt=0.01, inputs=np.zeros((n, 4)),
                       channels=("pos",), ys=np.zeros((n, 3)), x0=np.zeros(12),
                       p0=np.ones(12), exclude=exclude, floor=FloorLevel(0.06, "contact", 9))
    np.testing.assert_allclose(transition_heights(obs, mean), [0.01, 0.09, 0.25, 0.33],
                               atol=1e-12)
    near = replace(_found([0.01, 0.01, 0.01], None, [0.001] * 3), selected=("ground_effect",),
                   coefficients={"ground_effect": np.array([0.8])},
                   stderr={"ground_effect": np.array([0.1])})
    assert outside_domain(near, transition_heights(obs, mean), 0.046) == {}
    high = replace(obs, floor=FloorLevel(-0.4, "contact", 9))
    assert "never comes within" in outside_domain(near, transition_heights(high, mean),
                                                  0.046)["ground_effect"]


def _shifted(log, dz: float):
    pos = log.position.copy()
    pos[:, 2] += dz
    return replace(log, position=pos)


def _ground_regressor(obs: Observations, z: np.ndarray) -> np.ndarray:
    """The ground-effect column at heights z (world, m) with the log's thrust."""
    x = np.zeros((obs.n, 12))
    x[:, 2] = z
    return wrench_features("ground_effect", TransitionData.of(obs, x, np.arange(obs.n)))[:, 2, 0]


def test_the_floor_of_a_flightgen_flight_and_of_its_shifted_copy(tmp_path):
    """flightgen (floor plane z = 0, its contact sinks g / w_c^2 = 0.25 mm under the
    weight) takes off, strikes and lands: the floor the log shows is within 3 mm of 0;
    the same log written with every height 6 cm up (pinquad's writer) shows it 6 cm up,
    and the ground-effect regressor at the shifted heights equals the original's, the
    hand-computed F (r / 4 max(h, r/2))^2 at the height h above the floor."""
    flight = generate(FlightSpec(duration=8, trajectory="minsnap", log_rate=100,
                                 start_on_floor=True, land=True, floor_strikes=1, seed=5))
    write_csv(flight, tmp_path / "flight.csv")
    log = read_log(tmp_path / "flight.csv")
    obs = observations(log, "B", floor_contact(log, 0.035))
    assert obs.floor.source == "contact" and abs(obs.floor.height) < 0.003
    write_log(_shifted(log, 0.06), tmp_path / "up.csv")
    up = read_log(tmp_path / "up.csv")
    obs_up = observations(up, "B", floor_contact(up, 0.035))
    assert obs_up.floor.height - obs.floor.height == pytest.approx(0.06, abs=1e-9)
    h = np.linspace(0.0, 0.3, obs.n)
    base = _ground_regressor(obs, obs.floor.height + h)
    np.testing.assert_allclose(_ground_regressor(obs_up, obs_up.floor.height + h), base,
                               rtol=1e-6)
    r = obs.ground_radius
    by_hand = obs.inputs[:, 0] * (r / (4.0 * np.maximum(h, r / 2))) ** 2
    np.testing.assert_allclose(base, by_hand, rtol=1e-6)


def test_a_neural_swarm_flight_natively_and_shifted_to_its_floor(tmp_path):
    """randomwalk_l_cf102_01 (Parrot frame; the data set puts the floor plane at 0.06 m
    in the log's frame) shows its floor 6.4 cm up; written with the heights shifted
    down by 0.06 m it shows it at 0.4 cm: the heights above the floor, and so the
    ground-effect regressor, are the same."""
    log = read_log(NEURAL_SWARM / "randomwalk_l_cf102_01")
    obs = observations(log, "B", floor_contact(log, 0.05))
    assert abs(obs.floor.height - 0.06) < 0.006
    write_log(_shifted(log, -0.06), tmp_path / "floor.csv")
    low = read_log(tmp_path / "floor.csv")
    obs_low = observations(low, "B", floor_contact(low, 0.05))
    assert obs.floor.height - obs_low.floor.height == pytest.approx(0.06, abs=1e-9)
    # the written sidecar names the reader's default vehicle ("paper"), whose ground-effect
    # radius differs: compare the law at the native reading's radius
    obs_low = replace(obs_low, ground_radius=obs.ground_radius)
    z = np.nan_to_num(log.position[:, 2], nan=0.3)
    np.testing.assert_allclose(_ground_regressor(obs_low, z - 0.06),
                               _ground_regressor(obs, z), rtol=1e-9)
