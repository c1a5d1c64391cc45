"""springmass.fit: round trips, agreement with the command line, determinism, the GIL."""

from __future__ import annotations

import json
import math
import sys
import threading

import numpy as np
import pytest

import springmass
from conftest import run_cli, write_csv


def test_round_trip_recovers_system3_at_one_percent_noise():
    # the paper's System 3 (n = 20, masses 5 at 8 and 2 at 15), simulated,
    # 1% white noise; the fit is told n only: sigma unknown, k chosen by BIC
    # (k_max = 3 keeps the test at seconds: k = 4 alone enumerates 4845 sets)
    s3 = springmass.scene("S3")
    t = np.linspace(0.0, 200.0, 1001)
    clean = springmass.simulate(t=t, **s3.chain())
    x = springmass.simulate(t=t, noise="rel:0.01", seed=1, **s3.chain())
    r = springmass.fit(t, x, n=s3.n, defects="auto:3")
    assert r.k == 2, r.summary
    assert [(e.kind, e.at) for e in r.defects] == [(d.kind, d.at) for d in s3.defects]
    for e, truth in zip(r.defects, s3.defects):
        assert abs(e.value - truth.value) < 4 * e.se, e
        assert 0 < e.se < 0.2 * truth.value
    assert r.sigma_estimated
    sigma_true = 0.01 * np.max(np.abs(clean))
    assert abs(r.sigma / sigma_true - 1) < 0.2, (r.sigma, sigma_true)
    assert r.status == "converged" and r.fits_data, r.summary
    # every mass and spring the answer leaves unchanged (every kind sought)
    # would show halved or doubled
    assert r.unseen is not None and r.unseen["elements"] == [], r.unseen
    assert (r.unseen["checked"], r.unseen["of"]) == (39, 39), r.unseen
    # k raised past 2 only where one or two more defects could win
    assert [row.k for row in r.k_selection] in ([0, 1, 2], [0, 1, 2, 3])
    assert min(r.k_selection, key=lambda row: row.criterion).k == 2
    assert r.predicted.shape == t.shape
    np.testing.assert_allclose(r.residual, x - r.predicted, rtol=0, atol=1e-15)
    # the residual is noise-sized: the model is close to the clean record
    assert np.std(r.predicted - clean) < 0.5 * sigma_true


def close(a, b, path="report"):
    """Equal structure, equal strings/ints/bools, floats within 1e-12."""
    if isinstance(a, dict):
        assert set(a) == set(b), f"{path}: keys {sorted(a)} != {sorted(b)}"
        for k in a:
            close(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), f"{path}: length {len(a)} != {len(b)}"
        for i, (u, v) in enumerate(zip(a, b)):
            close(u, v, f"{path}[{i}]")
    elif isinstance(a, float) or isinstance(b, float):
        assert isinstance(a, (int, float)) and isinstance(b, (int, float)), f"{path}: {a!r} vs {b!r}"
        assert math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-300), f"{path}: {a!r} vs {b!r}"
    else:
        assert a == b, f"{path}: {a!r} != {b!r}"


CLI_CASES = {
    "defaults": (["--defects", "auto:2"], {"defects": "auto:2"}),
    "known-noise-any-kind-fitted-d": (
        ["--noise", "5e-4", "--kinds", "any", "--defects", "1", "--fit", "d", "--d", "0.12"],
        {"noise": 5e-4, "kinds": "any", "defects": 1, "fit": ("d",), "d": 0.12},
    ),
    "ga-bromwich-aic": (
        ["--defects", "auto:2", "--method", "ga", "--seed", "3", "--max-evals", "1500", "--misfit", "bromwich",
         "--criterion", "aic"],
        {"defects": "auto:2", "method": "ga", "seed": 3, "max_evals": 1500, "misfit": "bromwich", "criterion": "aic"},
    ),
}


@pytest.mark.parametrize("case", sorted(CLI_CASES))
def test_python_fit_equals_the_cli_json_of_the_same_csv(case, cli, s1_record, tmp_path):
    t, x = s1_record
    csv = tmp_path / "x1.csv"
    write_csv(csv, t, x)
    args, kwargs = CLI_CASES[case]
    want = json.loads(run_cli(cli, "fit", "--data", csv, "--n", "5", *args, "--json"))
    tr, cols = springmass.read_csv(csv)
    assert np.array_equal(tr, t) and np.array_equal(cols["x1"], x)  # the CSV is exact
    got = springmass.fit(tr, cols["x1"], n=5, **kwargs).to_dict()
    predicted = got.pop("predicted")
    assert np.array_equal(predicted["observed"], x)
    for d in (got, want):
        d.pop("wall_time_s")
    close(got, want)
    assert want["defects"], "the case should find defects"


