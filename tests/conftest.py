"""Shared test fixtures."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from estimators.linear import LinearGaussianModel


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
