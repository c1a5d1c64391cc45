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


def _damped_modes(n, springs, dampers, floors, count):
    """Modes of a fixed-fixed chain (unit masses) with dampers between the
    storeys, by numpy's eig of the first-order state matrix: frequency
    |p| / 2 pi, damping ratio -Re p / |p|, each shape divided by its largest
    component and its real part taken."""
    def lap(v):
        a = np.zeros((n, n))
        for j, x in enumerate(v):
            if j >= 1:
                a[j - 1, j - 1] += x
            if j < n:
                a[j, j] += x
            if 1 <= j < n:
                a[j - 1, j] -= x
                a[j, j - 1] -= x
        return a

    k, c = lap(springs), lap(dampers)
    a = np.block([[np.zeros((n, n)), np.eye(n)], [-k, -c]])
    lam, vec = np.linalg.eig(a)
    keep = lam.imag > 0
    lam, vec = lam[keep], vec[:, keep]
    order = np.argsort(np.abs(lam))[:count]
    modes = []
    for j in order:
        psi = vec[:n, j]
        psi = (psi / psi[np.argmax(np.abs(psi))]).real
        modes.append(
            {
                "frequency": abs(lam[j]) / (2 * np.pi),
                "damping": -lam[j].real / abs(lam[j]),
                "phi": {i: psi[i - 1] for i in floors},
            }
        )
    return modes


def test_a_changed_damper_is_searched_from_damped_modes():
    n = 8
    springs = np.ones(n + 1)
    springs[4] = 0.7
    dampers = np.full(n + 1, 0.03)
    dampers[2] = 0.3
    modes = _damped_modes(n, springs, dampers, [1, 3, 6, 8], 4)
    r = springmass.update_from_modes(
        modes, n=n, damping="between:0.03", defects="auto", kinds="spring,damper"
    )
    assert r["status"] == "converged", r["summary"]
    assert r["damping_ratios"] == "fitted"
    found = {(d["kind"], d["at"]): d["factor"] for d in r["defects"]}
    assert set(found) == {("spring", 4), ("damper", 2)}, r["summary"]
    assert abs(found[("spring", 4)] - 0.7) < 0.01
    # an undamped nominal leaves the ratios out and says so; a damper
    # search then has nothing to fit
    plain = springmass.update_from_modes(modes, n=n, defects="auto")
    assert plain["damping_ratios"] == "not used"
    with pytest.raises(ValueError, match="kinds"):
        springmass.update_from_modes(modes, n=n, defects="auto", kinds="damper")