def test_known_noise_is_used_not_estimated(s1_record):
    t, x = s1_record
    r = springmass.fit(t, x, n=5, defects=2, noise=2e-3)
    assert not r.sigma_estimated and r.sigma == 2e-3
    assert [e.at for e in r.defects] == [2, 4]
    assert r.criterion == "given" and len(r.k_selection) == 1


def test_result_fields_and_to_dict(s1_record):
    t, x = s1_record
    r = springmass.fit(t, x, n=5, defects="auto:2")
    assert r.k == 2 and [e.at for e in r.defects] == [2, 4]
    assert str(r) == r.summary and "mass at 2" in r.summary
    d = r.to_dict()
    assert d["k"] == 2 and d["noise_sigma"] == r.sigma and d["status"] == r.status
    assert [row["k"] for row in d["k_selection"]] == [0, 1, 2]
    json.dumps(d)  # plain Python objects
    alt = r.alternatives[0]
    assert alt.gap > 0 and all(isinstance(a, springmass.Defect) for a in alt.defects)
    assert r.defects[0].defect == springmass.Defect("mass", 2, r.defects[0].value)


def test_slot_kinds_and_known_defects(s1_record):
    t, x = s1_record
    r = springmass.fit(t, x, n=5, defects=1, known=[("mass", 2, 3.0)], kinds=["mass"])
    known = [e for e in r.defects if e.known]
    assert [(e.at, e.value, e.se) for e in known] == [(2, 3.0, 0.0)]
    assert [e.at for e in r.defects if not e.known] == [4]


def test_ground_spring_kind_round_trip():
    # a spring from mass 7 to the ground, found by kinds="ground" with sigma unknown
    t = np.arange(0.0, 200.0 + 1e-9, 0.25)
    x = springmass.simulate(12, t=t, defects=[("ground", 7, 0.3)], noise="rel:1e-3", seed=3)
    r = springmass.fit(t, x, n=12, defects=1, kinds="ground")
    (e,) = r.defects
    assert (e.kind, e.at) == ("ground", 7)
    assert abs(e.value - 0.3) < 4 * e.se and e.se > 1e-8


def test_relax_method_seeds_the_fit_from_the_profile(s1_record):
    t, x = s1_record
    r = springmass.fit(t, x, n=5, method="relax")
    assert r.method.startswith("relax")
    assert [e.at for e in r.defects] == [2, 4]


def test_seeded_stochastic_fit_is_reproducible(s1_record):
    t, x = s1_record
    kw = dict(n=5, defects=2, method="pso", max_evals=1500)
    a = springmass.fit(t, x, seed=7, **kw)
    b = springmass.fit(t, x, seed=7, **kw)
    da, db = a.to_dict(), b.to_dict()
    for d in (da, db):
        d.pop("wall_time_s")
    assert da == db


def test_fit_releases_the_gil(s1_record):
    # With a long switch interval a thread keeps the GIL until it blocks or
    # releases it: the main thread can run while the fit runs only if the fit
    # released it (float64 inputs: numpy makes no copy that could release it)
    t, x = s1_record
    done = threading.Event()

    def work():
        springmass.fit(t, x, n=5, defects=2)
        done.set()

    old = sys.getswitchinterval()
    sys.setswitchinterval(100.0)
    try:
        th = threading.Thread(target=work)
        th.start()
        ran_during_fit = not done.is_set()
        th.join()
    finally:
        sys.setswitchinterval(old)
    assert done.is_set()
    assert ran_during_fit


def test_real_setup_shear_frame_from_the_roof_accelerometer():
    # a 5-storey frame struck at its free roof, storey 2 weakened by 30%,
    # the roof's acceleration at 1% noise; kind and noise unknown
    t = np.arange(0, 120.0 + 1e-9, 0.1)
    a = springmass.simulate(5, defects=[("spring", 2, 0.7)], t=t, d=0.02, left="free",
                            observe_kind="acceleration", noise="rel:1e-2", seed=1)
    r = springmass.fit(t, a, n=5, d=0.02, left="free", observe_kind="acceleration",
                       kinds="any", defects=1)
    (e,) = r.defects
    assert (e.kind, e.at) == ("spring", 2)
    assert abs(e.value - 0.7) < 3 * e.se
    assert "acceleration" in r.to_dict()["setup"] and "free-fixed" in r.to_dict()["setup"]
    with pytest.raises(ValueError, match="left"):
        springmass.fit(t, a, n=5, left="loose")
    with pytest.raises(ValueError, match="observe"):
        springmass.fit(t, a, n=5, observe=9)


