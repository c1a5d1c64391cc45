"""Model updating from measured modes: springmass.update_from_modes."""

import numpy as np
import pytest

import springmass

# SMU's four-storey laboratory frame (ywang-structures/Structural-Model-Updating,
# Examples/FourStoryStructure/Experiment/FourStoryStructure.mat): frequency (Hz),
# shape at floors 1-4.
SMU = [
    (0.8828984322951569, [-0.3781280960215331, -0.7191118305650045, -0.9636915486724337, -1.0]),
    (2.7477377900887126, [-1.0, -0.7201734981320075, 0.2634076723075865, 0.8350934438202613]),
    (4.299764477476899, [1.0, -0.9971093104159209, -0.3603933286217553, 0.6323742157247872]),
    (5.52947433791878, [-0.16875631028631874, 0.43459162996916845, -1.0, 0.6953574407015102]),
]


def test_smu_frame_predicts_the_held_out_modes():
    modes = []
    for j, (f, phi) in enumerate(SMU):
        floors = 3 if j < 2 else 4
        modes.append({"frequency": f, "phi": {i + 1: phi[i] for i in range(floors)}})
    r = springmass.update_from_modes(
        modes, n=4, mass=12.06 / 386.088, k=10.0, right="free", hold_out=[3, 4]
    )
    assert r["status"] == "converged", r["summary"]
    held = [m for m in r["modes"] if m["held_out"]]
    assert len(held) == 2
    for m in held:
        assert abs(m["frequency"] / m["measured_frequency"] - 1) < 0.025
    assert all(f["determined"] for f in r["factors"])


@pytest.mark.parametrize("residual", ["property", "dynamic"])
def test_both_modal_residuals_predict_smu_and_a_bad_name_is_refused(residual):
    modes = []
    for j, (f, phi) in enumerate(SMU):
        floors = 3 if j < 2 else 4
        modes.append({"frequency": f, "phi": {i + 1: phi[i] for i in range(floors)}})
    r = springmass.update_from_modes(
        modes, n=4, mass=12.06 / 386.088, k=10.0, right="free", hold_out=[3, 4],
        modal_residual=residual,
    )
    assert r["formulation"] == {"property": "property-difference", "dynamic": "dynamic-residual"}[residual]
    for m in r["modes"]:
        if m["held_out"]:
            assert abs(m["frequency"] / m["measured_frequency"] - 1) < 0.025
    with pytest.raises(ValueError) as e:
        springmass.update_from_modes(modes, n=4, right="free", modal_residual="energy")
    assert e.value.field == "modal_residual"


def test_a_csv_path_and_a_dict_baseline_give_the_same_answer(tmp_path):
    # exact modes of a 3-mass nonuniform chain, nominal = its baseline
    m = np.array([2.0, 1.0, 1.5])
    k = np.array([3.0, 2.0, 1.0, 0.0])  # right end free
    kk = np.zeros((3, 3))
    for j in range(4):
        for p, q, s in [(j - 1, j - 1, 1), (j, j, 1), (j - 1, j, -1), (j, j - 1, -1)]:
            if 0 <= p < 3 and 0 <= q < 3:
                kk[p, q] += s * k[j]
    mi = np.diag(1 / np.sqrt(m))
    w2, q = np.linalg.eigh(mi @ kk @ mi)
    phi = mi @ q
    rows = ["frequency,phi_1,phi_2,phi_3"]
    for j in range(2):
        rows.append(",".join(repr(float(v)) for v in [np.sqrt(w2[j]) / (2 * np.pi), *phi[:, j]]))
    path = tmp_path / "modes.csv"
    path.write_text("\n".join(rows) + "\n")
    base = {"mass": list(m), "spring": list(k)}
    r = springmass.update_from_modes(path, n=3, right="free", baseline=base)
    assert r["status"] == "converged", r["summary"]
    for f in r["factors"]:
        assert abs(f["factor"] - 1.0) < 1e-6


def test_bad_modes_name_the_field(tmp_path):
    with pytest.raises(ValueError, match="frequency"):
        springmass.update_from_modes([{"frequency": -1.0, "phi": {1: 1.0}}], n=2)
    with pytest.raises(ValueError, match="phi_5"):
        springmass.update_from_modes([{"frequency": 1.0, "phi": {5: 1.0, 1: 0.5}}], n=2)
    with pytest.raises(ValueError, match="modes"):
        springmass.update_from_modes(str(tmp_path / "missing.csv"), n=2)
    with pytest.raises(ValueError, match="modes"):
        springmass.update_from_modes([], n=2)
