"""How much a real logger's time stamps move the estimate: each shared IMRC micro-SD log
(brushed jana*, brushless eckart*) is exported once as pinquad's own Parquet log (its ~500 Hz rows with rotor
speeds, ``pinquad.io.logs.write_log``), identified (regressor M-step, standard errors),
then its ``t`` column is perturbed and identified again:

* jitter: every row's stamp moved by uniform(-a, +a), then the stamps sorted (the rows
  keep their order, so ``t`` stays strictly increasing as the log contract demands;
  at ~2 ms per row, jitter of 1 ms or more is otherwise not increasing);
* epoch offset: a constant added to every stamp (Unix time ~1.7e9 s), in float64.

For every case it prints the largest change of mass, I_xx, I_yy or I_zz in standard
errors of the unperturbed export (its ``stderr``: statistical and systematic combined,
and its statistical part alone) and the number of transitions excluded as log gaps.

    PYTHONPATH=$PWD python scripts/time_robustness.py [--logs jana00 jana01 ...]
        [--jitter-ms 0.5 1 2 4] [--offsets 0 1e6 1.7e9] [--out table.md]

The full grid (24 logs x 4 jitters x 3 offsets plus the offsets alone) is about 20 EM
runs per log; ``--pairs`` runs each jitter at offset 0 and each offset without jitter,
plus the largest jitter at the largest offset (8 runs per log); ``--cycle`` runs one
case per log, the 12 (jitter, offset) pairs taken in turn over the logs (each pair on
two of the 24 logs: one EM run per log besides the unperturbed one).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from pinquad.experiments.recorded import LogOptions, identify_log
from pinquad.io.logs import FlightLog, LogFormatError, write_log
from pinquad.io.read import read_log

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "crazyflie"
FOLDERS = {"jana": SHARED / "imrc_brushed", "eckart": SHARED / "imrc_brushless"}


def jittered(t: np.ndarray, amplitude: float, offset: float, seed: int) -> np.ndarray:
    """Stamps t + uniform(-amplitude, amplitude), sorted, plus offset [s] (float64),
    strictly increasing."""
    rng = np.random.default_rng(seed)
    out = np.sort(t + rng.uniform(-amplitude, amplitude, t.size)) if amplitude else t.copy()
    # rows closer than 10 us apart would collide once a Unix-time offset rounds them
    step = np.maximum(np.diff(out), 1e-5)
    return out[0] + np.concatenate([[0.0], np.cumsum(step)]) + offset


def estimate(path: Path, information: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """([m, I_xx, I_yy, I_zz], stderr (4,), statistical stderr (4,), gap transitions) of
    the regressor run of a log."""
    result = identify_log(read_log(path), LogOptions(msteps=("regressor",),
                                                     information=information))
    run = result.runs[0]
    params = np.r_[run.mass, np.diag(run.inertia)]
    stat = run.measured.se_stat if run.measured is not None else run.stderr
    gaps = sum(int(line.split(" ")[0]) for line in result.excluded if "log gap" in line)
    return params, np.asarray(run.stderr), np.asarray(stat), gaps


def export(name: str, folder: Path) -> tuple[Path, FlightLog]:
    log = read_log(FOLDERS[name.rstrip("0123456789")] / name)
    log = replace(log, measured=None)
    return write_log(log, folder / f"{name}.parquet"), log


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    shared = [p.name for prefix, folder in FOLDERS.items()
              for p in sorted(folder.iterdir()) if p.name.startswith(prefix)]
    ap.add_argument("--logs", nargs="+", default=shared)
    ap.add_argument("--jitter-ms", type=float, nargs="+", default=[0.5, 1.0, 2.0, 4.0])
    ap.add_argument("--offsets", type=float, nargs="+", default=[0.0, 1e6, 1.7e9])
    ap.add_argument("--pairs", action="store_true", help="the reduced design (docstring)")
    ap.add_argument("--cycle", action="store_true", help="one case per log (docstring)")
    ap.add_argument("--out", type=Path, default=None, help="also write the table here")
    args = ap.parse_args()
    cycle = [(a, o) for o in args.offsets for a in args.jitter_ms]
    if args.pairs:
        cases = ([(a, 0.0) for a in args.jitter_ms] + [(0.0, o) for o in args.offsets if o]
                 + [(max(args.jitter_ms), max(args.offsets))])
    else:
        cases = [(a, o) for o in args.offsets for a in [0.0, *args.jitter_ms] if a or o]
    lines = ["| log | jitter [ms] | offset [s] | max change / stderr | max change / statistical "
             "stderr | worst parameter | gap transitions |", "|---|---|---|---|---|---|---|"]
    print("\n".join(lines), flush=True)
    names = ("mass", "I_xx", "I_yy", "I_zz")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name in args.logs:
            t0 = time.perf_counter()
            path, log = export(name, folder)
            try:
                base, se, stat, base_gaps = estimate(path, information=True)
            except (LogFormatError, ValueError) as exc:  # e.g. rotor speeds only from PWM
                lines.append(f"| {name} | - | - | - | - | - | the export is not identified: "
                             f"{str(exc).replace(str(folder) + '/', '')} |")
                print(lines[-1], flush=True)
                continue
            # --cycle: the pair of a log is fixed by its place among the shared logs
            place = shared.index(name) if name in shared else args.logs.index(name)
            mine = [cycle[place % len(cycle)]] if args.cycle else cases
            for i, (amp_ms, offset) in enumerate(mine):  # one jitter draw per amplitude
                moved = replace(log, t=jittered(log.t, amp_ms * 1e-3, offset, seed=int(amp_ms * 1000)))
                p = write_log(moved, folder / f"{name}-{i}.parquet")
                est, _, _, gaps = estimate(p, information=False)
                change = np.abs(est - base)
                worst = int(np.argmax(change / se))
                row = (f"| {name} | {amp_ms:g} | {offset:g} | {np.max(change / se):.3f} | "
                       f"{np.max(change / stat):.3f} | {names[worst]} | {gaps} (unperturbed "
                       f"{base_gaps}) |")
                lines.append(row)
                print(row, flush=True)
            print(f"<!-- {name}: {time.perf_counter() - t0:.0f} s -->", flush=True)
    if args.out is not None:
        args.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
