#!/usr/bin/env python3
"""What a user would write instead of `springmass fit`, timed beside it.

The peer fits Table 1 System 3 (n = 20, masses 5 at 8 and 2 at 15, unit
springs, grounded damping d = 0.1, fixed ends, an impulse on mass 1) from
the record of mass 1, as a scipy user would:

* **least_squares over the position sets**: for each of the 190 pairs of
  positions, `scipy.optimize.least_squares` over the two masses (bounds
  [0.1, 100], start 2) on the time-domain residual; the best pair wins;
* **differential_evolution** over the two positions (integers) and the two
  masses, on the same residual, seeded (population 10 per parameter, at
  most 100 generations: about 4000 evaluations).

The model is the chain's modal solution (numpy's eigen-decomposition of the
state matrix), exact for this linear chain; the script checks it against
the record at the truth before timing anything.

Both records are written by `springmass simulate` in this run (the 1%
record: `--noise rel:0.01 --seed 1`; the exact one: no noise), and the
command line fits them in the same run (`springmass fit --data FILE --n 20`,
whole process, wall time). The report prints every time and the ratios.

    python3 benches/scipy_peer.py --springmass target/release/springmass

Needs numpy and scipy (not needed by the Rust build or tests).
"""

import argparse
import itertools
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.optimize import differential_evolution, least_squares

N = 20
TRUTH = ((8, 5.0), (15, 2.0))
D = 0.1
BOUNDS = (0.1, 100.0)


def simulate_x1(masses, t, d=D, k=1.0, gamma=1.0):
    """x_1(t) of the fixed-fixed chain after an impulse gamma on mass 1."""
    n = len(masses)
    kmat = (np.diag(np.full(n, 2.0 * k)) - np.diag(np.full(n - 1, k), 1)
            - np.diag(np.full(n - 1, k), -1))
    minv = 1.0 / np.asarray(masses)
    a = np.zeros((2 * n, 2 * n))
    a[:n, n:] = np.eye(n)
    a[n:, :n] = -kmat * minv[:, None]
    a[n:, n:] = -d * np.diag(minv)
    z0 = np.zeros(2 * n)
    z0[n] = gamma * minv[0]
    lam, vec = np.linalg.eig(a)
    coef = np.linalg.solve(vec, z0)
    return np.real((vec[0, :] * coef) @ np.exp(np.outer(lam, t)))


def chain_masses(pairs):
    m = np.ones(N)
    for at, value in pairs:
        m[at - 1] = value
    return m


def read_csv(path):
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    return data[:, 0], data[:, 1]


def lsq_enumeration(t, y, sets=None):
    """Every pair of positions (the first `sets` only, when given), its two
    masses by least_squares."""
    best = None
    pairs = list(itertools.combinations(range(1, N + 1), 2))
    for j1, j2 in pairs[:sets]:
        def resid(v, j1=j1, j2=j2):
            return simulate_x1(chain_masses(((j1, v[0]), (j2, v[1]))), t) - y
        r = least_squares(resid, x0=[2.0, 2.0], bounds=BOUNDS)
        cost = 2.0 * r.cost
        if best is None or cost < best[0]:
            best = (cost, (j1, j2), tuple(r.x))
    return best


def de_fit(t, y, seed):
    """Positions and masses by differential evolution (positions integer)."""
    def cost(v):
        j1, j2 = int(round(v[0])), int(round(v[1]))
        if j1 == j2:
            return 1e6
        r = simulate_x1(chain_masses(((j1, v[2]), (j2, v[3]))), t) - y
        return float(r @ r)
    res = differential_evolution(
        cost,
        bounds=[(1, N), (1, N), BOUNDS, BOUNDS],
        integrality=[True, True, False, False],
        seed=seed,
        popsize=10,
        maxiter=100,
        polish=False,
    )
    j = sorted((int(round(res.x[0])), int(round(res.x[1]))))
    return res.fun, tuple(j), res.nfev


