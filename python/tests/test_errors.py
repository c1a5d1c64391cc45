"""Bad input raises ValueError (OSError for files) naming the field, with the library's message."""

from __future__ import annotations

import numpy as np
import pytest

import springmass


@pytest.fixture
def record():
    t = np.arange(0, 40, 0.5)
    return t, springmass.simulate(5, defects=[("mass", 2, 3.0)], t=t)


def raises(field, fn, *args, **kwargs):
    with pytest.raises(ValueError) as info:
        fn(*args, **kwargs)
    e = info.value
    assert getattr(e, "field", None) == field, f"{e!r} names {getattr(e, 'field', None)!r}, not {field!r}"
    assert field in str(e)
    return e


def test_nan_in_x(record):
    t, x = record
    x = x.copy()
    x[3] = np.nan
    e = raises("x[3]", springmass.fit, t, x, n=5)
    assert str(e) == "invalid x[3] = NaN: allowed finite (no NaN or inf)"
    assert e.kind == "InvalidParameter" and e.allowed == "finite (no NaN or inf)"


def test_t_not_increasing(record):
    t, x = record
    t = t.copy()
    t[5] = t[4]
    e = raises("t[5]", springmass.fit, t, x, n=5)
    assert "strictly greater than t[4]" in str(e)


def test_n_zero_and_negative(record):
    t, x = record
    e = raises("n", springmass.fit, t, x, n=0)
    assert str(e) == "invalid n = 0: allowed 1 <= n <= 1000000000"
    raises("n", springmass.fit, t, x, n=-3)
    raises("n", springmass.simulate, 0, t=t)
    raises("n", springmass.response, 0.5, n=0)


def test_unknown_kind(record):
    t, x = record
    e = raises("kinds", springmass.fit, t, x, n=5, kinds="atom")
    assert str(e) == "invalid kinds = atom: allowed mass, spring, damper, ground, any or mass-or-spring"
    raises("kinds", springmass.fit, t, x, n=5, defects=2, kinds=["mass", "atom"])
    e = raises("defect", springmass.simulate, 5, t=t, defects=[("atom", 2, 3.0)])
    assert "unknown kind" in str(e)


def test_other_options_name_their_field(record):
    t, x = record
    raises("defects", springmass.fit, t, x, n=5, defects=6)
    raises("defects", springmass.fit, t, x, n=5, defects="many")
    raises("misfit", springmass.fit, t, x, n=5, misfit="l2")
    raises("method", springmass.fit, t, x, n=5, method="anneal")
    raises("noise", springmass.fit, t, x, n=5, noise=-1.0)
    raises("fit", springmass.fit, t, x, n=5, fit=("d", "q"))
    raises("d", springmass.fit, t, x, n=5, d=float("nan"))
    raises("seed", springmass.fit, t, x, n=5, seed=-1)
    raises("left", springmass.simulate, 5, t=t, left="hinged")
    raises("observe_kind", springmass.response, 0.5, n=5, observe_kind="jerk")


def test_shapes_and_types_name_the_array(record):
    t, x = record
    raises("x", springmass.fit, t, np.vstack([x, x]), n=5)
    raises("x", springmass.fit, t, x[:-1], n=5)  # one value per time
    raises("x", springmass.fit, t, x.astype(complex), n=5)
    raises("x", springmass.fit, t, ["a"] * len(t), n=5)
    raises("t[2]", springmass.simulate, 5, t=[0.0, 0.5, 1.5])  # not a uniform grid
    raises("t[0]", springmass.simulate, 5, t=[0.5, 1.0, 1.5])  # not from 0


def test_unresolvable_and_os_errors():
    # a light, deep defect cannot be located from exact data at s >= 1
    s = [1.0, 2.0, 4.0]
    X = springmass.response(s, n=20, defects=[("mass", 18, 1.001)])
    with pytest.raises(springmass.UnresolvableError) as info:
        springmass.locate(n=20, s=s, values=X, m=1.001)
    assert isinstance(info.value, ValueError) and info.value.kind == "Unresolvable"
    with pytest.raises(OSError) as info:
        springmass.read_csv("no-such-dir/no-such-file.csv")
    assert info.value.kind == "Io" and "no-such-file.csv" in str(info.value)


def test_jobs_above_the_memory_budget_are_refused_not_attempted():
    t = np.arange(0, 10, 0.5)
    e = raises_kind("ResourceLimit", springmass.simulate, 10**9, t=t)
    assert "SPRINGMASS_MEMORY_BUDGET" in str(e)
    raises_kind("ResourceLimit", springmass.controls, 10**9 - 1, t=t)


def raises_kind(kind, fn, *args, **kwargs):
    with pytest.raises(ValueError) as info:
        fn(*args, **kwargs)
    assert info.value.kind == kind, repr(info.value)
    return info.value
