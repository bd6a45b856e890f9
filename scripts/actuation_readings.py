"""How much an estimate rests on how a sampled input acted between log rows
(docs/trust.md). Flies flightgen flights (the independent generator: controller
and RK4 at 2 kHz, the command SAMPLED at each log row), identifies each with the logged
input read two ways, held over each interval (pinquad's simulator's convention) and the
mean of the interval's two rows (``pinquad.models.sources.interval_inputs``, what a
sampled log gets), and prints mass and inertia against the truth. Both readings are the
pipeline's identify step's (``pinquad.pipeline.single.identify``, regressor M-step, at
most 100 E-steps): its sidecar not saying how the actuation acted, the log is read as
sampled and the held reading is the input alternative the step fits beside it
(``LogResult.input_alternative``, which the verdict weighs).

    PYTHONPATH=$PWD python scripts/actuation_readings.py     (about 5 minutes on 2 cores)
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from flightgen import FlightSpec, Noise, generate, write_csv
from pinquad.pipeline.identify import LogOptions
from pinquad.pipeline.single import identify, read

TRUTH = np.array([35.0, 16.6, 16.7, 29.3])
OPTIONS = LogOptions(msteps=("regressor",), estep="rts", max_iterations=100, information=False)
SCALE = np.array([1e3, 1e6, 1e6, 1e6])


def readings(path: Path) -> dict[str, np.ndarray]:
    """{"held", "sampled"}: [m [g], I_xx, I_yy, I_zz [1e-6 kg m^2]] of the log at path."""
    identified = identify(read(path), OPTIONS)
    held = identified.input_alternative
    assert held is not None  # the sidecar does not say how the actuation acted
    run = identified.runs[0]
    return {"held": held * SCALE, "sampled": np.r_[run.mass, np.diag(run.inertia)] * SCALE}


SEEDS = (1, 2, 3)
RATES = (100, 500)
DURATION = 20.0
NOISES = (("default", Noise()), ("no process noise", Noise(thrust=0.0, torque=(0.0, 0.0, 0.0))))


def main() -> None:
    print(f"flightgen Crazyflie-class flights, {DURATION:g} s, sines, no floor, seeds {SEEDS}; "
          f"truth mass {TRUTH[0]} g, inertia {TRUTH[1:]} e-6 kg m^2")
    print("| log rate | noise | seed | input read as | mass [g] | I_xx | I_yy | I_zz (errors vs truth) |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for rate in RATES:
            for noise_name, noise in NOISES:
                for seed in SEEDS:
                    flight = generate(FlightSpec(duration=DURATION, log_rate=rate,
                                                 seed=seed, floor=None, noise=noise))
                    path = Path(tmp) / f"f_{rate}_{noise_name[:4]}_{seed}.csv"
                    write_csv(flight, path)
                    for how, est in readings(path).items():
                        err = 100 * (est - TRUTH) / TRUTH
                        label = "held" if how == "held" else "mean of two rows"
                        cells = " | ".join(f"{v:.2f} ({e:+.0f} %)" for v, e in zip(est, err, strict=True))
                        print(f"| {rate} Hz | {noise_name} | {seed} | {label} | {cells} |")


if __name__ == "__main__":
    main()
