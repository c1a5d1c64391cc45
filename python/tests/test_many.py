"""Many records: fit_many on a thread pool, Ctrl-C, and the Dask recipe."""

from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest

import springmass

T = np.arange(0.0, 60.0, 0.1)


def _records(count: int, tmp_path=None):
    """Records of a 4-mass chain, spring 2 at 0.95 from the third on;
    written as CSV files under `tmp_path` when given."""
    recs = []
    for r in range(count):
        defects = [("spring", 2, 0.95)] if r >= 2 else []
        x = springmass.simulate(4, defects=defects, t=T, noise="rel:0.01", seed=100 + r)
        if tmp_path is None:
            recs.append((T, x))
        else:
            p = tmp_path / f"rec-{r}.csv"
            np.savetxt(p, np.column_stack([T, x]), delimiter=",", header="t,x1", comments="")
            recs.append(p)
    return recs


def _springs(r: springmass.ProfileResult):
    return [(v.at, v.value, v.se) for v in r.values]


def test_threads_give_the_answers_of_one_call_each_in_order():
    recs = _records(4)
    one = [springmass.fit_profile(t, x, n=4, profile="springs") for t, x in recs]
    many = springmass.fit_many(recs, n=4, profile="springs", workers=2)
    assert [_springs(r) for r in many] == [_springs(r) for r in one]
    # the defect fit too, and a single worker
    d1 = springmass.fit_many(recs[:2], n=4, kinds="spring", workers=1)
    d2 = [springmass.fit(t, x, n=4, kinds="spring") for t, x in recs[:2]]
    key = lambda r: (r.k, [(e.kind, e.at, e.value) for e in r.defects], r.chi2)  # noqa: E731
    assert [key(r) for r in d1] == [key(r) for r in d2]


def test_paths_and_errors():
    bad = (T[:3], np.zeros(3))
    out = springmass.fit_many([_records(1)[0], bad], n=4, profile="springs", errors="return")
    assert isinstance(out[0], springmass.ProfileResult)
    assert isinstance(out[1], ValueError)
    with pytest.raises(ValueError):
        springmass.fit_many([bad], n=4, profile="springs")
    with pytest.raises(ValueError, match="workers"):
        springmass.fit_many([bad], n=4, workers=0)
    with pytest.raises(ValueError, match="errors"):
        springmass.fit_many([bad], n=4, errors="ignore")
    with pytest.raises(ValueError, match=r"records\[0\]"):
        springmass.fit_many([42], n=4)


def test_csv_paths(tmp_path):
    paths = _records(2, tmp_path)
    a = springmass.fit_many(paths, n=4, profile="springs", workers=2)
    b = springmass.fit_many(_records(2), n=4, profile="springs", workers=1)
    # the CSV holds the values to 18 digits: the same fit within rounding
    for ra, rb in zip(a, b):
        for (ia, va, _), (ib, vb, _) in zip(_springs(ra), _springs(rb)):
            assert ia == ib and abs(va - vb) < 1e-9


@pytest.mark.skipif(not hasattr(signal, "SIGINT"), reason="needs SIGINT")
def test_ctrl_c_stops_every_worker(ctrl_c):
    # System 3 searched for three defects of any kind: minutes of work per
    # record; SIGINT after one second
    s3 = springmass.scene("S3")
    t = np.linspace(0.0, 200.0, 1001)
    x = springmass.simulate(t=t, noise="rel:0.01", seed=1, **s3.chain())
    timer = threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT))
    start = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            springmass.fit_many([(t, x)] * 4, n=s3.n, kinds="any", defects="3", workers=2)
    finally:
        timer.cancel()
    assert time.monotonic() - start < 60
    # the stop request was cleared: the library works again
    r = springmass.fit_many([(t, x)], n=s3.n, defects="2")[0]
    assert [(e.kind, e.at) for e in r.defects] == [(d.kind, d.at) for d in s3.defects]


def _fit_one(path):
    """The Dask recipe's task: one record's spring profile, as plain data."""
    t, cols = springmass.read_csv(path)
    r = springmass.fit_profile(t, cols["x1"], n=4, profile="springs")
    return _springs(r)


def test_dask_recipe(tmp_path):
    distributed = pytest.importorskip(
        "distributed", reason="dask.distributed is not installed (pip install dask distributed)"
    )
    paths = [str(p) for p in _records(6, tmp_path)]
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None
    ) as cluster, distributed.Client(cluster) as client:
        got = client.gather(client.map(_fit_one, paths))
    want = [_fit_one(p) for p in paths]
    assert got == want
    # the weakened spring is seen from the third record on
    for r, springs in enumerate(got):
        s2 = next(v for at, v, _ in springs if at == 2)
        assert (abs(s2 - 0.95) < 0.01) if r >= 2 else (abs(s2 - 1.0) < 0.01)
