#!/usr/bin/env python3
"""Records per second of many fits, on 1 and 2 (or more) cores.

`--kind profile` (default): 200 records (by default) of a 6-mass chain (unit springs and masses,
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

`--kind ambient`: 200 output-only records of a 12-mass chain (unit springs
and masses, grounded damping 0.1, fixed ends) under white forces on every
mass (the exact discretization of the state-space model, numpy's own,
independent of the package: displacements of masses 1, 6 and 12 sampled
every 0.5 s, 8000 samples, 5% sensor noise; spring 3 weakened by 10% from
the second half on), each fitted by `springmass.fit_ambient(...,
observe=[1, 6, 12], defects="auto:1")` (damping fitted): `loop`, `threads` (a
`concurrent.futures` thread pool of C threads: the fit releases the GIL)
and `dask` as above.

Each core count C runs in a child process confined to the first C cores
(`os.sched_setaffinity` before the package is loaded: its thread pool and
the Dask workers see C cores). The script checks that every way gives the
same numbers, then prints records per second and the speed-up over the
same way on one core.

    python3 benches/many_records.py [--kind profile|ambient] [--records 200] [--cores 1,2]

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


AMBIENT_N = 12
AMBIENT_OBSERVE = [1, 6, 12]
AMBIENT_DT = 0.5
AMBIENT_SAMPLES = 8000


def _expm(a):
    """exp(a) by scaling and squaring of a degree-20 Taylor sum (numpy only)."""
    norm = np.abs(a).sum(axis=1).max()
    j = max(0, int(np.ceil(np.log2(norm))) + 1) if norm > 0 else 0
    a = a / 2.0**j
    out = np.eye(len(a))
    term = np.eye(len(a))
    for i in range(1, 21):
        term = term @ a / i
        out = out + term
    for _ in range(j):
        out = out @ out
    return out


def ambient_generator(weak_factor):
    """The exact one-step map of the chain's state under white forces of unit
    spectral density on every mass (Van Loan): x_{j+1} = A x_j + chol(Q) z_j."""
    n = AMBIENT_N
    k = np.ones(n + 1)
    k[3] *= weak_factor  # spring 3: between masses 3 and 4 (k[0] is the left wall's)
    stiff = np.diag(k[:-1] + k[1:]) - np.diag(k[1:-1], 1) - np.diag(k[1:-1], -1)
    f = np.block([[np.zeros((n, n)), np.eye(n)], [-stiff, -0.1 * np.eye(n)]])
    g = np.vstack([np.zeros((n, n)), np.eye(n)])
    m = np.block([[-f, g @ g.T], [np.zeros_like(f), f.T]]) * AMBIENT_DT
    e = _expm(m)
    a = e[2 * n :, 2 * n :].T
    q = a @ e[: 2 * n, 2 * n :]
    return a, np.linalg.cholesky(0.5 * (q + q.T))


def write_ambient(folder, count):
    gens = {1.0: ambient_generator(1.0), 0.9: ambient_generator(0.9)}
    t = np.arange(AMBIENT_SAMPLES) * AMBIENT_DT
    paths = []
    for r in range(count):
        a, l = gens[0.9 if r >= count // 2 else 1.0]
        rng = np.random.default_rng(2000 + r)
        z = rng.standard_normal((AMBIENT_SAMPLES + 400, 2 * AMBIENT_N)) @ l.T
        x = np.zeros(2 * AMBIENT_N)
        seen = [j - 1 for j in AMBIENT_OBSERVE]
        out = np.empty((AMBIENT_SAMPLES, len(seen)))
        for i in range(-400, AMBIENT_SAMPLES):
            x = a @ x + z[i + 400]
            if i >= 0:
                out[i] = x[seen]
        out += 0.05 * out.std(axis=0) * rng.standard_normal(out.shape)
        p = os.path.join(folder, f"rec-{r:04d}.csv")
        header = ",".join(["t"] + [f"x{j}" for j in AMBIENT_OBSERVE])
        np.savetxt(p, np.column_stack([t, out]), delimiter=",", header=header, comments="")
        paths.append(p)
    return paths


def fit_ambient_one(path):
    """One ambient record's answer as plain data (the Dask task)."""
    r = springmass.fit_ambient(path, observe=AMBIENT_OBSERVE, n=AMBIENT_N, defects="auto:1")
    return [(f["kind"], f["at"], f["factor"], f["se"]) for f in r["factors"]]


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def run_dask(paths, workers, task=fit_one):
    from dask.distributed import Client, LocalCluster

    with LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, Client(cluster) as client:
        client.gather(client.map(task, paths[:workers], pure=False))  # warm the workers
        return timed(lambda: client.gather(client.map(task, paths)))


def child_ambient(paths, cores):
    """The ambient ways on `cores` cores: {way: seconds}, checked against the loop."""
    from concurrent.futures import ThreadPoolExecutor

    ref, sec = timed(lambda: [fit_ambient_one(p) for p in paths])
    out = {"loop": sec}
    with ThreadPoolExecutor(max_workers=cores) as pool:
        got, sec = timed(lambda: list(pool.map(fit_ambient_one, paths)))
    assert got == ref
    out["threads"] = sec
    try:
        import distributed  # noqa: F401
    except ImportError:
        return out
    got, sec = run_dask(paths, cores, fit_ambient_one)
    assert got == ref
    out["dask"] = sec
    return out


def child(folder, cores, kind="profile"):
    """Every way on `cores` cores: {way: seconds}, checked against the loop."""
    paths = sorted(os.path.join(folder, f) for f in os.listdir(folder))
    if kind == "ambient":
        return child_ambient(paths, cores)
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
    ap.add_argument("--kind", choices=["profile", "ambient"], default="profile")
    ap.add_argument("--records", type=int, default=200)
    ap.add_argument("--cores", default="1,2", help="comma-separated core counts")
    ap.add_argument("--child", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--folder", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        print(json.dumps(child(a.folder, a.child, a.kind)))
        return
    counts = [int(c) for c in a.cores.split(",")]
    with tempfile.TemporaryDirectory() as folder:
        (write_ambient if a.kind == "ambient" else write_records)(folder, a.records)
        runs = {}
        for c in counts:
            cmd = [sys.executable, __file__, "--child", str(c), "--folder", folder, "--kind", a.kind]
            out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
            runs[c] = json.loads(out.strip().splitlines()[-1])
    what = f"n = {N}, profile springs"
    if a.kind == "ambient":
        what = f"n = {AMBIENT_N}, ambient, channels {AMBIENT_OBSERVE}, defects auto:1"
    print(f"{a.records} records, {what}; {os.cpu_count()} cores on the machine")
    print(f"{'way':<10}{'cores':>6}{'seconds':>10}{'records/s':>11}{'speed-up':>10}")
    for way in runs[counts[0]]:
        for c in counts:
            sec = runs[c][way]
            one = runs[counts[0]][way]
            print(f"{way:<10}{c:>6}{sec:>10.2f}{a.records / sec:>11.1f}{one / sec:>10.2f}")


if __name__ == "__main__":
    main()
