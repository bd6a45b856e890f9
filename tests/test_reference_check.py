"""An estimate against the vehicle file's [reference], an independent measurement of the
same body: 2 combined standard errors away, the parameter is not trusted."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pinquad.core.vehicle_file import VehicleFileError, load_vehicle
from pinquad.identification.reference import reference_values
from pinquad.identification.verdict import NOT_ADEQUATE, TRUSTED, VerdictEvidence, judge


def test_the_crazyflie_file_states_how_well_its_reference_is_known():
    ref = reference_values(load_vehicle("crazyflie21"))
    assert ref is not None
    np.testing.assert_allclose(ref.values, [0.0347, 16.57e-6, 16.66e-6, 29.26e-6])
    np.testing.assert_allclose(ref.stderr / ref.values, [0.003, 0.1, 0.1, 0.1])
    # a file that states no uncertainty has values to show, none to judge by
    assert reference_values(load_vehicle("paper")) is None


def test_an_estimate_far_from_the_reference_is_not_trusted():
    ref = reference_values(load_vehicle("crazyflie21"))
    mass, inertia = 0.0348, np.diag([16e-6, 17e-6, 15e-6])
    stderr = np.r_[0.0017, 1.2e-6, 1.2e-6, 5.7e-6]
    verdict = judge(mass, inertia, stderr, VerdictEvidence(reference=ref), None)
    # I_zz: |15 - 29.26| = 14.3 against sqrt(5.7^2 + 2.9^2) = 6.4: 2.2 combined errors
    assert verdict.get("I_zz").verdict == NOT_ADEQUATE
    assert "reference 29.26" in verdict.get("I_zz").reasons[0]
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
    from pinquad.identification.verdict import NOT_IDENTIFIABLE, ParameterVerdict
    from pinquad.realdata.consistency import _carried

    ref = reference_values(load_vehicle("crazyflie21"))
    far = judge(0.0348, np.diag([16e-6, 17e-6, 15e-6]), np.r_[0.0017, 1.2e-6, 1.2e-6, 5.7e-6],
                VerdictEvidence(reference=ref), None).get("I_zz")
    assert far.verdict == NOT_ADEQUATE and only_the_reference(far.reasons) and _carried(far)
    other = ParameterVerdict("I_zz", 15e-6, 9e-6, NOT_ADEQUATE, ("innovations too large",))
    unsure = ParameterVerdict("I_zz", 15e-6, 9e-6, NOT_IDENTIFIABLE, ("cover 30 %",))
    assert not _carried(other) and not _carried(unsure)
    assert not only_the_reference(())
