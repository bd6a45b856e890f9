"""One flight, one answer: each shared IMRC micro-SD log identified as read from the card,
from pinquad's own export of it (``logs/flight.parquet`` with its sidecar) and from a CSV
copy of that export (quoted column names, as pyarrow and spreadsheets write them). Prints
the three readings' mass and inertia side by side and the largest difference in
statistical standard errors of the micro-SD reading.

    python scripts/round_trip.py [--data ../shared/data] [--jobs 2] [--only jana00 ...]
"""

from __future__ import annotations

import argparse
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pyarrow.csv as pa_csv
import pyarrow.parquet as pq

from pinquad.io.logs import write_log
from pinquad.pipeline import LOG_MAX_ITERATIONS
from pinquad.pipeline.identify import LogOptions
from pinquad.pipeline.single import identify, read

ROOT = Path(__file__).resolve().parents[1]
OPTIONS = LogOptions(msteps=("regressor",), max_iterations=LOG_MAX_ITERATIONS)


def _values(result) -> tuple[np.ndarray, np.ndarray]:
    run = result.runs[0]
    return np.r_[run.mass, np.diag(run.inertia)], np.asarray(run.stderr, dtype=float)


def three_readings(path: Path) -> tuple[str, np.ndarray, np.ndarray]:
    """(name, values (3, 4) of [m, I_xx, I_yy, I_zz] per reading, the micro-SD's stderr)."""
    first = identify(read(path), OPTIONS)
    with tempfile.TemporaryDirectory() as tmp:
        export = write_log(first.log, Path(tmp) / "flight.parquet")
        again = identify(read(export), OPTIONS)
        csv = Path(tmp) / "copy.csv"
        pa_csv.write_csv(pq.read_table(export), csv)
        Path(f"{csv}.json").write_text(Path(f"{export}.json").read_text())
        copy = identify(read(csv), OPTIONS)
    a, se = _values(first)
    return path.name, np.vstack([a, _values(again)[0], _values(copy)[0]]), se


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--only", nargs="*", default=None)
    args = parser.parse_args()
    folder = args.data / "crazyflie" / "imrc_brushed"
    logs = sorted(p for p in folder.iterdir() if p.name.startswith("jana"))
    if args.only:
        logs = [p for p in logs if p.name in args.only]
    with ProcessPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(three_readings, logs))
    print("| log | mass [g] micro-SD / export / CSV | I_xx [1e-6 kg m^2] | I_yy | I_zz | "
          "largest difference [statistical se] |")
    print("|---|---|---|---|---|---|")
    worst = 0.0
    for name, values, se in rows:
        scale = np.r_[1e3, 1e6, 1e6, 1e6]
        cells = [" / ".join(f"{v * s:.4f}" for v in values[:, j]) for j, s in enumerate(scale)]
        diff = np.max(np.abs(values[1:] - values[0]), axis=0) / se
        worst = max(worst, float(np.nanmax(diff)))
        print(f"| {name} | {' | '.join(cells)} | {np.nanmax(diff):.2g} |")
    print(f"\n{len(rows)} logs; largest difference of any estimate between the three readings: "
          f"{worst:.2g} statistical standard errors")


if __name__ == "__main__":
    main()
