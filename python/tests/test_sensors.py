"""springmass.fit with several sensors: x as samples x sensors, observe a list."""

from __future__ import annotations

import json

import numpy as np
import pytest

import springmass
from conftest import run_cli


@pytest.fixture(scope="module")
def two_sensors():
    """n = 12, a mass defect at 9, displacements of masses 1 and 12, 1% noise."""
    t = np.arange(0, 120, 0.5)
    x = springmass.simulate(12, t=t, defects=[("mass", 9, 2.0)], observe=[1, 12], noise="rel:0.01", seed=5)
    return t, x.T


def test_two_sensors_fit_jointly_and_agree_with_the_cli(two_sensors, cli, tmp_path):
    t, x = two_sensors
    r = springmass.fit(t, x, n=12, observe=[1, 12], defects=1, uncertainty=False)
    assert [(e.kind, e.at) for e in r.defects] == [("mass", 9)], r.summary
    assert abs(r.defects[0].value - 2.0) < 4 * r.defects[0].se
    assert [(s["at"], s["kind"], s["samples"]) for s in r.sensors] == [
        (1, "displacement", len(t)),
        (12, "displacement", len(t)),
    ]
    assert all(s["sigma"] > 0 for s in r.sensors)
    # the first sensor's series is the predicted one
    assert r.predicted.shape == t.shape
    # the same numbers as the command line on the same file
    path = tmp_path / "rec.csv"
    rows = ["t,a,b"] + [f"{a!r},{b!r},{c!r}" for a, b, c in zip(t.tolist(), x[:, 0].tolist(), x[:, 1].tolist())]
    path.write_text("\n".join(rows) + "\n")
    out = run_cli(
        cli, "fit", "--data", path, "--n", "12", "--observe", "1,12", "--column", "a,b",
        "--defects", "1", "--no-uncertainty", "--json",
    )
    j = json.loads(out)
    assert j["defects"][0]["at"] == 9
    assert j["defects"][0]["value"] == pytest.approx(r.defects[0].value, rel=1e-12)
    assert [s["sigma"] for s in j["sensors"]] == pytest.approx([s["sigma"] for s in r.sensors], rel=1e-12)


def test_one_column_and_an_int_is_the_one_sensor_fit(two_sensors):
    t, x = two_sensors
    a = springmass.fit(t, x[:, 0], n=12, defects=1, uncertainty=False)
    b = springmass.fit(t, x[:, :1], n=12, observe=[1], defects=1, uncertainty=False)
    assert a.defects[0].at == b.defects[0].at
    assert a.defects[0].value == b.defects[0].value
    assert a.sensors == [] and b.sensors == []


@pytest.mark.parametrize(
    "observe, kinds, field",
    [
        ([1], "displacement", "observe"),  # one mass for two columns
        ([1, 1], "displacement", "observe"),  # the same mass twice
        ([1, 13], "displacement", "observe"),  # outside the chain
        ([1, 12], ["displacement"] * 3, "observe_kind"),  # kinds of the wrong length
    ],
)
def test_bad_sensors_name_the_field(two_sensors, observe, kinds, field):
    t, x = two_sensors
    with pytest.raises(ValueError) as e:
        springmass.fit(t, x, n=12, observe=observe, observe_kind=kinds, defects=1, uncertainty=False)
    assert getattr(e.value, "field", None) == field, str(e.value)
