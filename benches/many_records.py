#!/usr/bin/env python3
"""Records per second of many whole-profile fits, on 1 and 2 (or more) cores.

200 records (by default) of a 6-mass chain (unit springs and masses,
grounded damping 0.1, fixed ends, an impulse on mass 1, x_1 sampled every
0.1 s to t = 60, 1% noise, one seed per record; spring 3 weakened by 5% from
the second half on) are simulated by `springmass.simulate` and written as CSV
files; each is then fitted by `springmass.fit_profile(..., profile="springs")`
in these ways, every one timed on the wall clock:

* `loop`: a plain Python loop of `fit_profile` calls;
* `fit_many`: the package's thread pool, one thread per core (the fit
  releases the GIL);
* `dask`: the guide's Dask recipe, `client.map` over the files on a
  `LocalCluster(n_workers=C, threads_per_worker=1)` (worker processes, as
  on a cluster; skipped when dask.distributed is not installed).

Each core count C runs in a child process confined to the first C cores
(`os.sched_setaffinity` before the package is loaded: its thread pool and
the Dask workers see C cores). The script checks that every way gives the
same numbers, then prints records per second and the speed-up over the
same way on one core.

    python3 benches/many_records.py [--records 200] [--cores 1,2]

Needs numpy and the springmass package; dask and distributed for the Dask
rows. On a shared machine, run it when the machine is otherwise idle: other
jobs on the cores lower the speed-up.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

if __name__ == "__main__" and "--child" in sys.argv:
    # confine this process (and what it starts) to the first C cores before
    # the package's thread pool is created
    os.sched_setaffinity(0, range(int(sys.argv[sys.argv.index("--child") + 1])))

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
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, Client(cluster) as client:
        client.gather(client.map(fit_one, paths[:workers], pure=False))  # warm the workers
        return timed(lambda: client.gather(client.map(fit_one, paths)))


def child(folder, cores):
    """Every way on `cores` cores: {way: seconds}, checked against the loop."""
    paths = sorted(os.path.join(folder, f) for f in os.listdir(folder))
    ref, sec = timed(lambda: [fit_one(p) for p in paths])
    out = {"loop": sec}
    got, sec = timed(lambda: springmass.fit_many(paths, n=N, profile="springs", workers=cores))
    assert [[(v.at, v.value, v.se) for v in r.values] for r in got] == ref
    out["fit_many"] = sec
    try:
        import distributed  # noqa: F401
    except ImportError:
        return out
    got, sec = run_dask(paths, cores)
    assert got == ref
    out["dask"] = sec
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--records", type=int, default=200)
    ap.add_argument("--cores", default="1,2", help="comma-separated core counts")
    ap.add_argument("--child", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--folder", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        print(json.dumps(child(a.folder, a.child)))
        return
    counts = [int(c) for c in a.cores.split(",")]
    with tempfile.TemporaryDirectory() as folder:
        write_records(folder, a.records)
        runs = {}
        for c in counts:
            cmd = [sys.executable, __file__, "--child", str(c), "--folder", folder]
            out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
            runs[c] = json.loads(out.strip().splitlines()[-1])
    print(f"{a.records} records, n = {N}, profile springs; {os.cpu_count()} cores on the machine")
    print(f"{'way':<10}{'cores':>6}{'seconds':>10}{'records/s':>11}{'speed-up':>10}")
    for way in runs[counts[0]]:
        for c in counts:
            sec = runs[c][way]
            one = runs[counts[0]][way]
            print(f"{way:<10}{c:>6}{sec:>10.2f}{a.records / sec:>11.1f}{one / sec:>10.2f}")


if __name__ == "__main__":
    main()
