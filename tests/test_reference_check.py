"""An estimate against the vehicle file's [reference], an independent measurement of the
same body: 2 combined standard errors away, the parameter is not trusted."""

from __future__ import annotations

import json
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pinquad.cli.offline import build_parser, pipeline_options
from pinquad.core.vehicle_file import VehicleFileError, load_vehicle
from pinquad.identification.reference import log_reference, reference_values
from pinquad.identification.verdict import NOT_ADEQUATE, TRUSTED, VerdictEvidence, judge
from pinquad.io.logs import LogFormatError, read_table, write_log
from pinquad.pipeline import read
from pinquad.sim.simulator import SimConfig, flight_log, simulate


def test_the_crazyflie_file_states_how_well_its_reference_is_known():
    ref = reference_values(load_vehicle("crazyflie21"))
    assert ref is not None
    np.testing.assert_allclose(ref.values, [0.0347, 16.57e-6, 16.66e-6, 29.26e-6])
    np.testing.assert_allclose(ref.stderr / ref.values, [0.003, 0.1, 0.1, 0.1])


def test_an_estimate_far_from_the_reference_is_not_trusted():
    ref = reference_values(load_vehicle("crazyflie21"))
    mass, inertia = 0.0348, np.diag([16e-6, 17e-6, 15e-6])
    stderr = np.r_[0.0017, 1.2e-6, 1.2e-6, 5.7e-6]
    verdict = judge(mass, inertia, stderr, VerdictEvidence(reference=ref), None)
    # I_zz: |15 - 29.26| = 14.3 against sqrt(5.7^2 + 2.9^2) = 6.4: 2.2 combined errors
    assert verdict.get("I_zz").verdict == NOT_ADEQUATE
    assert "reference 29.26" in verdict.get("I_zz").reasons[0]
    assert "crazyflie21's [reference] (shipped with pinquad)" in verdict.get("I_zz").reasons[0]
    assert all(verdict.get(n).verdict == TRUSTED for n in ("mass", "I_xx", "I_yy"))
    # the same estimate with an error bar that covers the difference is trusted
    wide = np.r_[stderr[:3], 7.5e-6]
    assert judge(mass, inertia, wide, VerdictEvidence(reference=ref), None).trusted
    # and without a reference nothing is compared
    assert judge(mass, inertia, stderr, VerdictEvidence(), None).trusted


def test_a_reference_uncertainty_must_be_a_positive_number(tmp_path: Path):
    text = (Path(__file__).resolve().parents[1] / "pinquad" / "data" / "crazyflie21.toml"
            ).read_text().replace("inertia_rel_se = 0.10", "inertia_rel_se = -0.1")
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    (tmp_path / "crazyflie21.urdf").write_text(
        (Path(__file__).resolve().parents[1] / "pinquad" / "data" / "crazyflie21.urdf").read_text())
    with pytest.raises(VehicleFileError, match="reference.inertia_rel_se"):
        load_vehicle(str(bad))


def test_a_number_only_the_reference_rejects_still_counts_in_the_scatter_between_flights():
    """The flights' scatter measures what the model misses: an estimate that only the
    vehicle's reference rejects was carried by its flight and counts; one the flight did
    not carry does not."""
    from pinquad.identification.reference import only_the_reference
    from pinquad.identification.verdict import NOT_IDENTIFIABLE, Estimate
    from pinquad.realdata.consistency import _carried

    ref = reference_values(load_vehicle("crazyflie21"))
    far = judge(0.0348, np.diag([16e-6, 17e-6, 15e-6]), np.r_[0.0017, 1.2e-6, 1.2e-6, 5.7e-6],
                VerdictEvidence(reference=ref), None).get("I_zz")
    assert far.verdict == NOT_ADEQUATE and only_the_reference(far.reasons) and _carried(far)
    other = Estimate("I_zz", 15e-6, "kg m^2", 9e-6, (), NOT_ADEQUATE, ("innovations too large",))
    unsure = Estimate("I_zz", 15e-6, "kg m^2", 9e-6, (), NOT_IDENTIFIABLE, ("cover 30 %",))
    assert not _carried(other) and not _carried(unsure)
    assert not only_the_reference(())


