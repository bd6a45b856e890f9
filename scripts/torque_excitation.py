"""Torque excitation against the error of the inertia on clean flights pinquad did not
simulate (docs/verdict.md, "Torques no larger than the noise").

Flies the clean flights of the flightgen discovery Monte Carlo (``flight_spec("none",
seed, i, rate)``: seed = i, the same flights as ``python -m pinquad.discovery --generator
flightgen --conditions none``), identifies each as ``offline --log`` does (regressor
M-step, 100 E-steps, no discovery) and prints per flight the inertia's error against the
truth, the torque excitation per body axis (``verdict_evidence.torque_excitation``) and each
inertia's verdict (the pipeline's, ``pinquad.pipeline.single.run`` without discovery).

    PYTHONPATH=$PWD python scripts/torque_excitation.py --rate 100 --flights 0 1 2 3
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from flightgen import CRAZYFLIE, generate, write_csv
from pinquad.discovery.calibrated import discovery_start
from pinquad.experiments.discovery_mc_flightgen import case_seed, flight_spec
from pinquad.identification.verdict_evidence import torque_excitation
from pinquad.pipeline.identify import LogOptions, input_reading
from pinquad.pipeline.single import PipelineOptions, read, run

OPTIONS = PipelineOptions(identification=LogOptions(msteps=("regressor",), estep="rts",
                                                    max_iterations=100, information=True),
                          discover=False)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rate", type=int, default=100, help="log rate [Hz] (100, 250, 500)")
    parser.add_argument("--flights", type=int, nargs="+", default=list(range(8)),
                        help="flight indices of the Monte Carlo's clean condition")
    args = parser.parse_args()
    truth = np.diag(CRAZYFLIE.inertia_matrix)
    print("| rate | flight | trajectory | I_xx, I_yy, I_zz error | excitation x, y, z | verdicts |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for i in args.flights:
            seed = case_seed(0, "none", i)
            spec = flight_spec("none", seed, i, args.rate)
            path = write_csv(generate(spec), Path(tmp) / f"fg-{args.rate}-{seed}.csv")
            piped = run(read(path), OPTIONS)
            result, fit, verdict = piped.identified, piped.run, piped.verdict
            err = 100 * (np.diag(fit.inertia) / truth - 1)
            start = discovery_start(fit)
            ratio, _ = torque_excitation(start.obs, start.theta,
                                         actuation=input_reading(result.kind, result.log))
            kind = f"{'aggressive' if spec.aggressive else 'gentle'} {spec.trajectory}"
            words = ", ".join(verdict.get(n).verdict for n in ("I_xx", "I_yy", "I_zz"))
            print(f"| {args.rate} Hz | {i} | {kind} | {', '.join(f'{e:+.1f} %' for e in err)} | "
                  f"{', '.join(f'{r:.2f}' for r in ratio)} | {words} |", flush=True)


if __name__ == "__main__":
    main()
