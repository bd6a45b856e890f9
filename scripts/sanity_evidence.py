"""The correct-log side of the physical checks (docs/bad_input.md): what each physical sanity check of
``pinquad.io.sanity`` measures on every shipped real Crazyflie log and on the simulated
flights of the paper's offline experiment (the default ``python -m pinquad.offline``:
20 cycles x sensors A, B, C, its flight seeds), and whether any check fires.

    PYTHONPATH=$PWD python scripts/sanity_evidence.py [CYCLES] [--flightgen N]

CYCLES: simulated cycles per sensor (default 20; about 1.5 s per flight). Prints one
row per log and a summary; exits 1 if any check fires on any of them.

A second table covers the single-column tests (``pinquad.io.units_check``,
``pinquad.io.actuation_check``) on the same logs plus the six Neural-Swarm flights,
the PX4 data-driven-dynamics sample (its kinematics; the ULog sample never arms) and
six flightgen flights, and ends with each test's weakest statistic against its
threshold (the margin).

A third table runs every check (``findings``) on N flights of the independent generator
``flightgen`` (default 60; about 2 s each): both of its vehicles, log rates 100, 250 and
500 Hz, gentle and aggressive, sums of sines and minimum-snap, clean and with each effect
(``flightgen_flights``), each written as its CSV and sidecar and read as a user reads it.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

from flightgen import CRAZYFLIE, QUAD_250, Effects, FlightSpec, generate, write_csv
from flightgen.trajectory import excursion
from flightgen.vehicle import Vehicle
from pinquad.core.params import PAPER_VEHICLE
from pinquad.experiments.discovery_mc_flightgen import LOWEST_PASS, flightgen_effects
from pinquad.experiments.offline_mc import flight_seed
from pinquad.io import actuation_check, units_check
from pinquad.io.read import read_command_log, read_log, with_vehicle
from pinquad.io.sanity import evidence, findings, implied_mass
from pinquad.sim.simulator import SimConfig, flight_log, simulate

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "crazyflie"
SHARED = DATA.parent


def _fmt(value: float | None, spec: str) -> str:
    return "-" if value is None else f"{value:{spec}}"


def _row(name: str, log) -> tuple[str, int]:
    ev = evidence(log)
    fired = findings(log)
    return (f"| {name} | {log.n} | {ev.dt * 1e3:.2f} | {_fmt(ev.gyro_ratio, '.3f')} | "
            f"{_fmt(ev.position_velocity_ratio, '.3f')} | {_fmt(ev.position_accel, '.2f')} | "
            f"{_fmt(ev.velocity_accel, '.2f')} | {_fmt(ev.specific_force, '.2f')} | "
            f"{_fmt(None if ev.implied_mass is None else ev.implied_mass * 1e3, '.1f')} | "
            f"{'; '.join(f.check for f in fired) or 'none'} |", len(fired))


def _worst(values: list[float | None]) -> float | None:
    """The decided value farthest from 1 on a log scale."""
    kept = [abs(v) for v in values if v is not None and np.isfinite(v)]
    return max(kept, key=lambda v: max(v, 1 / v)) if kept else None


def _unit_row(name: str, log, margins: dict[str, list[tuple[float, str]]]) -> tuple[str, int]:
    """One row of the single-column tests' table; fills ``margins`` with each decided
    statistic (as its distance to the threshold's side: factor or seconds)."""
    gyro = _worst(list(units_check.gyro_axis_ratios(log)))
    inertia = units_check.named_inertia(log)
    torque = None
    if inertia is not None and log.torque is not None:
        scales = units_check.torque_scales(log, inertia)
        if scales is not None:
            torque = _worst([r for r, c in scales if c >= units_check.MIN_CORRELATION])
            for r, c in scales:  # each decided axis: how much of its band it uses
                if c >= units_check.MIN_CORRELATION:
                    margins["torque"].append((max(r, 1 / r) / units_check.torque_band(c), name))
                if not 1 / units_check.TORQUE_FACTOR <= r <= units_check.TORQUE_FACTOR:
                    margins["correlation"].append((c, name))
    mass = units_check.named_mass(log)
    implied = implied_mass(log)
    normalised = (implied / mass if log.thrust is not None and implied is not None
                  and mass is not None else None)
    stuck = zero = None
    if log.rpm is not None:
        runs = actuation_check.stuck_runs(log, -1.0)
        stuck = max((log.t[b] - log.t[a] for _, a, b, _ in runs), default=0.0)
        zeros = actuation_check.zero_channels(log, -1.0)
        zero = max((rows.size / turning for _, rows, turning in zeros), default=0.0)
    for key, value in (("gyro", gyro),):
        if value is not None:
            margins[key].append((max(value, 1 / value), name))
    if normalised is not None:
        margins["normalised"].append((normalised if float(np.max(log.thrust)) <= 1.0
                                      else float("nan"), name))
    if stuck is not None:
        margins["stuck"].append((stuck, name))
    fired = [f for f in findings(log) if f.check in UNIT_CHECKS]
    return (f"| {name} | {_fmt(gyro, '.3f')} | {_fmt(torque, '.3f')} | "
            f"{_fmt(normalised, '.3f')} | {_fmt(stuck, '.3f')} | {_fmt(zero, '.3f')} | "
            f"{'; '.join(f.check for f in fired) or 'none'} |", len(fired))


UNIT_CHECKS = ("gyro-axis", "torque-scale", "thrust-normalised", "rotor-at-zero",
               "rotor-stuck", "rotor-speed-declared")


def unit_table(real: list[Path], cycles: int) -> int:
    """The single-column tests' table and margins (module docstring); returns how many
    fired."""
    print("\n| log | gyro axis ratio (farthest from 1) | torque rms ratio | thrust-implied / "
          "named mass | longest repeated rotor reading [s] | largest zero share | fired |")
    print("|---|---|---|---|---|---|---|")
    margins: dict[str, list[tuple[float, str]]] = {
        k: [] for k in ("gyro", "torque", "correlation", "normalised", "stuck")}
    fired = 0
    logs = [(p.name, lambda p=p: read_log(p)) for p in real]
    flights = sorted((SHARED / "neural_swarm" / "flights").iterdir())
    logs += [(p.name, lambda p=p: read_log(p)) for p in flights]
    # as docs/data.md runs them: each with its vehicle (the Parrot frame's file, else
    # the stock crazyflie21), so the torque and thrust tests judge them
    parrot = str(Path(__file__).resolve().parents[1] / "docs" / "vehicles" /
                 "cf21_parrot_frame.toml")
    logs += [(f"{p.name} --vehicle {'cf21_parrot_frame' if 'cf10' in p.name else 'crazyflie21'}",
              lambda p=p: with_vehicle(read_log(p), parrot if "cf10" in p.name
                                       else "crazyflie21", Path.cwd(), "--vehicle"))
             for p in flights]
    logs.append(("px4 ddd_quadrotor_model.csv",
                 lambda: read_command_log(SHARED / "px4" / "ddd_quadrotor_model.csv").log))
    for sensor in "ABC":
        for cycle in range(cycles):
            seed = flight_seed(0, sensor, cycle)
            logs.append((f"paper {sensor} seed {seed}", lambda s=sensor, d=seed: flight_log(
                simulate(SimConfig(vehicle=PAPER_VEHICLE, sensor=s), np.random.default_rng(d)))))
    with tempfile.TemporaryDirectory() as tmp:
        specs = [(v, rate, agg, eff) for v in (CRAZYFLIE, QUAD_250) for rate, agg, eff in
                 ((100, False, Effects()), (250, True, Effects()),
                  (500, False, Effects(drag=(0.006, 0.006, 0.007))))]
        for k, (vehicle, rate, aggressive, effects) in enumerate(specs):
            path = Path(tmp) / f"fg{k}.csv"
            write_csv(generate(FlightSpec(duration=20, log_rate=rate, aggressive=aggressive,
                                          vehicle=vehicle, effects=effects, seed=k)), path,
                      mass_guess=vehicle.mass, inertia_guess=vehicle.inertia)
            logs.append((f"flightgen {vehicle.name} {rate} Hz"
                         f"{' aggressive' if aggressive else ''}{' drag' if k % 3 == 2 else ''}",
                         lambda path=path: read_log(path)))
        for name, load in logs:
            line, n = _unit_row(name, load(), margins)
            print(line, flush=True)
            fired += n
    print("\nweakest correct-log statistic against its threshold:")
    for key, limit, unit in (("gyro", units_check.RATIO_TOLERANCE, "x"),
                             ("torque", 1.0, " of its band"),
                             ("correlation", units_check.STRONG_CORRELATION,
                              " (an axis outside x5)"),
                             ("normalised", units_check.NORMALISED_FACTOR, "x"),
                             ("stuck", actuation_check.STUCK_S, "s")):
        values = [(v, n) for v, n in margins[key] if np.isfinite(v)]
        if not values:
            print(f"  {key}: not applicable on any log (thrust above 1 wherever a vehicle "
                  "is named)" if key == "normalised" else f"  {key}: decided on no log")
            continue
        worst, where = max(values)
        print(f"  {key}: {worst:.3g}{unit} ({where}) against {limit:g}{unit}: margin "
              f"{limit / worst:.3g} (decided on {len({n for _, n in values})} logs)")
    return fired


FG_CONDITIONS = ("none", "drag", "ground_effect", "ground_effect_floor", "com_offset", "wind",
                 "motor_lag", "gyro_bias", "floor_strikes", "all")
"""flightgen conditions: no effect; one effect (``ground_effect`` with the reference's
lowest point 7 cm above a ground plane it cannot touch, as the discovery Monte Carlo
flies it; ``ground_effect_floor`` taking off from the floor and landing on it);
``floor_strikes``: no effect, take-off, two strikes 5 cm into the floor and landing;
``all``: every effect at once, in free space."""

FG_SEED = 7000


def _fg_effects(condition: str, vehicle: Vehicle) -> Effects:
    """The discovery Monte Carlo's values (``pinquad.sim.effects``' Crazyflie-class
    defaults); the forces (drag [N s/m], wind [N]) scaled by mass for the 0.5 kg quad."""
    names = ("drag", "ground_effect", "com_offset", "wind", "motor_lag", "gyro_bias")
    if condition == "all":
        chosen = names
    elif condition == "ground_effect_floor":
        chosen = ("ground_effect",)
    else:
        chosen = tuple(n for n in names if n == condition)
    scale = vehicle.mass / CRAZYFLIE.mass
    values = {}
    for name in chosen:
        value = getattr(flightgen_effects(name), name)
        values[name] = (tuple(scale * v for v in value) if name in ("drag", "wind")
                        else value)
    return Effects(**values)


def flightgen_flights(n: int) -> list[tuple[str, FlightSpec]]:
    """n seeded flights (label, spec), 20 s each, RK4 and controller at 1 ms: flight k has
    condition FG_CONDITIONS[(k // 6) % 10], vehicle CRAZYFLIE for k % 6 < 3 else
    QUAD_250, log rate (100, 250, 500)[k % 3], seed FG_SEED + k; aggressive and the
    trajectory (sines, minsnap) cycle over the four pairs with k // 6 + k % 6, so each
    vehicle and rate flies all four across the conditions."""
    out = []
    for k in range(n):
        condition = FG_CONDITIONS[(k // 6) % len(FG_CONDITIONS)]
        vehicle = (CRAZYFLIE, QUAD_250)[(k % 6) // 3]
        rate = (100, 250, 500)[k % 3]
        phase = k // 6 + k % 6
        aggressive, kind = phase % 2 == 0, ("sines", "minsnap")[(phase // 2) % 2]
        seed, duration, dt = FG_SEED + k, 20.0, 0.001
        common = dict(duration=duration, trajectory=kind, aggressive=aggressive,
                      log_rate=rate, dt=dt, seed=seed, vehicle=vehicle,
                      effects=_fg_effects(condition, vehicle))
        if condition in ("floor_strikes", "ground_effect_floor"):
            spec = FlightSpec(**common, start_on_floor=True, land=True,
                              floor_strikes=2 if condition == "floor_strikes" else 0)
        elif condition == "ground_effect":
            # the reference's excursion is generate's first draw from the seed's generator
            t = np.arange(int(round(duration / dt)) + 1) * dt
            lowest = float(excursion(t, kind, aggressive,
                                     np.random.default_rng(seed))[0, :, 2].min())
            spec = FlightSpec(**common, hover_height=LOWEST_PASS - lowest, floor=None)
        else:
            spec = FlightSpec(**common, floor=None)
        out.append((f"flightgen {vehicle.name} {rate} Hz {'aggressive' if aggressive else 'gentle'}"
                    f" {kind} {condition} seed {seed}", spec))
    return out


def _vehicle_file(path: Path) -> Path:
    """QUAD_250 as its user's vehicle file: its mass and inertia, x layout at its arm."""
    j = [float(v) for v in np.diag(QUAD_250.inertia_matrix)]
    path.write_text(f'name = "quad250"\n[body]\nmass = {QUAD_250.mass!r}\ninertia = {j!r}\n'
                    f"[reference]\nmass = {QUAD_250.mass!r}\ninertia = {j!r}\n"
                    f'[geometry]\narm = {QUAD_250.arm!r}\nlayout = "x"\nspin = [1, -1, 1, -1]\n')
    return path


def flightgen_table(n: int) -> int:
    """Every check on ``flightgen_flights(n)``; returns how many fired. The Crazyflie's
    CSV is read as written (its sidecar names ``crazyflie21``, as in the discovery Monte
    Carlo); the 0.5 kg quad's sidecar carries its mass and inertia (no shipped name is
    its) and the log is read with its vehicle file, as ``--vehicle`` reads it."""
    print("\n| flightgen flight | rows | checks fired |")
    print("|---|---|---|")
    fired = 0
    with tempfile.TemporaryDirectory() as tmp:
        toml = _vehicle_file(Path(tmp) / "quad250.toml")
        for k, (name, spec) in enumerate(flightgen_flights(n)):
            flight = generate(spec)
            if spec.vehicle is CRAZYFLIE:
                log = read_log(write_csv(flight, Path(tmp) / f"fg{k}.csv"))
            else:
                path = write_csv(flight, Path(tmp) / f"fg{k}.csv", mass_guess=QUAD_250.mass,
                                 inertia_guess=QUAD_250.inertia_matrix)
                log = with_vehicle(read_log(path), str(toml), Path(tmp), "--vehicle")
            found = findings(log)
            fired += len(found)
            words = "; ".join(f"{f.check}: {f.message}" for f in found) or "none"
            print(f"| {name} | {log.n} | {words} |", flush=True)
    print(f"\n{n} flightgen flights: {fired} check(s) fired")
    return fired


def main(argv: list[str]) -> int:
    n_flightgen = 60
    if "--flightgen" in argv:
        at = argv.index("--flightgen")
        n_flightgen = int(argv[at + 1])
        argv = argv[:at] + argv[at + 2:]
    cycles = int(argv[0]) if argv else 20
    print("| log | rows | dt [ms] | gyro / attitude | position / velocity | "
          "99 % accel from pos [m/s^2] | from vel | median abs(acc) [m/s^2] | "
          "mass from thrust [g] | checks fired |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    fired = 0
    real = sorted(p for d in ("imrc_brushed", "imrc_brushless") for p in (DATA / d).iterdir()
                  if p.suffix != ".txt")
    for path in real:
        line, n = _row(path.name, read_log(path))
        print(line)
        fired += n
    for sensor in "ABC":
        for cycle in range(cycles):
            seed = flight_seed(0, sensor, cycle)
            log = flight_log(simulate(SimConfig(vehicle=PAPER_VEHICLE, sensor=sensor),
                                      np.random.default_rng(seed)))
            line, n = _row(f"paper {sensor} seed {seed}", log)
            print(line)
            fired += n
    total = len(real) + 3 * cycles
    print(f"\n{len(real)} real logs + {3 * cycles} simulated flights: {fired} check(s) fired "
          f"in {total} logs")
    unit_fired = unit_table(real, cycles)
    print(f"single-column tests: {unit_fired} fired on {total + 19} logs (the above, 6 "
          "Neural-Swarm flights read as they are and with their vehicle, the PX4 sample, 6 "
          "flightgen flights)")
    fg_fired = flightgen_table(n_flightgen)
    return 1 if fired or unit_fired or fg_fired else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
