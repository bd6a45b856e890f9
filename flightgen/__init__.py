"""flightgen: a second flight generator, sharing no code with ``pinquad.sim`` (or any of
pinquad), for tests and the discovery Monte Carlo (docs/flightgen.md).

    from flightgen import FlightSpec, generate, write_csv
    flight = generate(FlightSpec(duration=30, trajectory="minsnap", log_rate=250, seed=1))
    write_csv(flight, "flight.csv")     # pinquad's log columns + flight.csv.json

Its own quaternion rigid body (RK4 at 1-2 kHz), its own geometric SE(3) controller at
that rate, optional effects of pinquad's discovery vocabulary and floor contact in the truth, logs at 100, 250
or 500 Hz with the actuation sampled at log instants and motion capture at 100 Hz.
Imports numpy and scipy only (import-linter contract in pyproject.toml).
"""

from flightgen.contact import Floor
from flightgen.controller import Gains
from flightgen.csvlog import write_csv
from flightgen.effects import Effects
from flightgen.generate import generate
from flightgen.spec import CLEAN, Flight, FlightSpec, Noise
from flightgen.vehicle import CRAZYFLIE, QUAD_250, Vehicle

__all__ = ["CLEAN", "CRAZYFLIE", "QUAD_250", "Effects", "Flight", "FlightSpec", "Floor",
           "Gains", "Noise", "Vehicle", "generate", "write_csv"]
