#!/usr/bin/env python3
"""Records per second of many whole-profile fits, on 1 and 2 (or more) cores.

200 records (by default) of a 6-mass chain (unit springs and masses,
grounded damping 0.1, fixed ends, an impulse on mass 1, x_1 sampled every
0.1 s to t = 60, 1% noise, one seed per record; spring 3 weakened by 5% from
the second half on) are simulated by `springmass.simulate` and written as CSV
files; each is then fitted by `springmass.fit_profile(..., profile="springs")`
in these ways, every one timed on the wall clock:

* `loop`: a plain Python loop (one core);
* `fit_many(workers=W)`: the package's thread pool (the fit releases the GIL);
* `dask processes=W`: the guide's Dask recipe, `client.map` over the files
  on a `LocalCluster(n_workers=W, threads_per_worker=1)` (worker processes,
  as on a cluster; skipped when dask.distributed is not installed).

Each fit runs on one thread (`RAYON_NUM_THREADS=1`, set before the package
is loaded), so W workers use W cores. The script checks that every way gives
the same numbers, then prints records per second and the speed-up over the
one-worker run of the same way.

    python3 benches/many_records.py [--records 200] [--workers 1,2]

Needs numpy and the springmass package; dask and distributed for the Dask
rows. On a shared machine, run it when the machine is otherwise idle: other
jobs on the cores lower the speed-up.
"""

import argparse
import os
import tempfile
import time

os.environ.setdefault("RAYON_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import springmass  # noqa: E402

N = 6
T = np.arange(0.0, 60.0, 0.1)


def write_records(folder, count):
    paths = []
    for r in range(count):
        defects = [("spring", 3, 0.95)] if r >= count // 2 else []
        x = springmass.simulate(N, defects=defects, t=T, noise="rel:0.01", seed=1000 + r)
        p = os.path.join(folder, f"rec-{r:04d}.csv")
        np.savetxt(p, np.column_stack([T, x]), delimiter=",", header="t,x1", comments="")
        paths.append(p)
    return paths


def fit_one(path):
    """One record's spring profile as plain data (the Dask task)."""
    t, cols = springmass.read_csv(path)
    r = springmass.fit_profile(t, cols["x1"], n=N, profile="springs")
    return [(v.at, v.value, v.se) for v in r.values]


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def run_dask(paths, workers):
    from dask.distributed import Client, LocalCluster

    with LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
        env={"RAYON_NUM_THREADS": "1"},
    ) as cluster, Client(cluster) as client:
        client.gather(client.map(fit_one, paths[:workers], pure=False))  # warm the workers
        return timed(lambda: client.gather(client.map(fit_one, paths)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--records", type=int, default=200)
    ap.add_argument("--workers", default="1,2", help="comma-separated worker counts")
    a = ap.parse_args()
    counts = [int(w) for w in a.workers.split(",")]
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        paths = write_records(folder, a.records)
        ref, sec = timed(lambda: [fit_one(p) for p in paths])
        rows.append(("loop", 1, sec))
        for w in counts:
            out, sec = timed(
                lambda: springmass.fit_many(paths, n=N, profile="springs", workers=w)
            )
            assert [[(v.at, v.value, v.se) for v in r.values] for r in out] == ref
            rows.append(("fit_many", w, sec))
        try:
            import distributed  # noqa: F401

            for w in counts:
                out, sec = run_dask(paths, w)
                assert out == ref
                rows.append(("dask processes", w, sec))
        except ImportError:
            print("dask.distributed is not installed: no Dask rows")
    print(f"{a.records} records, n = {N}, profile springs, {os.cpu_count()} cores")
    print(f"{'way':<16}{'workers':>8}{'seconds':>10}{'records/s':>11}{'speed-up':>10}")
    for way, w, sec in rows:
        one = next(s for wy, ww, s in rows if wy == way and ww == 1)
        print(f"{way:<16}{w:>8}{sec:>10.2f}{a.records / sec:>11.1f}{one / sec:>10.2f}")


if __name__ == "__main__":
    main()
