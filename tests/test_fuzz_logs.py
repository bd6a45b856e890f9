"""Property-based fuzzing of the log boundary (issue 21): mutated CSV, Parquet and
micro-SD logs and sidecars either fail with a LogFormatError whose message names the
file (and so the column, key, row or byte offset the reader located), or are accepted
and still give the right answer; never another exception, never a hang.

What runs per example: the reader (``pinquad.io.read.read_log``) and the physical checks
(``pinquad.io.sanity.check_log``), the boundary ``python -m pinquad.offline --log`` and
``pinquad.identify`` pass before any EM; for accepted micro-SD logs also the measured
flight's observations (``realdata.build_observations``). EM itself is not run per example
(about 20 s per log): an accepted log with thrust is scored by the mass its thrust
implies (``sanity.implied_mass``, vertical Newton's law), which must be within 10 % of
the truth of the mutated flight (0.18 kg times the factor a mutation scaled the thrust
by). Each example has a 5 s deadline (a hang fails).

Hypothesis runs derandomized (``derandomize=True``: the examples are a fixed function of
the test, the same on every machine); the case counts are ``EXAMPLES`` (printed by
``pytest -s``).
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pinquad
from pinquad.core.params import PAPER_INITIAL_INERTIA, PAPER_INITIAL_MASS, PAPER_SCENARIO
from pinquad.io.logs import LogFormatError, log_columns, sidecar
from pinquad.io.read import read_log
from pinquad.io.sanity import check_log, implied_mass
from pinquad.pipeline.identify import initial_guess
from pinquad.realdata.observations import build_observations
from pinquad.realdata.raw import raw_flight
from pinquad.sim.simulator import SimConfig

REPO = Path(__file__).resolve().parents[1]
SDLOG = REPO.parent / "shared" / "data" / "crazyflie" / "imrc_brushed" / "jana02"
TRUE_MASS = 0.18
EXAMPLES = {"csv": 60, "parquet": 30, "sdlog": 40, "sidecar": 60}
"""Examples per test (a fixed, derandomized set)."""

def fuzz(examples: int) -> settings:
    """Derandomized, no example database, a 5 s deadline per example."""
    return settings(derandomize=True, deadline=5000, database=None, max_examples=examples,
                    suppress_health_check=[HealthCheck.function_scoped_fixture,
                                           HealthCheck.too_slow])

SCENARIO = replace(PAPER_SCENARIO, start=np.array([0.0, 0.0, 0.0]),
                   waypoints=np.array([[0.0, 0.0, 1.0], [0.6, 0.4, 1.3]]), hover_time=1.0)


def _columns() -> tuple[dict[str, np.ndarray], dict]:
    log = pinquad.simulate(config=SimConfig(sensor="B", scenario=SCENARIO), seed=1)
    meta = replace(log.meta, mass_guess=PAPER_INITIAL_MASS,
                   inertia_guess=np.asarray(PAPER_INITIAL_INERTIA))
    cols = {k: v for k, v in log_columns(log).items() if not k.startswith(("true_", "est_"))}
    return cols, sidecar(meta)


COLUMNS, SIDECAR = _columns()
NAMES = list(COLUMNS)


def csv_bytes(cols: dict[str, np.ndarray]) -> bytes:
    names = list(cols)
    mat = np.column_stack([np.asarray(cols[k], dtype=float) for k in names])
    lines = [",".join(names)] + [",".join("" if math.isnan(v) else repr(float(v)) for v in row)
                                 for row in mat]
    return ("\n".join(lines) + "\n").encode()


# a column mutation: (kind, column, factor or value, row)
column_mutation = st.one_of(
    st.tuples(st.just("scale"), st.sampled_from(NAMES),
              st.sampled_from([-1.0, 0.5, 1.5, 2.0, 9.81, 1 / 9.81, 100.0, 1000.0, 1e-3,
                               180 / math.pi]), st.just(0)),
    st.tuples(st.just("extreme"), st.sampled_from(NAMES),
              st.sampled_from([1e300, -1e300, math.inf, -math.inf, math.nan, 0.0, 1e6]),
              st.integers(0, len(COLUMNS["t"]) - 1)),
    st.tuples(st.just("drop"), st.sampled_from(NAMES), st.just(0.0), st.just(0)),
    st.tuples(st.just("cut"), st.just("t"), st.just(0.0), st.integers(0, len(COLUMNS["t"]))),
)


def mutate_columns(mutation) -> tuple[dict[str, np.ndarray], float]:
    """The mutated columns and the factor the thrust was scaled by."""
    kind, name, value, row = mutation
    cols = {k: v.copy() for k, v in COLUMNS.items()}
    thrust_factor = 1.0
    if kind == "scale":
        cols[name] = cols[name] * value
        thrust_factor = value if name == "thrust" else 1.0
    elif kind == "extreme":
        cols[name][row] = value
    elif kind == "drop":
        del cols[name]
    else:
        cols = {k: v[:row] for k, v in cols.items()}
    return cols, thrust_factor


def byte_mutation(size: int):
    return st.one_of(
        st.tuples(st.just("cut"), st.integers(0, size), st.just(0)),
        st.tuples(st.just("flip"), st.integers(0, size - 1), st.integers(1, 255)),
    )


def mutate_bytes(data: bytes, mutation) -> bytes:
    kind, pos, bits = mutation
    if kind == "cut":
        return data[:pos]
    out = bytearray(data)
    out[pos] ^= bits
    return bytes(out)


def outcome(path: Path, thrust_factor: float = 1.0, measured: bool = False) -> str:
    """'rejected' (a LogFormatError, or the initial guess's ValueError, naming the file)
    or 'accepted' (and right); any other exception propagates and fails the test."""
    try:
        log = read_log(path)
        check_log(log)
        if not measured:
            initial_guess(log)  # identify_log's next step: positive guesses
    except (LogFormatError, ValueError) as exc:
        message = str(exc)
        assert str(path) in message, message  # names the file (or its sidecar)
        assert "\n" not in message.strip() and "Traceback" not in message
        return "rejected"
    if measured:
        real = build_observations(raw_flight(log))
        assert real.obs.n > 0
        return "accepted"
    mass = implied_mass(log)
    assert mass is not None
    assert mass == pytest.approx(TRUE_MASS * thrust_factor, rel=0.10), (mass, thrust_factor)
    return "accepted"


def _tally(counts: dict, key: str) -> None:
    counts[key] = counts.get(key, 0) + 1


@pytest.fixture(scope="module")
def tally() -> dict:
    counts: dict[str, int] = {}
    yield counts
    print(f"\nfuzz outcomes: {counts}")


@fuzz(EXAMPLES["csv"])
@given(mutation=st.one_of(column_mutation.map(lambda m: ("cols", m)),
                          byte_mutation(len(csv_bytes(COLUMNS))).map(lambda m: ("bytes", m))))
def test_mutated_csv_is_rejected_by_name_or_identified_right(mutation, tmp_path_factory, tally):
    path = tmp_path_factory.mktemp("csv") / "flight.csv"
    kind, m = mutation
    if kind == "cols":
        cols, factor = mutate_columns(m)
        data = csv_bytes(cols)
    else:
        data, factor = mutate_bytes(csv_bytes(COLUMNS), m), 1.0
    path.write_bytes(data)
    Path(f"{path}.json").write_text(json.dumps(SIDECAR))
    _tally(tally, f"csv {outcome(path, factor)}")


@fuzz(EXAMPLES["parquet"])
@given(mutation=column_mutation)
def test_mutated_parquet_is_rejected_by_name_or_identified_right(mutation, tmp_path_factory,
                                                                 tally):
    path = tmp_path_factory.mktemp("pq") / "flight.parquet"
    cols, factor = mutate_columns(mutation)
    pq.write_table(pa.table({k: np.asarray(v, dtype=float) for k, v in cols.items()}), path)
    Path(f"{path}.json").write_text(json.dumps(SIDECAR))
    _tally(tally, f"parquet {outcome(path, factor)}")


@pytest.fixture(scope="module")
def sdlog_bytes() -> bytes:
    assert SDLOG.exists(), f"{SDLOG}: the shipped Crazyflie logs are missing"
    return SDLOG.read_bytes()


@fuzz(EXAMPLES["sdlog"])
@given(mutation=byte_mutation(383279))
def test_mutated_sdlog_is_rejected_by_name_or_read_whole(mutation, sdlog_bytes,
                                                         tmp_path_factory, tally):
    path = tmp_path_factory.mktemp("sd") / "jana02"
    path.write_bytes(mutate_bytes(sdlog_bytes, mutation))
    _tally(tally, f"sdlog {outcome(path, measured=True)}")


json_values = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6),
                        st.floats(allow_nan=False), st.text(max_size=8),
                        st.lists(st.floats(-1, 1), max_size=10),
                        st.lists(st.lists(st.floats(0, 1e-3), min_size=3, max_size=3),
                                 min_size=3, max_size=3))


@fuzz(EXAMPLES["sidecar"])
@given(side=st.one_of(
    st.tuples(st.just("key"), st.sampled_from(["vehicle", "mass_guess", "inertia_guess",
                                               "gravity"]), json_values),
    st.tuples(st.just("document"), st.just(""), json_values),
    st.tuples(st.just("bytes"), st.just(""), byte_mutation(len(json.dumps(SIDECAR)))),
))
def test_mutated_sidecar_is_rejected_by_name_or_harmless(side, tmp_path_factory, tally):
    path = tmp_path_factory.mktemp("side") / "flight.csv"
    path.write_bytes(csv_bytes(COLUMNS))
    kind, key, value = side
    if kind == "key":
        text = json.dumps({**SIDECAR, key: value})
    elif kind == "document":
        text = json.dumps(value)
    else:
        text = mutate_bytes(json.dumps(SIDECAR).encode(), value).decode("latin-1")
    Path(f"{path}.json").write_text(text, encoding="latin-1")
    _tally(tally, f"sidecar {outcome(path)}")