def timed_cli(exe, args):
    t0 = time.perf_counter()
    out = subprocess.run([exe, *args], check=True, capture_output=True, text=True)
    return time.perf_counter() - t0, out.stdout


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--springmass", default=os.path.join(
        os.environ.get("CARGO_TARGET_DIR", "target"), "release", "springmass"))
    ap.add_argument("--de-seeds", type=int, default=2, help="differential evolution runs")
    ap.add_argument("--sets", type=int, default=None,
                    help="time the first SETS position sets only and scale the time to all 190")
    ap.add_argument("--skip-lsq", action="store_true",
                    help="leave out the least_squares enumeration (about a minute)")
    a = ap.parse_args()
    exe = a.springmass
    with tempfile.TemporaryDirectory() as tmp:
        noisy, exact = os.path.join(tmp, "s3.csv"), os.path.join(tmp, "s3_exact.csv")
        common = ["simulate", "--n", str(N), "--d", str(D), "--t-end", "300", "--dt", "0.05"]
        for at, m in TRUTH:
            common += ["--defect", f"mass:{at}:{m}"]
        subprocess.run([exe, *common, "--noise", "rel:0.01", "--seed", "1", "--out", noisy],
                       check=True, capture_output=True)
        subprocess.run([exe, *common, "--out", exact], check=True, capture_output=True)
        t, y_exact = read_csv(exact)
        check = np.max(np.abs(simulate_x1(chain_masses(TRUTH), t) - y_exact))
        print(f"peer model against `springmass simulate` at the truth: max |diff| {check:.2e}")
        if check > 1e-6 * np.max(np.abs(y_exact)):
            sys.exit("the peer's model does not match the record; nothing timed")
        _, y_noisy = read_csv(noisy)

        rows = []
        cli_noisy, out = timed_cli(exe, ["fit", "--data", noisy, "--n", str(N)])
        print(f"springmass fit (1% record, defaults): {cli_noisy:.3f} s wall, whole process")
        print("  " + "\n  ".join(out.strip().splitlines()[:2]))
        cli_given, _ = timed_cli(exe, ["fit", "--data", noisy, "--n", str(N), "--defects", "2"])
        print(f"springmass fit (1% record, --defects 2): {cli_given:.3f} s")
        cli_exact, out = timed_cli(exe, ["fit", "--data", exact, "--n", str(N)])
        print(f"springmass fit (exact record, defaults): {cli_exact:.3f} s")
        print("  " + "\n  ".join(out.strip().splitlines()[:2]))

        if not a.skip_lsq:
            t0 = time.perf_counter()
            cost, pos, masses = lsq_enumeration(t, y_noisy, a.sets)
            t_lsq = time.perf_counter() - t0
            done = min(a.sets or 190, 190)
            if done < 190:
                print(f"scipy least_squares over the first {done} position sets: {t_lsq:.2f} s, "
                      f"scaled to 190")
                t_lsq *= 190 / done
            else:
                print(f"scipy least_squares over 190 position sets (1% record): {t_lsq:.2f} s, "
                      f"best {pos} masses {masses[0]:.3f}, {masses[1]:.3f}")
            rows.append(("least_squares enumeration / springmass defaults (1%)", t_lsq / cli_noisy))
            rows.append(("least_squares enumeration / springmass k given (1%)", t_lsq / cli_given))

        hits, total = 0, 0.0
        for seed in range(a.de_seeds):
            t0 = time.perf_counter()
            fun, pos, nfev = de_fit(t, y_exact, seed)
            dt = time.perf_counter() - t0
            total += dt
            hit = pos == tuple(p for p, _ in TRUTH)
            hits += hit
            print(f"scipy differential_evolution (exact record, seed {seed}): {dt:.2f} s, "
                  f"{nfev} evaluations, positions {pos} ({'right' if hit else 'WRONG'})")
        t_de = total / max(a.de_seeds, 1)
        rows.append((f"differential_evolution / springmass defaults (exact; {hits} of "
                     f"{a.de_seeds} right)", t_de / cli_exact))
        print("\nratios (same run, same machine; larger = springmass faster):")
        for name, r in rows:
            print(f"  {name}: {r:.0f}x")


if __name__ == "__main__":
    main()
