"""Closed-loop Euler-Maruyama simulation of the paper's SDE quadcopter.

    x_{k+1} = x_k + dt f(x_k, u_k + n_k),   n_k ~ N(0, S / dt)

with f evaluated by Pinocchio's ABA on the free-flyer (``model.forward_dynamics``), S the
wrench noise intensity (noise on thrust and torques, as in the paper) and a floor at
z = 0: the vehicle rests on it while thrust cannot lift it (contact rows are flagged).

On board: sensor A (motion capture + IMU) feeds the paper's sensor-A EKF, whose estimate
feeds the LQG controller, which computes F and M from the controller's current mass
and inertia (fixed, or updated by an online estimator through ``on_step``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import rotation_from_euler
from pinquad.core.params import (
    FROZEN_SENSOR_NOISE,
    PAPER_SCENARIO,
    PAPER_VEHICLE,
    ProcessNoise,
    Scenario,
    SensorNoise,
    Vehicle,
    process_noise_for,
)
from pinquad.io.logs import FlightLog, LogMeta
from pinquad.models.navigation import (
    ModelBasedNavFilter,
    NavTuning,
    SensorANavModel,
    StreamingNavFilter,
)
from pinquad.models.sources import SOURCE_CHANNELS
from pinquad.sim.control import (
    ControllerGains,
    ReferenceTrajectory,
    build_reference,
    control_step,
    design_gains,
)
from pinquad.sim.sensors import SENSORS, measure_one
from pinquad.vehicle.model import forward_dynamics, load_model

Array = NDArray[np.float64]

@dataclass(frozen=True)
class ControllerUpdate:
    """What an online estimator hands the controller after step k's measurements.

    mass [kg], inertia (3, 3) [kg m^2]: the controller's new estimates;
    thrust_override [N] or None: fly this collective thrust instead of the position
    loop's (a take-off ramp while on the floor); reference_start: the step at which the
    reference trajectory starts (the controller tracks reference index k - start).
    """

    mass: float
    inertia: Array
    thrust_override: float | None = None
    reference_start: int = 0


ParamUpdate = Callable[[int, "FlightSoFar"], "ControllerUpdate | None"]
"""Online hook: called after step k's measurements; may return a ControllerUpdate that
holds from step k on."""


@dataclass(frozen=True)
class Disturbance:
    """A physical effect injected into the true vehicle (see ``pinquad.sim.effects``).

    ``wrench(x, u, t)`` -> extra body wrench (6,) [N, N m] at the body origin;
    ``actuation(u_cmd, u_prev, dt)`` -> the actuation that reaches the body (4,);
    ``gyro_bias`` (3,) [rad/s] added to every gyro sample; ``for_vehicle(vehicle)`` ->
    the disturbance to fly on that vehicle, for an effect that depends on it (the ground
    effect's radius is the flown vehicle's footprint): the simulator flies that instead.
    """

    name: str
    wrench: Callable[[Array, Array, float], Array] | None = None
    actuation: Callable[[Array, Array, float], Array] | None = None
    gyro_bias: Array | None = None
    for_vehicle: Callable[[Vehicle], Disturbance] | None = None


@dataclass(frozen=True)
class SimConfig:
    """Everything a simulated flight depends on besides the random generator.

    sensor: the sensor set the vehicle flies with (A, B or C); its samples feed the
    onboard filter and are what the log records, so the logged actuation is a function
    of the logged measurements (closed-loop data the direct EM method can use).
    nav_initial_error: start the onboard filter from the true state plus a draw from its
    prior (for consistency checks); by default it starts from the known resting pose,
    so the commands stay a function of the logged data alone.
    controller_mass [kg] / controller_inertia (3, 3): the controller's initial
    estimates (default: the truth). thrust_max_factor: maximum thrust as a multiple of
    the true weight. settle_time [s]: flight time after the last waypoint is reached.
    """

    vehicle: Vehicle = PAPER_VEHICLE
    scenario: Scenario = PAPER_SCENARIO
    sensor: str = "A"
    process_noise: ProcessNoise | None = None
    sensor_noise: SensorNoise = FROZEN_SENSOR_NOISE
    nav_tuning: str = "tuned"
    controller_mass: float | None = None
    controller_inertia: Array | None = None
    nav_initial_error: bool = False
    thrust_max_factor: float = 2.5
    settle_time: float = 1.0
    disturbances: tuple[Disturbance, ...] = ()
    gains: ControllerGains = field(default_factory=design_gains)

    def noise(self) -> ProcessNoise:
        return self.process_noise or process_noise_for(self.vehicle)


@dataclass
class FlightSoFar:
    """Mutable buffers of the flight in progress, read by an online estimator.

    t (N,), thrust/torque (N,), (N, 3) commanded actuation; position, accel, gyro (N, 3)
    sensor-A measurements; nav_state (N, 12) onboard EKF estimate; velocity/euler (N, 3)
    the other sensors' samples (for sensors B and C); contact_est (N,) bool.
    Only rows 0..k are filled when the hook is called at step k.
    """

    t: Array
    thrust: Array
    torque: Array
    position: Array
    velocity: Array
    euler: Array
    gyro: Array
    accel: Array
    nav_state: Array
    contact: NDArray[np.bool_]


@dataclass(frozen=True)
class Flight:
    """A finished simulated flight.

    t (N,) [s]; states (N, 12) true; inputs (N, 4) commanded [F, M] (what the log
    records); applied (N, 4) actuation including noise and disturbances; specific_force
    (N, 3) true body specific force [m/s^2]; nav_state (N, 12) onboard sensor-A EKF
    estimate; nav_cov (N, 12, 12); contact (N,) bool; reference; onboard: the
    samples of the flight's sensor set; waypoint_miss (M,) closest approach to each waypoint [m]; crashed;
    lifted_off; controller_params (N, 4): mass and inertia diagonal the controller used.
    """

    t: Array
    states: Array
    inputs: Array
    applied: Array
    specific_force: Array
    nav_state: Array
    nav_cov: Array
    contact: NDArray[np.bool_]
    reference: ReferenceTrajectory
    onboard: FlightSoFar
    waypoint_miss: Array
    crashed: bool
    lifted_off: bool
    controller_params: Array
    config: SimConfig


def _onboard_filter(config: SimConfig, suite, buf: FlightSoFar, inputs: Array, x0: Array,
                    mass: float, inertia: Array, rng: np.random.Generator
                    ) -> StreamingNavFilter | ModelBasedNavFilter:
    """The filter the vehicle flies with: the paper's sensor-A EKF for sensor A, the
    model-based EKF for B and C. Its initial mean is the true start perturbed by a draw
    from its own prior N(0, P0), so its covariance is honest from the first step."""
    dt = config.scenario.dt
    g = config.vehicle.gravity
    if config.sensor == "A":
        tuning = (NavTuning.paper() if config.nav_tuning == "paper"
                  else NavTuning.tuned(dt, config.sensor_noise))
        start = x0 + (np.sqrt(tuning.p0) * rng.standard_normal(12)
                      if config.nav_initial_error else 0.0)
        return StreamingNavFilter.start(SensorANavModel(buf.accel, dt, tuning, x0=start,
                                                        gravity=g))
    channels = SOURCE_CHANNELS[config.sensor]
    nz = config.sensor_noise
    per = {"pos": nz.position**2, "vel": nz.velocity**2, "euler": nz.euler**2,
           "gyro": nz.gyro**2}
    wrench = config.noise().wrench_intensity()
    wrench[0:2] = 1e-6 * wrench[2]
    p0 = np.full(12, 0.05**2)
    return ModelBasedNavFilter(
        channels=channels, inputs=inputs, dt=dt, wrench_intensity=wrench,
        meas_var=np.concatenate([np.full(3, per[c]) for c in channels]),
        x0=x0 + (np.sqrt(p0) * rng.standard_normal(12) if config.nav_initial_error else 0.0),
        p0=p0, mass=mass, inertia=inertia,
        gravity=g)


def _wrench_noise_std(noise: ProcessNoise, dt: float) -> Array:
    """Per-step standard deviation (4,) of [thrust, torque] noise for step dt."""
    s = noise.wrench_intensity()
    return np.sqrt(np.array([s[2], s[3], s[4], s[5]]) / dt)


def simulate(config: SimConfig, rng: np.random.Generator, on_step: ParamUpdate | None = None
             ) -> Flight:
    """Fly the scenario once. Randomness only from ``rng``."""
    veh = config.vehicle
    sc = config.scenario
    dt = sc.dt
    ref = build_reference(sc, final_hover=config.settle_time)
    n = ref.t.shape[0]
    pin_model = load_model(veh)
    pin_data = pin_model.createData()
    g = veh.gravity
    noise_std = _wrench_noise_std(config.noise(), dt)
    ctrl_mass = veh.mass if config.controller_mass is None else config.controller_mass
    ctrl_inertia = (np.array(veh.inertia, float) if config.controller_inertia is None
                    else np.array(config.controller_inertia, float))
    thrust_max = config.thrust_max_factor * veh.mass * g
    suite = SENSORS[config.sensor]
    suite = suite.__class__(**{**suite.__dict__, "noise": config.sensor_noise})
    # effects that depend on the vehicle (the ground effect's footprint) take this one's
    disturbances = tuple(d if d.for_vehicle is None else d.for_vehicle(veh)
                         for d in config.disturbances)
    gyro_bias = np.zeros(3)
    for dist in disturbances:
        if dist.gyro_bias is not None:
            gyro_bias = gyro_bias + dist.gyro_bias

    states = np.empty((n, 12))
    inputs = np.zeros((n, 4))
    applied = np.empty((n, 4))
    spec = np.empty((n, 3))
    nav_cov = np.empty((n, 12, 12))
    ctrl_params = np.empty((n, 4))
    contact = np.zeros(n, dtype=bool)
    buf = FlightSoFar(
        t=ref.t.copy(), thrust=np.full(n, np.nan), torque=np.full((n, 3), np.nan),
        position=np.full((n, 3), np.nan), velocity=np.full((n, 3), np.nan),
        euler=np.full((n, 3), np.nan), gyro=np.full((n, 3), np.nan),
        accel=np.full((n, 3), np.nan), nav_state=np.full((n, 12), np.nan),
        contact=np.zeros(n, dtype=bool),
    )
    x = np.zeros(12)
    x[0:3] = sc.start
    x[8] = sc.yaw
    nav = _onboard_filter(config, suite, buf, inputs, x, ctrl_mass, ctrl_inertia, rng)
    resting = x[2] <= 0.0
    lifted = not resting
    crashed = False
    u_prev = np.array([veh.mass * g, 0.0, 0.0, 0.0])
    override: float | None = None
    ref_start = 0
    for k in range(n):
        states[k] = x
        contact[k] = resting
        u_noise = noise_std * rng.standard_normal(4)
        m_k = measure_one(suite, k, x, np.zeros(3), rng)
        gyro_meas = m_k.gyro + gyro_bias
        buf.position[k], buf.velocity[k], buf.euler[k] = m_k.position, m_k.velocity, m_k.euler
        buf.gyro[k] = gyro_meas
        if isinstance(nav, StreamingNavFilter):
            x_est = nav.correct(k, m_k.position, gyro_meas)
        else:
            blocks = {"pos": m_k.position, "vel": m_k.velocity, "euler": m_k.euler,
                      "gyro": gyro_meas}
            x_est = nav.correct(k, np.concatenate([blocks[c] for c in nav.channels]))
        buf.nav_state[k] = x_est
        nav_cov[k] = nav.cov
        buf.contact[k] = resting
        if on_step is not None:
            upd = on_step(k, buf)
            if upd is not None:
                if upd.mass != ctrl_mass or not np.array_equal(upd.inertia, ctrl_inertia):
                    ctrl_mass, ctrl_inertia = float(upd.mass), np.array(upd.inertia, float)
                    if isinstance(nav, ModelBasedNavFilter):
                        nav.set_params(ctrl_mass, ctrl_inertia)
                override, ref_start = upd.thrust_override, upd.reference_start
                if isinstance(nav, ModelBasedNavFilter):
                    nav.set_grounded(override is not None)
        ctrl_params[k] = [ctrl_mass, *np.diag(ctrl_inertia)]
        out = control_step(x_est, max(k - ref_start, 0), ref, config.gains, ctrl_mass,
                           ctrl_inertia, g, (0.0, thrust_max))
        u = out.u
        if override is not None:
            u = u.copy()
            u[0] = min(max(override, 0.0), thrust_max)
        inputs[k] = u
        buf.thrust[k] = u[0]
        buf.torque[k] = u[1:4]
        u_act = u.copy()
        extra = np.zeros(6)
        for dist in disturbances:
            if dist.actuation is not None:
                u_act = dist.actuation(u_act, u_prev, dt)
        u_prev = u_act
        u_true = u_act + u_noise
        u_true[0] = max(u_true[0], 0.0)
        for dist in disturbances:
            if dist.wrench is not None:
                extra = extra + dist.wrench(x, u_true, float(ref.t[k]))
        applied[k] = u_true
        xdot = forward_dynamics(pin_model, pin_data, x, u_true, extra)
        rot = rotation_from_euler(x[6:9])
        if resting and xdot[5] <= 0.0:
            xdot = np.zeros(12)
        # The accelerometer sample of step k is the specific force of the step k -> k+1.
        spec[k] = rot.T @ (xdot[3:6] + np.array([0.0, 0.0, g]))
        if suite.accel_every > 0 and k % suite.accel_every == 0:
            buf.accel[k] = spec[k] + config.sensor_noise.accel * rng.standard_normal(3)
        nav.advance(k)
        x_next = x + dt * xdot
        if x_next[2] < 0.0 or (x_next[2] <= 0.0 and x_next[5] <= 0.0):
            if lifted and (x_next[5] < -1.0 or abs(x_next[6]) > 1.2 or abs(x_next[7]) > 1.2):
                crashed = True
            x_next[2] = 0.0
            x_next[3:6] = 0.0
            x_next[6:8] = 0.0
            x_next[9:12] = 0.0
            resting = True
        else:
            resting = False
            lifted = lifted or x_next[2] > 0.02
        x = x_next
    dists = np.linalg.norm(states[None, :, 0:3] - sc.waypoints[:, None, :], axis=2)
    # an online run that waited on the floor ends before its reference does

    return Flight(
        t=ref.t.copy(), states=states, inputs=inputs, applied=applied, specific_force=spec,
        nav_state=buf.nav_state.copy(), nav_cov=nav_cov, contact=contact, reference=ref,
        onboard=buf, waypoint_miss=dists.min(axis=1), crashed=crashed, lifted_off=lifted,
        controller_params=ctrl_params, config=config,
    )


def flight_log(flight: Flight, mass_guess: float | None = None,
               inertia_guess: Array | None = None) -> FlightLog:
    """The log of a flight: the samples of the sensor set it flew with (NaN where not
    sampled), the onboard filter's estimate, the commanded thrust and torques, contact
    flags and the truth."""
    cfg = flight.config
    buf = flight.onboard
    meta = LogMeta(vehicle=cfg.vehicle.name, mass_guess=mass_guess,
                   inertia_guess=None if inertia_guess is None else np.asarray(inertia_guess),
                   gravity=cfg.vehicle.gravity, source=f"simulation (sensor {cfg.sensor})",
                   calibration=(0.0, 0.0, 0.0))  # the applied wrench, exactly
    return FlightLog(
        t=flight.t.copy(), position=buf.position.copy(), velocity=buf.velocity.copy(),
        euler=buf.euler.copy(), gyro=buf.gyro.copy(), accel=buf.accel.copy(),
        thrust=flight.inputs[:, 0].copy(), torque=flight.inputs[:, 1:4].copy(),
        contact=flight.contact.copy(), truth=flight.states.copy(),
        onboard=flight.nav_state.copy(), meta=meta,
    )


def waypoint_report(flight: Flight) -> dict[str, float | bool]:
    """Closest approach [m] to each waypoint, crash and lift-off flags."""
    return {
        "max_miss_m": float(flight.waypoint_miss.max()),
        "crashed": bool(flight.crashed),
        "lifted_off": bool(flight.lifted_off),
        "duration_s": float(flight.t[-1] + flight.config.scenario.dt),
        "tilt_max_rad": float(np.max(np.abs(flight.states[:, 6:8]))),
        "speed_max": float(np.max(np.linalg.norm(flight.states[:, 3:6], axis=1))),
        "steps": int(flight.t.shape[0]),
        "hover_thrust_ratio": float(np.median(flight.inputs[:, 0]) /
                                    (flight.config.vehicle.mass * flight.config.vehicle.gravity)),
        "angle_rms": float(math.sqrt(np.mean(flight.states[:, 6:8] ** 2))),
    }
