"""Measured Crazyflie flights as EM observations on a uniform grid.

A micro-SD log (``pinquad.io.sdlog``, ~500 Hz ``fixedFrequency`` rows plus motion capture
at ~55 Hz on average) becomes :class:`~pinquad.models.ssm.Observations` on a uniform grid
t_k = t_0 + k dt, dt = 0.01 s. Rows are placed by their time on the log's own clock
(``io.timebase.clock_times``: a steady clock fitted through the stamps, so a few ms of
stamp jitter or a Unix-time offset moves no row), and the grid is anchored on the middle
row (``io.timebase.grid_times``). Each bin's value moves continuously with the rows'
times (``realdata.resample``), so no row jumps from one bin to the next:

* gyro, accelerometer, onboard velocity: the mean, over the bin t in [t_k - dt/2,
  t_k + dt/2) (centred, so it estimates the value at t_k), of the straight line through
  the samples at the bin's row points (``resample.sample_average``);
* inputs u_k = [F, M_x, M_y, M_z] over [t_k, t_k + dt): the wrench of the bin's mean rotor
  speeds (the same points, forward bin), F = kf sum_i omega_i^2 [N], M = mixer
  (``ActuatorModel``) [N m], which is what the resampled log carries, so its export
  reads back to the same inputs; speeds held from row to row (a sidecar's
  ``"actuation": "held"``) give the bin's exact time average of the wrench
  (``resample.held_average``). The forward bin is what the explicit-Euler transition
  x_{k+1} = x_k + dt f(x_k, u_k) integrates: v_{k+1} - v_k = int_{t_k}^{t_k+dt} a dt;
* motion-capture position [m] and Euler angles [rad] (``locSrv`` quaternion), each pose
  on the stream's frame clock (``resample.pose_stream_times``): a grid step with a pose
  within dt/2 reads it at t_k, along the straight line to the next pose on t_k's other
  side (up to ``resample.POSE_BRIDGE_S`` away), else NaN (a dropout is a missing sample);
  a pose more than ``outlier_m`` / ``outlier_rad`` from the median of its neighbours is
  a tracking glitch and is dropped too.

Transitions k -> k+1 the M-step must skip (``Observations.exclude``): ground contact and
the take-off / landing around it (height below ``contact_height`` at low speed, or rotors
below flight speed, or found resting on / striking the floor by the detector shared with
logs that carry thrust and torques, ``models.contact``; widened by ``contact_margin``
seconds), implausible rotor readings (``faults.detect_actuation_faults``) unless
repaired from the PWM commands, log gaps and bins without a finite actuation value
(``realdata.input_holes``; a gap, or a bin whose every sample was flagged implausible
and not rebuilt, is also a reset, ``Observations.resets``: the smoother does not carry
the flight dynamics across it); a bin without a row outside a gap (jitter, a slow log)
gets an interpolated input.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from pinquad.core.conventions import rotation_from_euler
from pinquad.identification.measured import Exclusion
from pinquad.io.logs import FlightLog, LogMeta
from pinquad.io.timebase import clock_times, grid_times, sampling_interval
from pinquad.models.attitude_range import near_euler_singularity
from pinquad.models.contact import ContactSettings, detect_floor_contact, floor_level
from pinquad.models.ssm import Observations
from pinquad.realdata.dataset import default_guess
from pinquad.realdata.faults import (
    ActuationFaultReport,
    detect_actuation_faults,
    diagonal_partners,
    no_actuation_message,
    reconstruct_rpm,
)
from pinquad.realdata.input_holes import input_holes
from pinquad.realdata.observation_options import RealDataOptions
from pinquad.realdata.raw import PoseSamples, RawFlight, raw_from_simulated
from pinquad.realdata.resample import (
    bin_mean,
    fill_rows,
    held_average,
    interp_nan,
    pose_glitches,
    pose_stream_times,
    poses_on_grid,
    sample_average,
)
from pinquad.realdata.rotor_acceleration import (
    grid_rotor_acceleration,
    held_grid_rotor_acceleration,
)
from pinquad.realdata.thrust import thrust_coefficient
from pinquad.sim.simulator import Flight
from pinquad.vehicle.actuators import (
    KF_CRAZYFLIE,
    ActuatorModel,
    ThrustCoefficient,
)

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

# ----------------------------------------------------------------------------- result

@dataclass(frozen=True)
class RealObservations:
    """A measured flight ready for EM.

    obs: the E-step's Observations on the grid (N steps of dt); log: the resampled
    flight (N rows: mocap position / Euler, onboard velocity, gyro, accelerometer,
    rotor speeds after repair, thrust [N] and torque [N m] = obs.inputs);
    exclusions: why transitions were skipped, with counts; notes: what else was done
    (repairs, dropouts, glitches) in words; faults: the actuation fault report of the
    original-rate log; kf: the thrust coefficient used; source: the file; repaired:
    motors (0-based) whose readings were rebuilt from PWM; rotor_acc (N,) [rad/s^2]: mean
    over [t_k, t_k + dt) of sum_i spin_i d(omega_i)/dt (from the bins' mean speeds,
    ``rotor_acceleration.grid_rotor_acceleration``; held speeds: each bin's change of speed,
    ``held_grid_rotor_acceleration``; gaps
    interpolated), the regressor of the rotor-inertia yaw torque J_r * rotor_acc;
    rebuilt_fraction (N,) [-]: share of the log's rotor samples in [t_k, t_k + dt) with a
    speed taken from the PWM map (1 for a bin without samples; None: not recorded).
    """

    obs: Observations
    log: FlightLog
    exclusions: tuple[Exclusion, ...]
    notes: tuple[str, ...]
    faults: ActuationFaultReport
    kf: ThrustCoefficient
    source: str
    options: RealDataOptions = field(default_factory=RealDataOptions)
    repaired: tuple[int, ...] = ()
    rotor_acc: Array | None = None
    rebuilt_fraction: Array | None = None

    @property
    def n_transitions(self) -> int:
        return self.obs.n - 1

    @property
    def n_excluded(self) -> int:
        return int(self.obs.exclude[: self.obs.n - 1].sum())

    @property
    def n_used(self) -> int:
        return self.n_transitions - self.n_excluded

    @property
    def excluded(self) -> tuple[str, ...]:
        """Human-readable exclusion list: one line per reason with its count, then the
        total."""
        lines = [f"{e.transitions} transitions: {e.reason}" for e in self.exclusions
                 if e.transitions]
        lines.append(f"total: {self.n_excluded} of {self.n_transitions} transitions excluded, "
                     f"{self.n_used} used ({self.obs.dt * 1e3:.0f} ms each)")
        return tuple(lines)


# ----------------------------------------------------------------------------- build

def _repair(raw: RawFlight, report: ActuationFaultReport, mode: str,
            partners: Sequence[int | None]) -> tuple[Array, BoolArray, BoolArray, list[str]]:
    """Rotor speeds (N, n) after the chosen fault handling, rows (N,) still untrusted,
    readings (N, n) taken from the PWM map, and notes. partners: each rotor's diagonal
    partner (``faults.diagonal_partners``) or None. Raises ValueError if the log's PWM
    commands do not have one column per rotor speed."""
    log = raw.log
    rpm = np.asarray(log.rpm, dtype=float)
    n_rotors = rpm.shape[1]
    untrusted = report.motor_mask | report.unreliable[None, :]
    notes: list[str] = []
    none = np.zeros((log.n, n_rotors), dtype=bool)
    if not untrusted.any():
        return rpm, np.zeros(log.n, dtype=bool), none, notes
    if mode == "exclude" or raw.pwm is None or not np.isfinite(raw.pwm).all():
        if mode != "exclude":
            notes.append("implausible rotor speeds cannot be rebuilt (no PWM in the log): "
                         "their rows are excluded")
        return rpm, untrusted.any(axis=1), none, notes
    if raw.pwm.shape != rpm.shape:
        raise ValueError(f"{log.meta.source}: {raw.pwm.shape[1]} PWM commands per row but "
                         f"{n_rotors} rotor speeds; PWM repair needs one command per rotor "
                         "(or --faults exclude)")
    bad_motors = [i for i in range(n_rotors) if untrusted[:, i].any()]
    paired = all(partners[i] is not None and not untrusted[:, partners[i]].any()
                 for i in bad_motors)
    if mode == "repair" and paired:
        # A motor's diagonal partner spins the same way with the same propeller type;
        # on the clean flights the PWM -> rpm map of M3 alone predicts M1's mean speed
        # to +0.5 % on average, the map of all three other motors to +2 %.
        out = rpm.copy()
        rebuilt = none.copy()
        for i in bad_motors:
            partner = partners[i]
            assert partner is not None
            others = tuple(j for j in range(n_rotors) if j != partner)
            rec = reconstruct_rpm(log, raw.pwm, report, replace_motors=others)
            out[untrusted[:, i], i] = rec.rpm[untrusted[:, i], i]
            rebuilt[:, i] = untrusted[:, i] & rec.replaced[:, i]
            notes.append(f"M{i + 1}: {int(rebuilt[:, i].sum())} readings rebuilt from its PWM "
                         f"through the PWM -> rpm map of its diagonal partner M{partner + 1} "
                         f"(first-order lag {rec.tau * 1e3:.0f} ms, map residual "
                         f"{rec.fit_rms:.0f} rev/min)")
            div = rec.divisions[i]
            if div is not None and div.divisor > 1:
                notes.append(div.describe(i))
        return out, np.zeros(log.n, dtype=bool), rebuilt, notes
    if mode == "repair":
        notes.append("a rotor without a trusted diagonal partner (untrusted too, or none in "
                     "this geometry): map learned on all trusted motors")
    rec = reconstruct_rpm(log, raw.pwm, report)
    notes.extend(rec.notes)
    return rec.rpm, np.zeros(log.n, dtype=bool), rec.replaced, notes


def build_observations(raw: RawFlight, options: RealDataOptions | None = None,
                       kf: ThrustCoefficient | None = None) -> RealObservations:
    """Resample a measured flight to the grid and build the EM observations (module
    docstring). Raises ValueError if nothing usable remains."""
    options = options or RealDataOptions()
    log = raw.log
    source = log.meta.source
    if log.rpm is None:
        raise ValueError(f"{source}: the log has no rotor speeds (rpm_1..rpm_4); expected "
                         "rpm columns to compute thrust and torques")
    if log.n < 10:
        raise ValueError(f"{source}: only {log.n} samples; expected a flight of at least 10")
    if kf is None:
        kf = (thrust_coefficient() if options.kf is None else
              ThrustCoefficient(options.kf, 0.05 * options.kf, (), options.kf,
                                f"kf = {options.kf:.4e} N/(rad/s)^2 given (5 % assumed)"))
    notes: list[str] = [kf.note]
    dt = options.dt

    actuator = ActuatorModel(kf=kf.kf, arm=options.arm, yaw_ratio=options.yaw_ratio,
                             spin=options.spin, xy=options.xy)
    if log.rpm.shape[1] != actuator.n_rotors:
        raise ValueError(f"{source}: the log has {log.rpm.shape[1]} rotor speeds per row but "
                         f"the vehicle has {actuator.n_rotors} rotors; give the vehicle file "
                         "that matches the log (--vehicle FILE)")
    # Diagonal partners from the vehicle's geometry (the Crazyflie's: M1-M3, M2-M4).
    partners = diagonal_partners(actuator.positions, actuator.spin)
    report = detect_actuation_faults(log, flight_rpm=options.flight_rpm,
                                    max_rpm=options.max_rpm, partners=partners)
    rpm, untrusted_rows, rebuilt, repair_notes = _repair(raw, report, options.faults, partners)
    untrusted_motors = report.motor_mask | report.unreliable[None, :]
    notes.extend(repair_notes)
    if report.vbat_stuck:
        notes.append(f"battery voltage stuck at {report.vbat_value:.2f} V: not used")
    finite_rpm = np.isfinite(rpm).all(axis=1)
    thrust = np.full(log.n, np.nan)
    torque = np.full((log.n, 3), np.nan)
    if finite_rpm.any():
        thrust[finite_rpm], torque[finite_rpm] = actuator.wrench(rpm[finite_rpm])
    # Rotor speeds held over each row (a table whose sidecar declares "actuation":
    # "held", as the simulator's rotor log does), else sampled readings (micro-SD logs) or
    # their bin means (a measured flight's export, whose wrench is "from rpm").
    held = (log.measured is None and log.meta.actuation == "held"
            and not log.meta.wrench_from_rpm)
    # Untrusted rows carry no input: their bins become NaN and are excluded below.
    wrench = np.column_stack([thrust, torque])
    wrench[untrusted_rows] = np.nan

    # rows binned by their time on the log's clock, not by their jittered stamps
    t_src = clock_times(log.t)
    grid = grid_times(t_src, dt)
    k = grid.size
    centred = grid - 0.5 * dt
    row_step = sampling_interval(t_src)

    def centred_mean(values: Array) -> Array:  # a reading's mean around t_k
        return sample_average(t_src, values, centred, dt, k, row_step, 0.5)

    def forward_mean(values: Array) -> Array:  # over [t_k, t_k + dt)
        if held:
            return held_average(t_src, values, grid, dt, k)
        return sample_average(t_src, values, grid, dt, k, row_step, 0.0)

    gyro, accel, vel = (centred_mean(x) for x in (log.gyro, log.accel, log.velocity))
    rpm_g = forward_mean(np.where(untrusted_rows[:, None], np.nan, rpm))
    rebuilt_g = bin_mean(t_src, rebuilt.any(axis=1).astype(float), grid, dt, k)[:, 0]
    if held:  # speeds held over each row: the bin's exact time average of the wrench
        inputs = forward_mean(wrench)
    else:  # readings: the wrench of the bin's mean speeds, as the resampled log carries it
        inputs = np.full((k, 4), np.nan)
        finite_bins = np.isfinite(rpm_g).all(axis=1)
        if finite_bins.any():
            inputs[finite_bins, 0], inputs[finite_bins, 1:] = actuator.wrench(rpm_g[finite_bins])
    if held:  # the bin's change of speed over dt, exactly, whatever the stamps' jitter
        rotor_acc_g = interp_nan(grid, held_grid_rotor_acceleration(
            t_src, np.where(untrusted_rows[:, None], np.nan, rpm), options.spin, grid, dt))
    else:  # sampled readings: from the bin means, as the resampled log carries them
        rotor_acc_g = interp_nan(grid, grid_rotor_acceleration(fill_rows(grid, rpm_g),
                                                               options.spin, dt))
    if options.rotor_inertia:  # None (not fixed) and 0 add nothing
        inputs[:, 3] += options.rotor_inertia * rotor_acc_g
    vbat = None
    if log.vbat is not None and not report.vbat_stuck:
        vbat = centred_mean(log.vbat)[:, 0]
    onboard_pos = None
    if raw.onboard_pos is not None:
        onboard_pos = centred_mean(raw.onboard_pos)

    # Motion capture: the grid steps with a sample within half a bin.
    if raw.pose is not None:  # its own stamps: on its frame clock, else the rows' clock
        pose_t, pose_note = pose_stream_times(raw.pose.t, log.t, t_src)
        pose = replace(raw.pose, t=pose_t)
        notes += [pose_note] if pose_note else []
    else:
        pose = PoseSamples(t=t_src, position=log.position, euler=log.euler)
    has_pose = np.isfinite(pose.position).all(axis=1) | np.isfinite(pose.euler).all(axis=1)
    p_t, p_pos, p_eul = pose.t[has_pose], pose.position[has_pose], pose.euler[has_pose]
    glitch_pos = pose_glitches(p_pos, options.outlier_m)
    glitch_eul = pose_glitches(p_eul, options.outlier_rad, angle=True)
    p_pos = np.where(glitch_pos[:, None], np.nan, p_pos)
    p_eul = np.where(glitch_eul[:, None], np.nan, p_eul)
    position, euler = poses_on_grid(grid, p_t, p_pos, p_eul, dt)
    n_pose = int(np.isfinite(position).all(axis=1).sum())
    notes.append(f"motion capture: {p_t.size} poses; {n_pose} of {k} grid steps have one "
                 f"within {0.5 * dt * 1e3:.0f} ms ({100 * n_pose / k:.0f} %), the others are "
                 "missing samples")
    if glitch_pos.any() or glitch_eul.any():
        notes.append(f"motion capture: {int(glitch_pos.sum())} position / "
                     f"{int(glitch_eul.sum())} attitude samples more than "
                     f"{options.outlier_m * 100:.0f} cm / {options.outlier_rad:.2f} rad from the "
                     "median of their 6 neighbours dropped as tracking glitches")

    # --- exclusions (transitions k -> k+1)
    exclusions: list[Exclusion] = []
    n_tr = k - 1
    exclude = np.zeros(k, dtype=bool)

    # Ground contact: near the floor and slow, or rotors below flight speed; widened by
    # the margin because take-off and landing mix contact forces and ground effect. Also
    # what the shared detector (models.contact) finds from height, velocity and thrust.
    z = position[:, 2]
    z_fill = interp_nan(grid, z)
    speed = np.linalg.norm(np.nan_to_num(vel), axis=1)
    rotors_idle = np.isfinite(rpm_g).all(axis=1)
    rotors_idle[rotors_idle] = np.median(rpm_g[rotors_idle], axis=1) < options.flight_rpm
    low = np.isfinite(z_fill) & (z_fill < options.contact_height) & (speed < options.contact_speed)
    heuristic = low | rotors_idle
    mass_guess = (log.meta.mass_guess if log.meta.mass_guess is not None
                  else default_guess(log.meta.vehicle)[0])
    found = detect_floor_contact(
        grid, z, vel[:, 2], inputs[:, 0], rotation_from_euler(euler)[:, 2, 2], mass_guess,
        log.meta.gravity, ContactSettings(margin=0.0), np.hypot(vel[:, 0], vel[:, 1]))
    detected = found.contact
    # the floor where contact shows: found from the data, or the rotors idle on it
    floor = floor_level(z, None, 1, detected | rotors_idle, found.floor_height)
    contact = heuristic | detected
    grow = int(round(options.contact_margin / dt))
    if contact.any():
        near = np.convolve(contact.astype(float), np.ones(2 * grow + 1), mode="same") > 0
        ex = near.copy()
        ex[:-1] |= near[1:]
        exclusions.append(Exclusion(
            "contact", f"ground contact, take-off or landing (height < {options.contact_height * 100:.0f} "
            f"cm at < {options.contact_speed:g} m/s, or median rotor speed < "
            f"{options.flight_rpm:.0f} rev/min: {int(heuristic.sum())} steps; found from the "
            f"data by models.contact: {int(detected.sum())} steps, "
            f"{int((detected & ~heuristic).sum())} of them not in the former; widened by "
            f"{options.contact_margin:g} s)", int(ex[:n_tr].sum())))
        exclude |= ex
    else:
        exclusions.append(Exclusion("contact", "ground contact, take-off or landing: none "
                                    "(airborne throughout: the logs start and end in flight)",
                                    0))

    # an attitude near the Euler singularity, cut out as in models.sources.observations
    singular = near_euler_singularity(grid, euler)
    if singular.rows.any():
        exclusions.append(Exclusion("attitude", singular.describe(),
                                    int((singular.touching() & ~exclude)[:n_tr].sum())))
        exclude |= singular.touching()

    flagged = np.zeros(k, dtype=bool)
    if untrusted_rows.any():
        # A bin with any untrusted sample is skipped, even if trusted samples remain.
        ex = bin_mean(t_src, untrusted_rows.astype(float), grid, dt, k)[:, 0] > 0
        flagged = ex
        exclusions.append(Exclusion(
            "faulty rpm", f"implausible rotor readings ({report.n_flagged} of {log.n} samples flagged by "
            "faults.detect_actuation_faults" + (", not repaired" if options.faults == "exclude"
                                                 else "") + ")", int(ex[:n_tr].sum())))
        exclude |= ex
    elif report.n_flagged:
        exclusions.append(Exclusion(
            "faulty rpm", f"implausible rotor readings: {report.n_flagged} of {log.n} samples flagged, all "
            "rebuilt from PWM (none excluded)", 0))

    nan_in = np.isnan(inputs).any(axis=1)
    holes = input_holes(t_src, grid, dt, nan_in)  # log gaps judged on the log's own step
    for kind, reason, ex in holes.exclusions():
        exclusions.append(Exclusion(kind, reason, int((ex & ~exclude)[:n_tr].sum()),
                                    holes.gaps if kind == "log gaps" else ""))
        exclude |= ex
    # A bin whose every actuation sample was flagged implausible and not rebuilt (a rotor
    # read as stopped in flight) gets an interpolated input only so the E-step can pass
    # over it: the log says the wrench there was something else, which it cannot give. The
    # transition is a reset (ssm.RESET_VAR), as a touch-down is: carried through the
    # flight dynamics, the made-up torque drags the smoothed rates away from the gyro and
    # inflates its variance for the whole flight (a simulated 250 mm quad's take-off with
    # stopped rotors: I_zz +9.4 % instead of +1.1 %). A log gap is a reset (input_holes).
    resets = (nan_in & flagged) | singular.touching() | holes.gap
    notes.extend(n for n in (holes.note(dt),) if n)
    if nan_in.all():
        raise ValueError(no_actuation_message(source, report, raw.pwm is not None,
                                              options.faults))
    inputs = np.column_stack([interp_nan(grid, inputs[:, c]) for c in range(4)])

    # --- measurements
    if options.onboard_pos and onboard_pos is None:
        raise ValueError(f"{source}: sensor A needs the onboard position estimate "
                         "(stateEstimate.x/y/z), which the log does not have")
    blocks = {"pos": onboard_pos if options.onboard_pos else position, "vel": vel,
              "euler": euler, "gyro": gyro}
    for ch in options.channels:
        if not np.isfinite(blocks[ch]).any():
            raise ValueError(f"{source}: measurement channel {ch!r} has no sample in the "
                             "log; expected motion capture (pos, euler), onboard velocity "
                             "(vel) or gyro samples")
    ys = np.column_stack([blocks[ch] for ch in options.channels])
    x0 = np.zeros(12)
    p0 = np.array([1e-2] * 3 + [0.25] * 3 + [1e-2] * 3 + [0.25] * 3)
    for sl, blk in ((slice(0, 3), blocks["pos"]), (slice(3, 6), vel), (slice(6, 9), euler),
                    (slice(9, 12), gyro)):
        ok = np.isfinite(blk).all(axis=1)
        if ok.any():
            x0[sl] = blk[np.argmax(ok)]
    # the ground-effect radius from the vehicle's geometry (the rotor footprint) unless given
    footprint = float(np.max(np.hypot(actuator.positions[:, 0], actuator.positions[:, 1])))
    # a measured flight moves continuously between bins (Observations.continuous)
    obs = Observations(t=grid - grid[0], dt=dt, inputs=inputs, channels=options.channels,
                       ys=ys, x0=x0, p0=p0, exclude=exclude, resets=resets,
                       ground_radius=footprint if options.ground_radius is None
                       else options.ground_radius, continuous=True, floor=floor)
    if obs.n < 3 or int((~exclude[:n_tr]).sum()) < 10:
        why = "; ".join(e.reason for e in exclusions if e.transitions)
        raise ValueError(f"{source}: only {int((~exclude[:n_tr]).sum())} usable transitions "
                         f"after exclusions ({why}); expected at least 10")

    meta = LogMeta(vehicle=log.meta.vehicle, mass_guess=log.meta.mass_guess,
                   inertia_guess=log.meta.inertia_guess, gravity=log.meta.gravity,
                   source=source, notes=tuple(log.meta.notes) + tuple(notes))
    resampled = FlightLog(t=obs.t, position=position, velocity=vel, euler=euler, gyro=gyro,
                          accel=accel, thrust=inputs[:, 0], torque=inputs[:, 1:4],
                          rpm=fill_rows(grid, rpm_g), vbat=vbat, meta=meta)
    repaired = tuple(int(i) for i in range(untrusted_motors.shape[1])
                     if untrusted_motors[:, i].any()) if not untrusted_rows.any() else ()
    return RealObservations(obs=obs, log=resampled, exclusions=tuple(exclusions),
                            notes=tuple(notes), faults=report, kf=kf, source=source,
                            options=options, repaired=repaired,
                            rotor_acc=np.nan_to_num(rotor_acc_g),
                            rebuilt_fraction=np.nan_to_num(rebuilt_g, nan=1.0))


def simulated_observations(flight: Flight) -> RealObservations:
    """A sensor-B simulated flight through the measured-flight path
    (``raw.raw_from_simulated``, then :func:`build_observations` with the shared kf)."""
    return build_observations(raw_from_simulated(flight), RealDataOptions(kf=KF_CRAZYFLIE))
