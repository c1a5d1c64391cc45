"""Array input in any dtype, container and memory layout; shapes of the outputs."""

from __future__ import annotations

import numpy as np

import springmass


def test_float32_lists_and_float64_give_the_same_fit(s1_record):
    t, x = s1_record
    x32 = x.astype(np.float32)
    t32 = t.astype(np.float32)  # the grid 0, 0.25, ... is exact in float32
    a = springmass.fit(t32, x32, n=5, defects=2)
    b = springmass.fit(t.tolist(), x32.astype(np.float64).tolist(), n=5, defects=2)
    assert a.to_dict()["defects"] == b.to_dict()["defects"]
    assert a.predicted.dtype == np.float64
    assert [e.at for e in a.defects] == [2, 4]


def test_non_contiguous_arrays_are_read_with_their_strides(s1_record):
    t, x = s1_record
    both = np.asfortranarray(np.stack([t, x], axis=1))  # columns are contiguous...
    rows = np.stack([t, x])  # ...rows of a C array are too; a column of it is not
    wide = np.zeros((len(t), 3))
    wide[:, 0], wide[:, 2] = t, x
    assert not wide[:, 2].flags["C_CONTIGUOUS"]
    ref = springmass.fit(t, x, n=5, defects=2).to_dict()
    for tt, xx in [(both[:, 0], both[:, 1]), (rows[0], rows[1]), (wide[:, 0], wide[:, 2])]:
        got = springmass.fit(tt, xx, n=5, defects=2).to_dict()
        assert got["defects"] == ref["defects"] and got["chi2"] == ref["chi2"]
    # every other sample: a strided view, fitted like its copy
    half = springmass.fit(t[::2], x[::2], n=5, defects=2).to_dict()
    copy = springmass.fit(t[::2].copy(), x[::2].copy(), n=5, defects=2).to_dict()
    assert half["defects"] == copy["defects"]


def test_simulate_shapes_and_cli_agreement(cli, tmp_path):
    from conftest import run_cli

    t = np.arange(0, 20.25, 0.5)
    one = springmass.simulate(5, t=t, defects=["mass:2:3"], noise="rel:0.01", seed=4)
    two = springmass.simulate(5, t=t, defects=["mass:2:3"], observe=[1, 3], noise="rel:0.01", seed=4)
    assert one.shape == t.shape and two.shape == (2, len(t))
    assert np.array_equal(two[0], one)  # row c uses seed + c
    csv = tmp_path / "sim.csv"
    run_cli(cli, "simulate", "--n", "5", "--defect", "mass:2:3", "--t-end", "20", "--dt", "0.5",
            "--observe", "1,3", "--noise", "rel:0.01", "--seed", "4", "--out", csv)
    tc, cols = springmass.read_csv(csv)
    np.testing.assert_allclose(tc, t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(cols["x1"], two[0], rtol=1e-12, atol=0)
    np.testing.assert_allclose(cols["x3"], two[1], rtol=1e-12, atol=0)


def test_simulate_is_deterministic_with_a_seed():
    t = np.arange(0, 10, 0.1)
    a = springmass.simulate(4, t=t, noise=1e-3, seed=5)
    b = springmass.simulate(4, t=t, noise=1e-3, seed=5)
    c = springmass.simulate(4, t=t, noise=1e-3, seed=6)
    clean = springmass.simulate(4, t=t)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert 0.5e-3 < np.std(a - clean) < 2e-3


def test_response_keeps_shape_and_dtype():
    s3 = springmass.scene("S3")
    s = np.array([[0.1, 0.5], [1.0, 2.0]])
    real = springmass.response(s, **s3.chain())
    cplx = springmass.response(s.astype(complex), **s3.chain())
    assert real.shape == (2, 2) and real.dtype == np.float64
    assert cplx.shape == (2, 2) and cplx.dtype == np.complex128
    np.testing.assert_allclose(cplx.real, real, rtol=1e-14)
    assert np.all(cplx.imag == 0)
    one = springmass.response(0.5, **s3.chain())
    assert np.ndim(one) == 0 and float(one) == real[0, 1]
    assert springmass.response([0.5], **s3.chain()).shape == (1,)
    # X(conj s) = conj X(s): a real system
    z = np.array([0.2 + 1.5j, 0.05 + 0.3j])
    np.testing.assert_allclose(springmass.response(z.conj(), **s3.chain()), springmass.response(z, **s3.chain()).conj())


def test_laplace_of_a_simulation_matches_the_response():
    # the time stepper and the closed form agree through the series transform
    s2 = springmass.scene("S2")
    t = np.arange(0, 300, 0.05)
    x = springmass.simulate(t=t, **s2.chain())
    s = np.array([0.2, 0.5 + 1j, 1.0])
    tr = springmass.laplace(t, x, s)
    want = springmass.response(s, **s2.chain())
    assert tr.value.shape == s.shape and tr.value.dtype == np.complex128
    assert np.all(np.abs(tr.value - want) <= 10 * tr.err + 1e-12)
    assert np.all(tr.err < 1e-6) and tr.noise_std is None
    noisy = springmass.laplace(t, x, s.reshape(3, 1), noise_sigma=1e-3)
    assert noisy.noise_std.shape == (3, 1) and np.all(noisy.noise_std > 0)


def test_controls_are_the_theorem_forces():
    # F(s) = -sinh(3 l)/sinh((n+2) l), G(s) = sinh(2 l)/sinh((n+2) l),
    # F1(s) = -sinh(l)/sinh(n l), cosh(l) = 1 + (s^2 + d s)/2 (unit m, k, gamma)
    n, d = 4, 0.1
    t = np.arange(0, 400, 0.02)
    c = springmass.controls(n, t=t, d=d)
    assert sorted(c) == ["f", "f1", "g"] and all(v.shape == t.shape for v in c.values())
    assert c["f"][0] == 0 and c["g"][0] == 0
    s = 0.7
    lam = np.arccosh(1 + (s * s + d * s) / 2)
    want = {
        "f": -np.sinh(3 * lam) / np.sinh((n + 2) * lam),
        "g": np.sinh(2 * lam) / np.sinh((n + 2) * lam),
        "f1": -np.sinh(lam) / np.sinh(n * lam),
    }
    for name, w in want.items():
        tr = springmass.laplace(t, c[name], s)
        assert abs(tr.value.real - w) < 1e-8 + 10 * tr.err, name


def test_locate_from_a_series_and_from_laplace_values():
    p3 = springmass.scene("P3")  # n = 20, mass 5 at 3
    t = np.arange(0, 300, 0.01)
    x = springmass.simulate(t=t, **p3.chain())
    loc = springmass.locate(t, x, n=20, m=5.0)
    assert loc.position == 3 and loc.method == "exact"
    assert abs(loc.j - 3) + 3 * loc.sigma + loc.model_error < 0.5
    s = np.geomspace(0.01, 1, 13)
    X = springmass.response(s, **p3.chain())
    free = springmass.locate(n=20, s=s, values=X)
    assert free.position == 3 and free.method == "unknown-mass"
    assert abs(free.mass - 5.0) < 1e-6