SHIPPED = [Path(__file__).resolve().parents[1] / p for p in (
    "pinquad/data/paper.toml", "pinquad/data/crazyflie21.toml",
    "docs/vehicles/cf21_brushless.toml", "docs/vehicles/cf21_parrot_frame.toml",
    "docs/vehicles/quad250_plus.toml")]


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_every_shipped_file_states_how_well_it_knows_its_reference(path: Path):
    """Read as TOML, not through pinquad: each reference value has its own uncertainty."""
    ref = tomllib.loads(path.read_text())["reference"]
    if "mass" in ref:
        assert 0 < ref["mass_rel_se"] < 0.1
    if "inertia" in ref:
        assert 0 < ref["inertia_rel_se"] < 0.5


def _file(tmp_path: Path, reference: str, name: str = "other") -> str:
    """A vehicle file ``name``.toml whose [reference] is ``reference``, the rest the
    brushless build's (a new name for each: vehicle files are read once per path)."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "vehicles" / "cf21_brushless.toml"
            ).read_text()
    text = text[: text.index("[reference]")] + "[reference]\n" + reference
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return str(path)


def test_a_reference_without_its_uncertainty_is_judged_with_the_stated_default(tmp_path: Path):
    """A file of another vehicle: a 66.48 +- 1.16 g estimate (a brushed Crazyflie's
    rotor speeds through the brushless file's thrust map) against its 37 g without
    mass_rel_se. By hand: the default 2 % is 0.74 g, |66.48 - 37| / sqrt(1.16^2 + 0.74^2)
    = 29.48 / 1.376 = 21.4 combined standard errors. The file states no inertia, yet the
    inertia from the same flight is not trusted either."""
    ref = reference_values(load_vehicle(_file(tmp_path, "mass = 0.037\n")))
    assert ref is not None
    assert ref.stderr[0] == pytest.approx(0.037 * 0.02, rel=1e-12)
    assert np.isnan(ref.values[1:]).all()
    mass, inertia = 0.06648, np.diag([32.6e-6, 33.3e-6, 25.7e-6])
    stderr = np.r_[0.00116, 1.07e-6, 1.13e-6, 4.5e-6]
    verdict = judge(mass, inertia, stderr, VerdictEvidence(reference=ref), None)
    assert not verdict.trusted
    assert {p.name: p.verdict for p in verdict.parameters} == {
        "mass": NOT_ADEQUATE, "I_xx": NOT_ADEQUATE, "I_yy": NOT_ADEQUATE, "I_zz": NOT_ADEQUATE}
    why = verdict.get("mass").reasons[0]
    assert "21.4 combined standard errors" in why and "other.toml" in why
    assert "another vehicle" in why and "load" in why and "payload_mass" in why
    assert "other.toml" in verdict.get("I_xx").reasons[0]
    # an inertia alone off its reference (the mass agreeing) is the model's, not a load's
    pendulum = reference_values(load_vehicle(_file(
        tmp_path, "mass = 0.0665\ninertia = [32.6e-6, 33.3e-6, 45e-6]\ninertia_rel_se = 0.05\n",
        "pendulum")))
    alone = judge(mass, inertia, stderr, VerdictEvidence(reference=pendulum), None)
    assert [p.name for p in alone.parameters if not p.trusted] == ["I_zz"]
    assert "does not hold on this log" in alone.get("I_zz").reasons[0]
    assert "payload_mass" not in alone.get("I_zz").reasons[0]
    # the same estimate against its own vehicle's file (66.5 g stated) is trusted
    own = reference_values(load_vehicle(_file(tmp_path, "mass = 0.0665\n", "own")))
    assert judge(mass, inertia, stderr, VerdictEvidence(reference=own), None).trusted


def test_an_inertia_reference_without_its_uncertainty_is_judged_at_30_percent(tmp_path: Path):
    """By hand: I_xx 16.5 +- 1 against a stated 30e-6 at the default 30 % (9e-6):
    13.5 / sqrt(1 + 81) = 1.49 combined errors, agrees; against 100e-6 (30e-6):
    83.5 / 30.02 = 2.8, disagrees, and only I_xx."""
    inertia = np.diag([16.5e-6, 17e-6, 30e-6])
    stderr = np.r_[0.0008, 1e-6, 1e-6, 5e-6]
    near = reference_values(load_vehicle(_file(
        tmp_path, "mass = 0.037\nmass_rel_se = 0.01\ninertia = [30e-6, 17e-6, 30e-6]\n")))
    assert judge(0.037, inertia, stderr, VerdictEvidence(reference=near), None).trusted
    far = reference_values(load_vehicle(_file(
        tmp_path, "mass = 0.037\nmass_rel_se = 0.01\ninertia = [100e-6, 17e-6, 30e-6]\n",
        "far")))
    verdict = judge(0.037, inertia, stderr, VerdictEvidence(reference=far), None)
    assert verdict.get("I_xx").verdict == NOT_ADEQUATE
    assert "2.8 combined standard errors" in verdict.get("I_xx").reasons[0]
    assert all(verdict.get(n).trusted for n in ("mass", "I_yy", "I_zz"))


def test_a_declared_payload_moves_the_reference_mass(tmp_path: Path):
    """A 37 g vehicle flying with a 7.4 g payload (44.4 g): 45.1 +- 0.8 g is 9.2 combined
    standard errors from 37 +- 0.37 g (by hand: 8.1 / sqrt(0.8^2 + 0.37^2) = 8.1 / 0.881),
    and 0.8 from 44.4 +- 0.37 g (0.7 / 0.881) when the payload is declared in the log's
    sidecar."""
    vehicle = _file(tmp_path, "mass = 0.037\nmass_rel_se = 0.01\n")
    log = flight_log(simulate(SimConfig(sensor="B"), np.random.default_rng(3))).slice(0, 50)
    path = write_log(log, tmp_path / "flight.csv")
    side = Path(str(path) + ".json")
    raw = json.loads(side.read_text())
    raw["vehicle"] = vehicle
    side.write_text(json.dumps(raw))
    assert read_table(path).meta.payload_mass == 0.0
    plain = log_reference(read_table(path).meta)
    raw["payload_mass"] = 0.0074
    side.write_text(json.dumps(raw))
    meta = read_table(path).meta
    assert meta.payload_mass == 0.0074
    loaded = log_reference(meta)
    assert plain is not None and loaded is not None
    assert loaded.values[0] == pytest.approx(0.0444, rel=1e-12)
    assert loaded.stderr[0] == pytest.approx(0.00037, rel=1e-12)  # the file's part only
    assert "payload 7.4 g" in loaded.source
    inertia, stderr = np.diag([17e-6, 17e-6, 30e-6]), np.r_[0.0008, 1e-6, 1e-6, 6e-6]
    without = judge(0.0451, inertia, stderr, VerdictEvidence(reference=plain), None)
    assert without.get("mass").verdict == NOT_ADEQUATE
    assert "9.2 combined standard errors" in without.get("mass").reasons[0]
    assert judge(0.0451, inertia, stderr, VerdictEvidence(reference=loaded), None).trusted
    # the payload round-trips through pinquad's own export of the log
    again = write_log(read_table(path), tmp_path / "again.csv")
    assert read_table(again).meta.payload_mass == 0.0074
    raw["payload_mass"] = -0.001
    side.write_text(json.dumps(raw))
    with pytest.raises(LogFormatError, match=r"flight\.csv\.json.*payload_mass"):
        read_table(path)


def test_the_command_line_declares_a_payload_over_the_sidecar(tmp_path: Path, capsys):
    """--payload-mass reaches the log the pipeline judges, over the sidecar's value; a
    negative mass is refused by the parser (exit code 2, the option named)."""
    log = flight_log(simulate(SimConfig(sensor="B"), np.random.default_rng(3))).slice(0, 50)
    path = write_log(replace(log, meta=replace(log.meta, payload_mass=0.002)),
                     tmp_path / "flight.csv")
    args = build_parser().parse_args(["--log", str(path), "--payload-mass", "0.0074"])
    options = pipeline_options(args)
    assert options.payload_mass == 0.0074
    assert read(path, options.vehicle, options.payload_mass).meta.payload_mass == 0.0074
    assert read(path).meta.payload_mass == 0.002  # the sidecar's, when no option is given
    with pytest.raises(SystemExit) as stop:
        build_parser().parse_args(["--log", str(path), "--payload-mass", "-0.01"])
    assert stop.value.code == 2
    assert "--payload-mass" in capsys.readouterr().err
