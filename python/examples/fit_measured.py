"""Fit defects to a measured record of mass 1 and plot data against model.

    python python/examples/fit_measured.py x1.csv --n 20
    python python/examples/fit_measured.py x1.csv --n 20 --column x1 --defects auto:3 --plot fit.png
    python python/examples/fit_measured.py --n 20        # no CSV: a simulated System 3 record

The CSV has a time column ``t`` and one or more value columns (the
displacement of mass 1 in the paper's units: unit masses and springs, the
impulse on mass 1 at t = 0). Prints the answer with standard errors; with
matplotlib installed, draws the data, the fitted model and the residual
(saved with ``--plot FILE``, shown otherwise).
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import tempfile

import numpy as np

import springmass


def demo_csv(directory: pathlib.Path) -> pathlib.Path:
    """A simulated record of Table 1's System 3 at 1% noise, written as CSV."""
    s3 = springmass.scene("S3")
    t = np.linspace(0.0, 200.0, 1001)
    x = springmass.simulate(t=t, noise="rel:0.01", seed=1, **s3.chain())
    path = directory / "system3-1pct.csv"
    np.savetxt(path, np.column_stack([t, x]), delimiter=",", header="t,x1", comments="", fmt="%.17g")
    print(f"no CSV given: simulated System 3 (defects {', '.join(map(str, s3.defects))}) at 1% noise -> {path}")
    return path


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("csv", nargs="?", type=pathlib.Path, help="t,<column>,... (default: a simulated record)")
    p.add_argument("--n", type=int, required=True, help="number of masses of the chain")
    p.add_argument("--column", help="value column to fit (default: the first)")
    p.add_argument("--d", type=float, default=0.1, help="damping per mass (default 0.1)")
    p.add_argument("--defects", default="auto:3", help="auto, auto:KMAX or a number (default auto:3)")
    p.add_argument("--kinds", help="mass, spring, damper, ground or any (default any)")
    p.add_argument("--noise", default="auto", help="auto or the samples' standard deviation")
    p.add_argument("--plot", type=pathlib.Path, help="save the figure here (PNG, PDF, SVG)")
    a = p.parse_args(argv)

    with tempfile.TemporaryDirectory() as tmp:
        path = a.csv if a.csv is not None else demo_csv(pathlib.Path(tmp))
        t, columns = springmass.read_csv(path)
        name = a.column or next(iter(columns))
        if name not in columns:
            p.error(f"no column {name!r} in {path}: {', '.join(columns)}")
        noise = a.noise if a.noise == "auto" else float(a.noise)
        defects = int(a.defects) if a.defects.isdigit() else a.defects
        r = springmass.fit(t, columns[name], n=a.n, d=a.d, defects=defects, kinds=a.kinds, noise=noise)
    print(r)
    for e in r.defects:
        print(f"{e.kind:>6} at {e.at:>3}: {e.value:.4f} +- {e.se:.4f}")

    try:
        import matplotlib

        if a.plot is not None:
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("(matplotlib is not installed: no plot)")
        return 0
    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(9, 6), gridspec_kw={"height_ratios": [3, 1]})
    top.plot(r.t, r.observed, ".", ms=2, label=f"data ({name})")
    top.plot(r.t, r.predicted, "-", lw=1, label=f"model, k = {r.k}")
    top.set_ylabel("x_1")
    top.set_title(", ".join(f"{e.kind} {e.value:.3g} at {e.at}" for e in r.defects) or "no defect")
    top.legend()
    bottom.plot(r.t, r.residual, "-", lw=0.5)
    bottom.axhline(0, color="k", lw=0.5)
    bottom.set_xlabel("t")
    bottom.set_ylabel(f"residual (sigma {r.sigma:.2g})")
    fig.tight_layout()
    if a.plot is not None:
        fig.savefig(a.plot)
        print(f"plot: {a.plot}")
    else:
        plt.show()
    return 0


if __name__ == "__main__":
    sys.exit(main())
