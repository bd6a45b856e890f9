"""How much a real logger's time stamps move the estimate: each shared IMRC micro-SD log
(brushed jana*, brushless eckart*) is exported once as pinquad's own Parquet log (its
~500 Hz rows with rotor speeds, ``pinquad.io.logs.write_log``), identified (regressor
M-step, standard errors), then its ``t`` column is perturbed and identified again. A log
whose rotor speeds only its PWM commands can rebuild (not in the export) is identified
from its micro-SD reading, its row and pose stamps perturbed in memory:

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
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

from pinquad.io.logs import FlightLog, LogFormatError, write_log
from pinquad.io.timebase import clock_times
from pinquad.pipeline.identify import LogOptions
from pinquad.pipeline.single import identify, read

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


def estimate(source: Path | FlightLog,
             information: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """([m, I_xx, I_yy, I_zz], stderr (4,), statistical stderr (4,), gap transitions) of
    the regressor run of a log (a file, or a micro-SD reading in memory), identified by
    the pipeline's identify step."""
    log = source if isinstance(source, FlightLog) else read(source)
    result = identify(log, LogOptions(msteps=("regressor",), information=information))
    run = result.runs[0]
    params = np.r_[run.mass, np.diag(run.inertia)]
    stat = run.measured.se_stat if run.measured is not None else run.stderr
    gaps = sum(e.transitions for e in (() if run.measured is None else run.measured.exclusions)
               if e.kind == "log gaps")
    return params, np.asarray(run.stderr), np.asarray(stat), gaps


def micro_sd(name: str) -> FlightLog:
    return read(FOLDERS[name.rstrip("0123456789")] / name)


def export(name: str, folder: Path) -> tuple[Path, FlightLog]:
    log = replace(micro_sd(name), measured=None)
    return write_log(log, folder / f"{name}.parquet"), log


def moved_micro_sd(log: FlightLog, amplitude: float, offset: float, seed: int) -> FlightLog:
    """The micro-SD reading with its row stamps and, independently, its pose stamps
    jittered and offset (the PWM it rebuilds faulty rotor speeds from kept)."""
    measured = log.measured
    assert measured is not None and measured.pose_t is not None
    pose_t = jittered(measured.pose_t, amplitude, offset, seed + 1)
    return replace(log, t=jittered(log.t, amplitude, offset, seed),
                   measured=replace(measured, pose_t=pose_t))


NAMES = ("mass", "I_xx", "I_yy", "I_zz")


def log_rows(name: str, cases: list[tuple[float, float]]) -> list[str]:
    """The table rows of one log: each (jitter [ms], offset [s]) case against the
    unperturbed log, one jitter draw per amplitude."""
    t0 = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        path, log = export(name, folder)
        card = None
        try:
            base, se, stat, base_gaps = estimate(path, information=True)
        except (LogFormatError, ValueError):
            # rotor speeds that only the PWM commands can rebuild, which the export does
            # not carry: the micro-SD reading itself, its stamps moved in memory
            card = micro_sd(name)
            base, se, stat, base_gaps = estimate(card, information=True)
        for i, (amp_ms, offset) in enumerate(cases):
            seed = int(amp_ms * 1000)
            if card is None:
                moved = replace(log, t=jittered(log.t, amp_ms * 1e-3, offset, seed=seed))
                est, _, _, gaps = estimate(write_log(moved, folder / f"{name}-{i}.parquet"),
                                           information=False)
            else:
                est, _, _, gaps = estimate(moved_micro_sd(card, amp_ms * 1e-3, offset, seed),
                                           information=False)
            change = np.abs(est - base)
            worst = int(np.argmax(change / se))
            label = name if card is None else f"{name} (micro-SD)"
            rows.append(f"| {label} | {amp_ms:g} | {offset:g} | {np.max(change / se):.3f} | "
                        f"{np.max(change / stat):.3f} | {NAMES[worst]} | {gaps} (unperturbed "
                        f"{base_gaps}) |")
    shift = clock_times(log.t) - log.t
    rows.append(f"<!-- {name}: {time.perf_counter() - t0:.0f} s; the log's clock moves its "
                f"rows by {np.sqrt(np.mean(shift**2)) * 1e3:.3f} ms rms, at most "
                f"{np.abs(shift).max() * 1e3:.3f} ms -->")
    return rows


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
    ap.add_argument("--jobs", type=int, default=1, help="logs identified at once")
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
    jobs = [(name, [cycle[place % len(cycle)]] if args.cycle else cases)
            for place, name in ((shared.index(n) if n in shared else args.logs.index(n), n)
                                for n in args.logs)]
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for rows in pool.map(log_rows, *zip(*jobs, strict=True)):
            lines.extend(rows)
            print("\n".join(rows), flush=True)
    if args.out is not None:
        args.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
