"""The Python API and ``python -m pinquad.offline --log`` side by side on the shared real
logs: the Neural-Swarm flights (no vehicle named, and the Parrot-frame flights again with
``docs/vehicles/cf21_parrot_frame.toml``) and jana00. For each log it runs the command as
a user does (a subprocess, its report.json read back) and ``pinquad.discover(log,
pinquad.identify(log))`` in this process, and prints both: effects kept (or why discovery
did not run), the verdict per parameter and overall, the headline mass and inertia.

    python scripts/api_vs_cli.py [--data ../shared/data] [--only NAME ...]
                                 [--with-vehicle both|no|only]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

import pinquad

ROOT = Path(__file__).resolve().parents[1]
PARROT = ROOT / "docs" / "vehicles" / "cf21_parrot_frame.toml"
SHORT = {"trusted": "T", "not identifiable": "NI", "implausible": "IMP",
         "model not adequate": "NA", "not judged": "NJ"}
NAMES = ("mass", "I_xx", "I_yy", "I_zz")


def outcome(effects: list[str], not_run: str | None, verdicts: dict[str, str], overall: str,
            mass: float, inertia: list[float]) -> dict:
    """What is compared: effects (or the reason discovery did not run), verdicts, values."""
    return {"effects": ", ".join(effects) or (f"not run: {not_run[:40]}" if not_run else "none"),
            "verdicts": "/".join(SHORT.get(verdicts[n], verdicts[n]) for n in NAMES),
            "overall": overall, "values": [mass, *inertia]}


def from_cli(log: Path, vehicle: Path | None, out: Path) -> dict:
    cmd = [sys.executable, "-m", "pinquad.offline", "--log", str(log), "--out", str(out),
           "--jobs", "1", *(["--vehicle", str(vehicle)] if vehicle else [])]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=3600)
    rep = json.loads((out / "report.json").read_text())
    est, disc = rep["estimates"], rep["discovery"]
    row = outcome([s["effect"] for s in disc["selected"]], disc.get("not_run"),
                  {k: v["verdict"] for k, v in est["verdict"]["parameters"].items()},
                  est["verdict"]["overall"], est["mass"],
                  np.diag(np.asarray(est["inertia"])).tolist())
    row["exit"] = proc.returncode
    return row


def from_api(log: Path, vehicle: Path | None) -> dict:
    flight = pinquad.read_log(log, None if vehicle is None else str(vehicle))
    found = pinquad.discover(flight, pinquad.identify(flight))
    row = outcome(list(found.selected), found.discovery_note,
                  {n: found.verdict.get(n).verdict for n in NAMES}, found.verdict.overall,
                  found.mass, found.inertia_diag.tolist())
    row["exit"] = 0 if found.trusted else 3
    return row


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    parser.add_argument("--only", nargs="*", default=None, help="log names to run")
    parser.add_argument("--with-vehicle", choices=["both", "no", "only"], default="both",
                        help="the Parrot-frame flights with their vehicle file too (both), "
                             "not (no), or those alone (only)")
    args = parser.parse_args()
    flights = sorted((args.data / "neural_swarm" / "flights").glob("*"))
    plain = [(p, None) for p in flights]
    plain.append((args.data / "crazyflie" / "imrc_brushed" / "jana00", None))
    parrot = [(p, PARROT) for p in flights if "cf10" in p.name]
    cases = {"both": plain + parrot, "no": plain, "only": parrot}[args.with_vehicle]
    cases = [c for c in cases if args.only is None or c[0].name in args.only]
    print("| log | vehicle | offline --log: effects | verdicts m/xx/yy/zz (overall, exit) "
          "| API: effects | verdicts (overall, exit) | same | largest value difference |")
    print("|---" * 8 + "|")
    same_all = True
    with tempfile.TemporaryDirectory() as tmp:
        for i, (log, vehicle) in enumerate(cases):
            cli = from_cli(log, vehicle, Path(tmp) / f"run{i}")
            api = from_api(log, vehicle)
            same = all(cli[k] == api[k] for k in ("effects", "verdicts", "overall", "exit"))
            same_all &= same
            diff = float(np.max(np.abs(np.subtract(cli["values"], api["values"]))
                                / np.abs(cli["values"])))
            print(f"| {log.name} | {vehicle.name if vehicle else '-'} | {cli['effects']} | "
                  f"{cli['verdicts']} ({cli['overall']}, {cli['exit']}) | {api['effects']} | "
                  f"{api['verdicts']} ({api['overall']}, {api['exit']}) | "
                  f"{'yes' if same else 'NO'} | {diff:.1e} |", flush=True)
    print(f"\n{len(cases)} logs: the same discovery outcome and verdicts on "
          f"{'every one' if same_all else 'NOT every one'}")
    return 0 if same_all else 1


if __name__ == "__main__":
    raise SystemExit(main())
