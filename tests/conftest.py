"""Shared test fixtures, and the check, before any test runs, that the real data the tests
read is there.

The tests read the public flights from ``../shared/data`` beside the checkout (CI's copy).
When a part is missing, the session first fetches the Crazyflie part there (pinned commit,
SHA-256 per file: ``pinquad.io.datafetch``); if anything is still missing (offline, or the
Neural-Swarm and PX4 files, which pinquad cannot download), it stops once with one
instruction instead of a hundred "data not found" failures. A test run alone still fails,
never skips, without its data (``PINQUAD_TESTS_WITHOUT_DATA=1`` lets the session start to
run the tests that need none).
"""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import requests

from estimators.linear import LinearGaussianModel
from pinquad.experiments.batch import NAN3, BatchRow
from pinquad.io.crazyflie_files import COMMIT, REPOSITORY
from pinquad.io.datafetch import fetch_crazyflie

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
"""Where the tests read the real data: ``../shared/data`` beside the checkout."""

NEEDED = {
    "crazyflie/imrc_brushed": f"the IMRC Crazyflie flights ({REPOSITORY} at {COMMIT[:8]})",
    "crazyflie/imrc_brushless": "the IMRC brushless Crazyflie flights (the same repository)",
    "crazyflie/thrust_stand": "the Bitcraze thrust-stand runs (the same download)",
    "neural_swarm/flights": "the Caltech Neural-Swarm flights (aerorobotics/neural-swarm at "
                            "48b18511, data/training/datacollection21_06_16_2020/; "
                            "docs/data.md)",
    "px4": "the PX4 logs (ethz-asl/data-driven-dynamics at 252a9cb0, "
           "resources/quadrotor_model.csv and its config; PX4/pyulog's test/sample.ulg)",
}
"""The data folders the tests read, and what each holds."""

WITHOUT_DATA = "PINQUAD_TESTS_WITHOUT_DATA"


def _missing() -> list[str]:
    return [part for part in NEEDED
            if not (DATA / part).is_dir() or not any((DATA / part).iterdir())]


def pytest_configure(config: pytest.Config) -> None:
    """Fetch the Crazyflie data the tests need on first use; stop once, with one
    instruction, when data is still missing (module docstring)."""
    if os.environ.get(WITHOUT_DATA) or not _missing():
        return
    failed = ""
    if any(part.startswith("crazyflie/") for part in _missing()):
        print(f"fetching the Crazyflie data the tests read into {DATA / 'crazyflie'} "
              "(pinned commit, SHA-256 checked) ...", file=sys.stderr)
        created = [d for d in (DATA.parent, DATA, DATA / "crazyflie") if not d.exists()]
        try:
            fetch_crazyflie(DATA / "crazyflie")
        except requests.ConnectionError as exc:
            host = exc.request.url.split("/")[2] if exc.request is not None else "its origin"
            failed = f"fetching the Crazyflie part failed: cannot reach {host}.\n"
        except (requests.RequestException, ValueError, OSError) as exc:
            failed = f"fetching the Crazyflie part failed: {type(exc).__name__}: {exc}\n"
        if failed and created:  # no empty folders left, which would read as the data's place
            for folder in [*sorted(created[0].rglob("*"), reverse=True), *reversed(created)]:
                with contextlib.suppress(OSError):
                    folder.rmdir()  # only an empty folder goes
    missing = _missing()
    if missing:
        pytest.exit(
            f"the tests read real flight data from {DATA}; missing there:\n"
            + "".join(f"  {part}: {NEEDED[part]}\n" for part in missing) + failed
            + f"Put them there (the Crazyflie part: `python -m pinquad.data fetch crazyflie "
            f"--cache {DATA / 'crazyflie'}` where the network reaches GitHub), or set "
            f"{WITHOUT_DATA}=1 to run the tests that need none (the others then fail).",
            returncode=2)


