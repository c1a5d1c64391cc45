"""springmass.fit_scene: scenes with several sensors, several records and modal data."""

from __future__ import annotations

import json

import numpy as np
import pytest

import springmass
from conftest import run_cli

MODAL = """
[truth]
n = 6
right = "free"
defects = [{ kind = "spring", at = 4, k = 0.75 }]
[data]
source = "modes"
modes = 3
floors = [2, 4, 6]
frequency_noise = 0.002
shape_noise = 0.01
seed = 3
[unknowns]
kind = "spring"
"""


def test_a_modal_scene_from_text_and_file_agrees_with_the_cli(cli, tmp_path):
    r = springmass.fit_scene(MODAL)
    assert r["status"] == "converged", r["summary"]
    d = r["defects"][0]
    assert (d["kind"], d["at"]) == ("spring", 4)
    assert abs(d["k"] - 0.75) < 4 * r["std_errors"][0]
    assert "spring at 4" in r["summary"]
    path = tmp_path / "modal.toml"
    path.write_text(MODAL)
    assert springmass.fit_scene(path)["defects"] == r["defects"]
    out = json.loads(run_cli(cli, "fit", "--scene", path, "--json"))
    assert out["defects"] == r["defects"]


def test_a_series_scene_with_two_sensors(tmp_path):
    t = np.arange(0, 120, 0.5)
    x = springmass.simulate(8, t=t, defects=[("mass", 6, 2.0)], observe=[1, 8], noise="rel:0.01", seed=2)
    path = tmp_path / "rec.csv"
    rows = ["t,a,b"] + [f"{a!r},{b!r},{c!r}" for a, b, c in zip(t.tolist(), x[0].tolist(), x[1].tolist())]
    path.write_text("\n".join(rows) + "\n")
    scene = (
        '[truth]\nn = 8\n[data]\nsource = "series"\n'
        f'path = "{path.as_posix()}"\nobserve = [1, 8]\ncolumn = ["a", "b"]\n[unknowns]\nk = 1\n'
    )
    r = springmass.fit_scene(scene)
    assert [(d["kind"], d["at"]) for d in r["defects"]] == [("mass", 6)], r["summary"]
    assert "2 sensors" in r["misfit"]


@pytest.mark.parametrize(
    "data, field",
    [
        ('source = "simulated"\nobserve = [1, 4]\nrecords = 2', "data.records"),
        ('source = "simulated"\nobserve = [1, 4]\nobserve_kind = ["velocity", "velocity", "velocity"]', "data.observe_kind"),
        ('source = "simulated"\nobserve = [1, 9]', "data.observe"),
        ('source = "modes"\nmodes = 0', "data.modes"),
    ],
)
def test_bad_scene_data_raise_value_error_naming_the_field(data, field):
    scene = f"[truth]\nn = 4\nright = \"free\"\n[data]\n{data}\n[unknowns]\nkind = \"spring\"\nk = 1\n"
    with pytest.raises(ValueError) as e:
        springmass.fit_scene(scene)
    assert e.value.field == field


def test_a_scene_that_is_neither_file_nor_text_is_refused(tmp_path):
    with pytest.raises(ValueError) as e:
        springmass.fit_scene(3)
    assert e.value.field == "scene"
    with pytest.raises(ValueError) as e:
        springmass.fit_scene(tmp_path / "missing.toml")
    assert e.value.field == "scene"


LONG = """
[truth]
n = 40
defects = [{ kind = "mass", at = 9, m = 2.5 }, { kind = "mass", at = 23, m = 0.5 }, { kind = "mass", at = 35, m = 1.8 }]
[unknowns]
k = 3
"""


def test_a_long_chain_scene_is_certified_without_ranking_every_set():
    r = springmass.fit_scene(LONG)
    assert r["certified"] and r["status"] == "converged", r["summary"]
    assert [d["at"] for d in r["defects"]] == [9, 23, 35]
    assert r["sets"] < 9880 and r["exhaustive"] is False
    every = springmass.fit_scene(LONG + "[search]\nexhaustive = true\n")
    assert not every["certified"] and every["exhaustive"] and every["sets"] == 9880
    assert [d["at"] for d in every["defects"]] == [9, 23, 35]
