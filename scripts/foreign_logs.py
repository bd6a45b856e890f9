"""Every shared real log through ``offline --log`` and ``online --log``, as a user runs them:
the Neural-Swarm flights (another lab's Crazyflies, commanded thrust) and the IMRC
Crazyflie 2.1 logs (measured rotor speeds). Prints one table per data set: mass with its
total standard error and its parts, the inertia diagonal, each verdict, the effects kept
(or why discovery did not run), the largest inertia entry anywhere in report.json
against the range EM searched, any LAPACK or traceback text, the exit codes, and the
online replay's final verdict. For the IMRC logs also the chi-square of the trusted I_zz
values about their weighted mean (total standard errors).

    python scripts/foreign_logs.py [--data ../shared/data] [--jobs 2] [--only NAME ...]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BAD_TEXT = ("Traceback", "DLASCL", "On entry to", "LinAlgError")


def run(cmd: list[str]) -> tuple[int, str]:
    proc = subprocess.run([sys.executable, "-m", *cmd], capture_output=True, text=True,
                          cwd=ROOT, timeout=1800)
    return proc.returncode, proc.stdout + proc.stderr


def one(log: Path, out: Path, extra: list[str]) -> dict:
    code, text = run(["pinquad.offline", "--log", str(log), "--out", str(out / "offline"),
                      "--jobs", "1", *extra])
    row: dict = {"log": log.name, "exit": code, "bad_text": [b for b in BAD_TEXT if b in text]}
    report_path = out / "offline" / "report.json"
    if report_path.is_file():
        rep = json.loads(report_path.read_text())
        est = rep["estimates"]
        entries = [rep["estimates"], rep.get("base", rep["estimates"]),
                   *(r["estimates"] for r in rep.get("runs", []))]
        row.update(
            mass=est["mass"], mass_se=est["stderr"]["mass"],
            parts={k: v["mass"] for k, v in (est.get("stderr_parts") or {}).items()
                   if k != "assumed" and v["mass"] > 0},
            inertia=np.diag(np.asarray(est["inertia"])).tolist(),
            inertia_se=est["stderr"]["inertia_diag"],
            verdicts={k: v["verdict"] for k, v in est["verdict"]["parameters"].items()},
            overall=est["verdict"]["overall"],
            max_inertia=max(float(np.max(np.diag(np.asarray(e["inertia"])))) for e in entries),
            # the largest inertia entry anywhere over its axis's upper edge of the search range
            over_range=(max(float(np.max(np.diag(np.asarray(e["inertia"]))
                                         / np.asarray(rep["search_range"]["inertia_hi"])))
                            for e in entries) if rep.get("search_range") else float("nan")),
            effects=[s["effect"] for s in rep["discovery"]["selected"]],
            not_run=rep["discovery"].get("not_run"),
            unphysical=[u["effect"] for u in rep["discovery"].get("unphysical", [])])
    else:
        row["error"] = text.strip().splitlines()[-1] if text.strip() else "no output"
    code2, text2 = run(["pinquad.online", "--log", str(log), "--out", str(out / "online")])
    row["online_exit"] = code2
    row["bad_text"] += [b for b in BAD_TEXT if b in text2 and b not in row["bad_text"]]
    online = out / "online" / "report.json"
    if online.is_file():
        rep = json.loads(online.read_text())
        row["online_verdict"] = rep.get("verdict", {}).get("overall")
        row["online_mass"] = rep["estimates"]["mass"]
        row["online_max_inertia"] = float(np.max(np.diag(np.asarray(rep["estimates"]["inertia"]))))
    return row


def table(rows: list[dict]) -> str:
    lines = ["| log | exit | mass [g] (total se: parts) | I_xx, I_yy, I_zz [e-6 kg m^2] | "
             "verdicts m/xx/yy/zz | largest inertia anywhere (/ its range's top) | "
             "effects kept | online: "
             "verdict, mass, largest inertia | bad text |", "|---" * 9 + "|"]
    short = {"trusted": "T", "not identifiable": "NI", "implausible": "IMP",
             "model not adequate": "NA", "not judged": "NJ"}
    for r in rows:
        if "mass" not in r:
            lines.append(f"| {r['log']} | {r['exit']} | {r.get('error', '')} | | | | | | |")
            continue
        parts = ", ".join(f"{k} {1e3 * v:.3g}" for k, v in r["parts"].items())
        inertia = ", ".join(f"{1e6 * v:.4g} ± {1e6 * s:.2g}"
                            for v, s in zip(r["inertia"], r["inertia_se"], strict=True))
        verdicts = "/".join(short.get(r["verdicts"][k], r["verdicts"][k])
                            for k in ("mass", "I_xx", "I_yy", "I_zz"))
        effects = ", ".join(r["effects"]) or ("not run" if r["not_run"] else "none")
        if r["unphysical"]:
            effects += f" (not kept, unphysical: {', '.join(r['unphysical'])})"
        online = (f"{r.get('online_verdict')}, {1e3 * r.get('online_mass', np.nan):.2f} g, "
                  f"{1e6 * r.get('online_max_inertia', np.nan):.4g} (exit {r['online_exit']})")
        lines.append(f"| {r['log']} | {r['exit']} | {1e3 * r['mass']:.2f} ± "
                     f"{1e3 * r['mass_se']:.2f} ({parts}) | {inertia} | {verdicts} | "
                     f"{1e6 * r['max_inertia']:.4g} ({r['over_range']:.3f}) | {effects} | "
                     f"{online} | "
                     f"{', '.join(r['bad_text']) or 'none'} |")
    return "\n".join(lines)


def chi2_line(rows: list[dict], index: int, name: str, trusted_only: bool) -> str:
    """Chi-square of one inertia entry about its weighted mean, with total errors."""
    use = [r for r in rows if "verdicts" in r
           and (not trusted_only or r["verdicts"][name] == "trusted")]
    what = "trusted" if trusted_only else "all"
    if len(use) < 2:
        return f"{what} {name}: {len(use)} log(s), no chi-square"
    x = np.array([r["inertia"][index] for r in use])
    s = np.array([r["inertia_se"][index] for r in use])
    w = 1 / s**2
    mu = float(np.sum(w * x) / np.sum(w))
    chi2 = float(np.sum(w * (x - mu) ** 2))
    worst = float(np.max(np.abs(x - mu) / s))
    return (f"{what} {name} on {len(use)} logs: weighted mean {1e6 * mu:.3g} e-6 kg m^2, "
            f"chi-square {chi2:.2f} on {len(use) - 1} dof (total errors), largest "
            f"|x - mean| / total se {worst:.2f}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--only", nargs="*", default=None)
    args = parser.parse_args()
    sets = {"Neural-Swarm (commanded thrust)": sorted((args.data / "neural_swarm" / "flights")
                                                      .glob("*")),
            "IMRC brushed (measured rotor speeds)": sorted(
                p for p in (args.data / "crazyflie" / "imrc_brushed").glob("jana*"))}
    with tempfile.TemporaryDirectory() as tmp, ThreadPoolExecutor(args.jobs) as pool:
        for title, logs in sets.items():
            logs = [p for p in logs if args.only is None or p.name in args.only]
            if not logs:
                continue
            jobs = [pool.submit(one, p, Path(tmp) / p.name, []) for p in logs]
            rows = [j.result() for j in jobs]
            print(f"\n## {title}\n")
            print(table(rows))
            masses = [r for r in rows if "mass" in r]
            print(f"\nlogs {len(rows)}, with a report {len(masses)}; LAPACK/traceback text in "
                  f"{sum(bool(r['bad_text']) for r in rows)}; largest inertia entry anywhere "
                  f"over its range's top: {max(r['over_range'] for r in masses):.4f}")
            if "IMRC" in title:
                off = [abs(r["mass"] / 0.0347 - 1) for r in masses]
                print(f"mass against the scale's 34.7 g: largest |error| {100 * max(off):.2f} %")
                for i, name in enumerate(("I_xx", "I_yy", "I_zz")):
                    print(chi2_line(rows, i, name, True))
                    print(chi2_line(rows, i, name, False))
            else:
                parrot = [r for r in masses if "cf10" in r["log"]]
                for r in parrot:
                    z = (r["mass"] - 0.067) / r["mass_se"]
                    print(f"{r['log']}: mass {1e3 * r['mass']:.2f} g, (m - 67 g) / total se "
                          f"= {z:+.2f}, verdict {r['verdicts']['mass']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