def test_a_record_with_a_pre_trigger_segment_gets_its_blow_time():
    # the logger started 5 time units before the blow: 25 samples at rest,
    # on an axis from -5 (the blow at 0 of that axis)
    t = np.linspace(0.0, 100.0, 501)
    x = springmass.simulate(5, defects=[("mass", 2, 3.0)], t=t, noise="rel:1e-3", seed=4)
    t_axis = np.concatenate([np.linspace(-5.0, -0.2, 25), t])
    x_axis = np.concatenate([np.zeros(25) + 1e-4 * np.sin(np.arange(25.0)), x])
    r = springmass.fit(t_axis, x_axis, n=5, defects=1)
    assert [(e.kind, e.at) for e in r.defects] == [("mass", 2)], r.summary
    assert r.trigger is not None and r.trigger["detected"]
    assert abs(r.trigger["time"]) < 4 * r.trigger["se"] + 1e-3, r.trigger
    given = springmass.fit(t_axis, x_axis, n=5, defects=1, trigger=0.0)
    assert not given.trigger["detected"]
    with pytest.raises(ValueError, match="trigger"):
        springmass.fit(t_axis, x_axis, n=5, defects=1, trigger=[1])
    with pytest.raises(ValueError, match="force_window"):
        springmass.fit(t, x, n=5, force=np.ones_like(t), force_window="soon")


def test_several_records_are_fitted_jointly_and_a_foreign_one_is_named():
    # two hits of System 3 sampled differently, and one of another chain
    s3 = springmass.scene("S3")
    ta = np.linspace(0.0, 200.0, 1001)
    tb = np.linspace(0.0, 150.0, 1501)
    xa = springmass.simulate(t=ta, noise="rel:0.01", seed=1, **s3.chain())
    xb = springmass.simulate(t=tb, noise="rel:0.01", seed=2, **s3.chain())
    r = springmass.fit(ta, xa, n=20, defects="auto:3", records=[(tb, xb)])
    assert [(e.at) for e in r.defects] == [8, 15], r.summary
    assert r.status == "converged", r.summary
    assert [s["record"] for s in r.sensors] == [1, 2]
    assert [s["samples"] for s in r.sensors] == [1001, 1501]
    assert all(s["fits_data"] for s in r.sensors), r.sensors
    other = springmass.simulate(20, defects=[("mass", 8, 5.0), ("mass", 12, 3.0)], t=ta, noise="rel:0.01", seed=3)
    bad = springmass.fit(ta, xa, n=20, defects="auto:3", records=[(tb, xb), (ta, other)])
    assert bad.status == "model-mismatch", bad.summary
    assert [s["fits_data"] for s in bad.sensors] == [True, True, False], bad.sensors
    assert "record 3" in bad.message
    with pytest.raises(ValueError, match="records"):
        springmass.fit(ta, xa, n=20, records=[(tb,)])


def _modal_record(n, masses, zeta, t, level, seed):
    """x_1(t) after a unit impulse on mass 1 of a fixed-fixed chain of unit
    springs whose every mode has the damping ratio zeta (or, for a list,
    mode j the ratio zeta[j], the last for every higher mode): numpy's own
    modal sum (not the library's)."""
    def ratios(w):
        return np.array([np.atleast_1d(zeta)[min(j, np.size(zeta) - 1)] for j in range(w.size)])

    return _modal_sum(n, masses, ratios, t, level, seed)


def _modal_sum(n, masses, ratios, t, level, seed):
    """The modal sum of _modal_record with the ratios ratios(w) of the
    undamped frequencies w (ascending), plus white noise of level times the
    peak."""
    m = np.ones(n)
    for at, v in masses:
        m[at - 1] = v
    k = 2.0 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1)
    mh = 1.0 / np.sqrt(m)
    w2, q = np.linalg.eigh(mh[:, None] * k * mh[None, :])
    w = np.sqrt(w2)  # ascending (eigh)
    zeta = ratios(w)
    phi1 = mh[0] * q[0, :]
    wd = w * np.sqrt(1.0 - zeta**2)
    x = (phi1**2 * np.exp(-zeta * w * t[:, None]) * np.sin(wd * t[:, None]) / wd).sum(axis=1)
    rng = np.random.default_rng(seed)
    return x + level * np.abs(x).max() * rng.standard_normal(t.size)