def random_stable_model(rng: np.random.Generator, n: int = 4, m: int = 3) -> LinearGaussianModel:
    """A random linear-Gaussian model with spectral radius 0.95."""
    a = rng.standard_normal((n, n))
    a *= 0.95 / max(abs(np.linalg.eigvals(a)))
    c = rng.standard_normal((m, n))
    lq = rng.standard_normal((n, n)) * 0.3
    lr = rng.standard_normal((m, m)) * 0.3
    return LinearGaussianModel(
        a=a, c=c, q=lq @ lq.T + 0.05 * np.eye(n), r=lr @ lr.T + 0.1 * np.eye(m),
        m0=rng.standard_normal(n), p0=np.eye(n),
    )


@pytest.fixture
def linear_case():
    """A random stable model, 60 steps of data with about 20 % of the entries missing."""
    rng = np.random.default_rng(7)
    model = random_stable_model(rng)
    _, ys = model.simulate(60, rng)
    ys[rng.random(ys.shape) < 0.2] = np.nan
    ys[5] = np.nan
    return model, ys


def write_with_paper_guess(log, path: Path) -> Path:
    """Write ``log`` to ``path`` (CSV or Parquet) with the paper's initial guess (m0 = 1 g,
    I0) in its sidecar; the written path."""
    from pinquad.core.params import PAPER_INITIAL_INERTIA, PAPER_INITIAL_MASS
    from pinquad.io.logs import write_log

    written = Path(write_log(log, path))
    sidecar_path = Path(f"{written}.json")
    sidecar = json.loads(sidecar_path.read_text())
    sidecar["mass_guess"] = PAPER_INITIAL_MASS
    sidecar["inertia_guess"] = np.asarray(PAPER_INITIAL_INERTIA).tolist()
    sidecar_path.write_text(json.dumps(sidecar))
    return written


def offline_on_csv(log, path: Path, out: Path, *options: str) -> subprocess.CompletedProcess:
    """Write ``log`` to the CSV ``path`` with the paper's initial guess (m0 = 1 g, I0) in
    its sidecar and run ``python -m pinquad.offline --log path --out out *options``."""
    written = write_with_paper_guess(log, path)
    return subprocess.run(
        [sys.executable, "-m", "pinquad.offline", "--log", str(written), "--out", str(out),
         *options], capture_output=True, text=True, timeout=900)


def row_from_written_report(name: str, path: str, report: dict, seconds: float) -> BatchRow:
    """A batch row (``experiments.batch.BatchRow``) read back from the report.json its
    log's run wrote: the rows as the batch built them before it carried the numbers
    themselves, kept here to show the two agree."""
    def number(value: object) -> float:
        return float("nan") if value is None else float(value)

    est = report["estimates"]
    verdict = est.get("verdict") or report.get("verdict") or {}
    se = est.get("stderr") or {}
    run = (report.get("runs") or [{}])[0]
    stat = run.get("stderr_statistical") or {}
    rebuilt = (run.get("motor_split") or {}).get("rebuilt_motors") or []
    source = report.get("source") or {}
    vehicle = str(source.get("vehicle") or "")
    named = source.get("vehicle_named", True) is not False
    return BatchRow(
        name=name, path=path,
        status="trusted" if verdict.get("overall", "") == "trusted" else "not trusted",
        mass=float(est["mass"]), mass_se=number(se.get("mass")),
        inertia_diag=tuple(float(v) for v in np.diag(np.asarray(est["inertia"], dtype=float))),
        inertia_se=tuple(number(v) for v in (se.get("inertia_diag") or NAN3)),
        overall=verdict.get("overall", ""),
        verdicts={k: v.get("verdict", "") for k, v in verdict.get("parameters", {}).items()},
        effects=tuple(s["effect"] for s in (report.get("discovery") or {}).get("selected", [])),
        seconds=seconds, error="", vehicle=vehicle,
        group=(vehicle if named else f"{name} (no vehicle named)") + (
            "" if not rebuilt else ", motor(s) " + ", ".join(f"M{int(i)}" for i in rebuilt)
            + " rebuilt from PWM"),
        stat_se=(number(stat.get("mass")),
                 *(number(v) for v in (stat.get("inertia_diag") or NAN3))))
