"""springmass.fit: intervals at a level and probabilities over hypotheses."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import springmass
from conftest import run_cli, write_csv


def _record(seed: int = 2):
    t = np.linspace(0.0, 150.0, 601)
    x = springmass.simulate(5, defects=[("mass", 2, 3.0), ("mass", 4, 0.5)], t=t, noise="rel:1e-3", seed=seed)
    return t, x


def test_intervals_and_probabilities_as_the_command_line(tmp_path, cli):
    t, x = _record()
    r = springmass.fit(t, x, n=5, level=0.8)
    assert r.level == 0.8
    for e in r.defects:
        lo, hi = e.interval
        assert lo < e.value < hi, e
        assert e.interval_method in ("wald", "profile", "profile-bounded")
    assert r.answer_probability > 0.9, r.summary
    top = r.hypotheses[0]
    assert [(d["kind"], d["at"]) for d in top["defects"]] == [("mass", 2), ("mass", 4)]
    assert math.isclose(sum(r.k_probability.values()), 1.0, rel_tol=1e-9)
    at = {(p["kind"], p["at"]): p["probability"] for p in r.position_probability}
    assert at[("mass", 2)] > 0.9 and at[("mass", 4)] > 0.9
    assert 0.0 <= r.pruned_bound <= 1.0
    assert "most probable" in str(r)
    # the command line gives the same numbers
    path = tmp_path / "x1.csv"
    write_csv(path, t, x)
    out = json.loads(run_cli(cli, "fit", "--data", str(path), "--n", "5", "--level", "0.8", "--json"))
    assert [d["interval"] for d in out["defects"]] == [list(e.interval) for e in r.defects]
    assert out["answer_probability"] == r.answer_probability


def test_without_uncertainty_and_bad_priors():
    t, x = _record()
    r = springmass.fit(t, x, n=5, defects=2, uncertainty=False)
    assert r.hypotheses == [] and all(e.interval is None for e in r.defects)
    with pytest.raises(ValueError, match="level"):
        springmass.fit(t, x, n=5, level=1.0)
    with pytest.raises(ValueError, match="prior_k"):
        springmass.fit(t, x, n=5, prior_k="site:0")
    with pytest.raises(ValueError, match="prior_range"):
        springmass.fit(t, x, n=5, prior_range="2:1")
    # a stated prior is reported
    r = springmass.fit(t, x, n=5, defects="auto:3", prior_k="site:0.1")
    assert "probability 0.1" in r.to_dict()["prior"]