def test_modal_damping_is_simulated_fitted_and_chosen():
    t = np.arange(0.0, 120.5, 0.5)
    masses = [(2, 3.0), (4, 0.5)]
    exact = _modal_record(5, masses, 0.03, t, 0.0, 0)
    sim = springmass.simulate(5, defects=[("mass", 2, 3.0), ("mass", 4, 0.5)], t=t, d=0.0, damping="modal:0.03")
    assert np.abs(sim - exact).max() < 1e-9 * np.abs(exact).max()
    x = _modal_record(5, masses, 0.03, t, 1e-2, 11)
    given = springmass.fit(t, x, n=5, damping="modal", fit=("d",))
    chosen = springmass.fit(t, x, n=5, fit=("d",))
    for r in (given, chosen):
        assert [(e.kind, e.at) for e in r.defects] == [("mass", 2), ("mass", 4)], r.summary
        for e, (_, v) in zip(r.defects, masses):
            assert abs(e.value - v) < 3 * e.se, r.summary
        assert r.damping["model"] == "modal", r.damping
        assert abs(r.damping["zeta"] - 0.03) < 3 * r.damping["se"]["zeta"], r.damping
    assert [c["model"] for c in chosen.damping["candidates"]] == ["grounded", "between", "rayleigh", "modal"]
    # models fitted only at the chosen set do no better there; every model
    # searched (effort="high") chooses the same
    at = [e.at for e in chosen.defects]
    best = next(c for c in chosen.damping["candidates"] if c["model"] == "modal")
    assert best["searched"]
    for c in chosen.damping["candidates"]:
        if not c["searched"]:
            assert c["positions"] == at and c["criterion"] >= best["criterion"], c
    every = springmass.fit(t, x, n=5, fit=("d",), effort="high")
    assert all(c["searched"] for c in every.damping["candidates"])
    assert every.damping["model"] == "modal" and [e.at for e in every.defects] == at
    with pytest.raises(ValueError, match="damping.zeta"):
        springmass.simulate(5, t=t, damping="modal:7")


def test_a_ratio_per_mode_is_simulated_and_fitted():
    t = np.arange(0.0, 120.5, 0.5)
    masses = [(2, 3.0), (4, 0.5)]
    zeta = [0.01, 0.05, 0.02]  # modes 1, 2, and 3 to 5
    exact = _modal_record(5, masses, zeta, t, 0.0, 0)
    sim = springmass.simulate(5, defects=[("mass", 2, 3.0), ("mass", 4, 0.5)], t=t, d=0.0, damping="modal:0.01,0.05,0.02")
    assert np.abs(sim - exact).max() < 1e-9 * np.abs(exact).max()
    x = _modal_record(5, masses, zeta, t, 1e-3, 12)
    r = springmass.fit(t, x, n=5, damping="modal:0.03,0.03,0.03", fit=("d",))
    assert [(e.kind, e.at) for e in r.defects] == [("mass", 2), ("mass", 4)], r.summary
    for e, (_, v) in zip(r.defects, masses):
        assert abs(e.value - v) < 3 * e.se, r.summary
    for j, z in enumerate(zeta):
        name = f"zeta_{j + 1}"
        assert abs(r.damping[name] - z) < 3 * r.damping["se"][name], r.damping
    with pytest.raises(ValueError, match=r"damping.zeta\[1\]"):
        springmass.simulate(5, t=t, damping="modal:0.01,-1")


def test_any_kind_is_searched_with_the_kinds_narrowed_per_position():
    # n = 12, a mass (2 at 4) and a spring (0.5 at 8), 1% noise: with the
    # kind unknown and k left to BIC, the search from k = 2 on takes its
    # kinds per position from the sensitivities at k - 1 (the report says
    # so), and its answer is the full product's at the same k
    t = np.arange(0.0, 200.0, 0.1)
    defects = [("mass", 4, 2.0), ("spring", 8, 0.5)]
    x = springmass.simulate(12, t=t, defects=defects, noise="rel:0.01", seed=3)
    r = springmass.fit(t, x, n=12, kinds="any")
    assert [(e.kind, e.at) for e in r.defects] == [("mass", 4), ("spring", 8)], r.summary
    assert r.status == "converged", r.summary
    assert "kinds narrowed per position" in r.method, r.method
    assert not r.to_dict()["exhaustive"]
    # every kind is the default: the same fit; masses only is a mismatch,
    # and a search that places masses only seeks masses by default
    default = springmass.fit(t, x, n=12)
    assert default.to_dict()["defects"] == r.to_dict()["defects"]
    masses = springmass.fit(t, x, n=12, kinds="mass")
    assert masses.status != "converged" and "--kinds any" in masses.message, masses.summary
    ga = springmass.fit(t, x, n=12, defects=2, method="ga", max_evals=200)
    assert {e.kind for e in ga.defects} == {"mass"}, ga.summary
    full = springmass.fit(t, x, n=12, kinds="any", defects=2)
    assert "narrowed" not in full.method and full.to_dict()["exhaustive"]
    assert [(e.kind, e.at) for e in full.defects] == [(e.kind, e.at) for e in r.defects]
    for a, b in zip(r.defects, full.defects):
        assert abs(a.value - b.value) <= 0.01 * b.se, (a, b)


