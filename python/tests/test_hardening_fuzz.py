"""Issue 32's fuzz findings over the Python package (items 5, 7, 9, 11)."""

from __future__ import annotations

import os
import pathlib

import numpy as np
import pytest

import springmass


def _record(n: int = 201) -> tuple:
    t = np.arange(n) * 0.25
    return t, np.sin(0.9 * t) * np.exp(-0.05 * t)


def test_item7_profile_of_a_huge_chain_is_refused_before_allocating() -> None:
    t, x = _record()
    with pytest.raises(ValueError, match="SPRINGMASS_MEMORY_BUDGET"):
        springmass.fit_profile(t, x, n=10**6, profile="masses")


def test_item7_fit_of_a_huge_chain_is_refused_before_allocating() -> None:
    t, x = _record()
    with pytest.raises(ValueError, match="SPRINGMASS_MEMORY_BUDGET"):
        springmass.fit(t, x, n=10**9)


def test_item5_n_out_of_range_gives_one_allowed_range() -> None:
    t, x = _record()
    messages = []
    for n in (-3, 0, 2 * 10**9):
        with pytest.raises(ValueError) as e:
            springmass.fit(t, x, n=n)
        messages.append(str(e.value).split(": allowed ")[1])
    assert messages[0] == messages[1] == messages[2] == "1 <= n <= 1000000000"


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_item9_fifo_is_refused(tmp_path: pathlib.Path) -> None:
    fifo = tmp_path / "in.csv"
    os.mkfifo(fifo)
    with pytest.raises(OSError, match="FIFO"):
        springmass.read_csv(fifo)


def test_item9_extra_field_and_duplicate_names(tmp_path: pathlib.Path) -> None:
    for text, needle in [
        ("t,x1\n0,1\n19.25,1,5\n", "column 3"),
        ("t,t,x1\n0,1,2\n1,2,3\n", "same name"),
        ("0,1\n1,2\n", "no header"),
    ]:
        f = tmp_path / "bad.csv"
        f.write_text(text)
        with pytest.raises(ValueError, match=needle):
            springmass.read_csv(f)


def test_item11_read_csv_of_bytes_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="not bytes"):
        springmass.read_csv(b"t,x1\n0,1\n")


def test_item11_datetime_array_is_refused() -> None:
    t, x = _record()
    stamps = np.datetime64("2026-01-01") + np.arange(len(t)).astype("timedelta64[s]")
    with pytest.raises(ValueError, match="datetime"):
        springmass.fit(t, stamps, n=3)


def test_item11_laplace_beyond_f64_is_refused_as_the_cli_does() -> None:
    t, x = _record()
    with pytest.raises(ValueError, match="not representable"):
        springmass.laplace(t, x, [1e308 + 1e308j])


def test_item11_zero_impulse_is_refused() -> None:
    t, x = _record()
    for g in (0.0, 5e-324):
        with pytest.raises(ValueError, match="gamma"):
            springmass.fit(t, x, n=3, gamma=g)


def test_item13_all_zero_record_is_named() -> None:
    t, _ = _record()
    with pytest.raises(ValueError, match="every one 0"):
        springmass.fit(t, np.zeros_like(t), n=3)


def test_noise_sigma_beside_laplace_values_is_refused() -> None:
    s = [0.5, 1.0, 2.0]
    values = springmass.response(s, n=3, defects=["mass:2:2"])
    for sigma in (-1.0, float("nan"), 0.01):
        with pytest.raises(ValueError, match="noise_sigma"):
            springmass.locate(n=3, s=s, values=values, noise_sigma=sigma)


def test_huge_known_damping_fails_at_once() -> None:
    t, x = _record(40)
    with pytest.raises(springmass.NumericalError, match="beyond f64"):
        springmass.fit(t, x, n=3, defects=1, d=1e300)
