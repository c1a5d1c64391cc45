"""Output-only (ambient) fits: springmass.fit_ambient."""

import numpy as np
import pytest

import springmass


def _record(n=4, weak=2, factor=0.7, d=0.1, dt=0.5, samples=4000, sub=50, seed=3):
    """Displacements of masses 1 and n of a fixed-fixed chain under white
    forces on every mass (semi-implicit Euler at dt / sub), 5% sensor noise."""
    rng = np.random.default_rng(seed)
    k = np.ones(n + 1)
    k[weak] *= factor
    stiff = np.diag(k[:-1] + k[1:]) - np.diag(k[1:-1], 1) - np.diag(k[1:-1], -1)
    h = dt / sub
    x = np.zeros(n)
    v = np.zeros(n)
    out = np.empty((samples, 2))
    for i in range(-200, samples):
        for _ in range(sub):
            f = rng.standard_normal(n) / np.sqrt(h)
            v += h * (f - stiff @ x - d * v)
            x += h * v
        if i >= 0:
            out[i] = x[0], x[-1]
    out += 0.05 * out.std(axis=0) * rng.standard_normal(out.shape)
    return np.arange(samples) * dt, [out[:, 0], out[:, 1]]


def test_a_weak_storey_is_found_from_two_channels():
    t, channels = _record()
    r = springmass.fit_ambient((t, channels), observe=[1, 4], n=4, d=None, defects="auto:1")
    assert r["status"] == "converged", r["summary"]
    assert [(f["kind"], f["at"]) for f in r["factors"]] == [("spring", 2)], r["summary"]
    assert abs(r["factors"][0]["factor"] - 0.7) < 0.05, r["summary"]


def test_a_constant_channel_names_the_field():
    t = np.arange(3000) * 0.5
    with pytest.raises(ValueError, match="channel 2"):
        springmass.fit_ambient((t, [np.sin(t), np.ones_like(t)]), observe=[1, 4], n=4)


def test_a_force_band_is_passed_to_the_fit_and_checked():
    t, channels = _record()
    white = springmass.fit_ambient((t, channels), observe=[1, 4], n=4, defects="auto:1")
    # a band over every fitted frequency models the same white forces
    banded = springmass.fit_ambient(
        (t, channels), observe=[1, 4], n=4, defects="auto:1", ambient_band=(0.0, 20.0)
    )
    assert banded["force_band"] == [0.0, 20.0]
    assert banded["factors"] == white["factors"]
    assert "force band" in banded["summary"]
    for bad in [(2.0, 1.0), (0.0, float("nan")), "ab", 3.0]:
        with pytest.raises(ValueError, match="ambient_band"):
            springmass.fit_ambient((t, channels), observe=[1, 4], n=4, ambient_band=bad)