def test_searches_from_three_defects_are_nested_unless_exhaustive():
    # n = 14, three masses, 0.1% noise: with k left to BIC the searches at
    # k = 3 and 4 extend the best answers at one defect fewer (the report
    # says so); exhaustive=True searches every set and finds the same
    t = np.arange(0.0, 150.0, 0.25)
    defects = [("mass", 2, 1.6), ("mass", 7, 0.6), ("mass", 11, 2.5)]
    x = springmass.simulate(14, t=t, defects=defects, noise="rel:0.001", seed=5)
    quick = springmass.fit(t, x, n=14, uncertainty=False)
    every = springmass.fit(t, x, n=14, uncertainty=False, exhaustive=True)
    assert [(e.kind, e.at) for e in quick.defects] == [("mass", 2), ("mass", 7), ("mass", 11)], quick.summary
    assert "nested in the best" in quick.method, quick.method
    assert not quick.to_dict()["exhaustive"]
    assert every.to_dict()["exhaustive"] and "nested" not in every.method, every.method
    assert [(e.kind, e.at) for e in every.defects] == [(e.kind, e.at) for e in quick.defects]
    for a, b in zip(quick.defects, every.defects):
        assert abs(a.value - b.value) <= 0.05 * b.se, (a, b)


def test_effort_trades_the_search_for_time_and_names_its_level():
    # the same record at the three levels of effort: the same answer here;
    # the report's method names a level other than normal, and high
    # searches every set (exhaustive); a level outside the three is refused
    t = np.arange(0.0, 150.0, 0.25)
    defects = [("mass", 3, 0.5), ("mass", 9, 2.0)]
    x = springmass.simulate(12, t=t, defects=defects, noise="rel:0.01", seed=7)
    runs = {e: springmass.fit(t, x, n=12, uncertainty=False, effort=e) for e in ("low", "normal", "high")}
    for e, r in runs.items():
        assert [(d.kind, d.at) for d in r.defects] == [("mass", 3), ("mass", 9)], (e, r.summary)
    assert "[effort low]" in runs["low"].method, runs["low"].method
    assert "effort" not in runs["normal"].method, runs["normal"].method
    assert "[effort high]" in runs["high"].method and runs["high"].to_dict()["exhaustive"]
    ev = [runs[e].to_dict()["evaluations"] for e in ("low", "normal", "high")]
    assert ev[0] <= ev[1] <= ev[2], ev
    with pytest.raises(ValueError, match="effort"):
        springmass.fit(t, x, n=12, effort="max")


def _rayleigh_record(n, masses, a, b, t, level, seed):
    """x_1(t) of _modal_record's chain with the Rayleigh damping
    C = a M + b K: its modes are the undamped ones with the ratios
    a / (2 w) + b w / 2."""
    return _modal_sum(n, masses, lambda w: a / (2.0 * w) + b * w / 2.0, t, level, seed)


def test_a_wrong_damping_model_given_is_checked_against_the_others():
    # a Rayleigh-damped record fitted with the between-storey model given:
    # its fit needs coloured noise (AR(5), a damper at 8 beside a mass at
    # 9), so the other models are fitted with white noise, and the Rayleigh
    # model explains the record
    t = np.arange(0.0, 200.5, 0.5)
    masses = [(8, 5.0), (15, 2.0)]
    x = _rayleigh_record(20, masses, 0.05, 0.01, t, 1e-2, 0)
    r = springmass.fit(t, x, n=20, damping="between", fit=("d",), defects=2)
    assert r.status == "model-mismatch" and not r.resolved, r.summary
    assert "rayleigh damping explains it with white noise (mass@8, mass@15" in r.message, r.summary
    assert r.damping["model"] == "between" and r.damping["checked"], r.damping
    assert "rayleigh" in [c["model"] for c in r.damping["candidates"]], r.damping
    # the right model given needs no check
    right = springmass.fit(t, x, n=20, damping="rayleigh", fit=("d",), defects=2)
    assert [(e.kind, e.at) for e in right.defects] == [("mass", 8), ("mass", 15)], right.summary
    assert right.status == "converged" and "checked" not in right.damping, right.summary
