"""Seeded fuzz of the Python API (issue 32): 10 000 calls by default.

Every public function is called from a valid, cheap base call with one or two
arguments replaced, and every CSV reader call gets a mutated file. Each case
is classified before the call:

* **invalid by construction** (a NaN, an infinity, a string or a list where a
  number goes, a negative or fractional count, an empty, 2-D, text or
  datetime array, arrays of different lengths, an unknown name, a CSV cell
  that is not a number, a row with an extra field, a repeated column name):
  the call must raise ``ValueError``, ``TypeError`` or ``OSError`` naming the
  problem. Returning is a *silent accept*; any other exception (a panic, an
  ``IndexError``, a ``SystemError``, ...) is a defect.
* **plausible** (another valid value, a boundary): the call returns, or raises
  one of the three above (or ``springmass.NumericalError``).

No call may take more than ``HANG_SECONDS`` (each runs in a worker thread;
the first that overruns ends the run as a failure naming it). Scale with ``SPRINGMASS_PY_FUZZ_CASES`` and pick the stream with
``SPRINGMASS_PY_FUZZ_SEED``; a failure lists each failing case (function,
arguments) so that it can be replayed by hand.
"""

from __future__ import annotations

import os
import pathlib
import random
import threading
import time
from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np

import springmass

CASES = int(os.environ.get("SPRINGMASS_PY_FUZZ_CASES", "10000"))
SEED = int(os.environ.get("SPRINGMASS_PY_FUZZ_SEED", "17"))
HANG_SECONDS = 60.0
REFUSALS = (ValueError, TypeError, OSError)
ACCEPTED = REFUSALS + (springmass.NumericalError,)

T = np.arange(40) * 0.5
# The uniform chain's record: every profile kind fits it in tens of
# milliseconds. (On a mass defect's record a spring profile, which cannot
# fit it, takes about 2 s of the debug build per call: 10 000 cases took
# 110 s, nearly all of it in those calls.)
X = springmass.simulate(3, t=T)
S = [0.5, 1.0, 2.0]
VALUES = springmass.response(S, n=3, defects=["mass:2:2"])


def _bases() -> Dict[str, Tuple[Callable[..., Any], Tuple[Any, ...], Dict[str, Any]]]:
    """The valid base call of each function: (function, positional, keywords)."""
    sm = springmass
    return {
        "fit": (sm.fit, (T, X), dict(n=3, defects=1, max_evals=500)),
        # a fixed penalty: one stage per start instead of the continuation's
        # eleven (the arguments are checked before either runs); a mutated
        # chain that cannot fit the record restarts several times
        "fit_profile": (sm.fit_profile, (T, X), dict(n=3, penalty=1e-3)),
        "simulate": (sm.simulate, (3,), dict(t=T)),
        "response": (sm.response, (S,), dict(n=3)),
        "controls": (sm.controls, (3,), dict(t=T)),
        "laplace": (sm.laplace, (T, X, S), {}),
        "locate": (sm.locate, (), dict(n=3, s=S, values=VALUES)),
        "spectral": (sm.spectral, ([1.0], [0.5]), {}),
        "scene": (sm.scene, ("S1",), {}),
    }


# What each argument is: decides the mutations that apply.
COUNTS = {"n", "degree", "observe", "max_evals"}
SEEDS = {"seed"}
POSITIVE = {"k", "mass", "m", "change"}
NONNEG = {"d", "noise_sigma"}
REALS = {"at", "penalty", "gamma"}  # gamma: any sign (the hit's direction), 0 gives no motion
ARRAYS = {"t", "x", "s", "omega", "residue", "values", "err"}
NAMES = {
    "kinds": "mass",
    "misfit": "time",
    "method": "enumerate",
    "criterion": "bic",
    "left": "fixed",
    "right": "fixed",
    "observe_kind": "displacement",
    "tail": "envelope",
    "profile": "masses",
}
POSITIONAL = {
    "fit": ["t", "x"],
    "fit_profile": ["t", "x"],
    "simulate": ["n"],
    "response": ["s"],
    "controls": ["n"],
    "laplace": ["t", "x", "s"],
    "spectral": ["omega", "residue"],
    "scene": ["name"],
}
# Keyword arguments each function takes (beyond its base call) that the fuzz varies.
EXTRA = {
    "fit": ["d", "k", "mass", "gamma", "seed", "kinds", "criterion", "left", "right", "observe", "observe_kind", "noise", "misfit", "method", "max_evals"],
    "fit_profile": ["d", "k", "mass", "gamma", "change", "penalty", "left", "right", "observe", "observe_kind", "profile", "noise"],
    "simulate": ["d", "k", "mass", "gamma", "seed", "left", "right", "observe_kind"],
    "response": ["n", "d", "k", "mass", "gamma", "left", "right", "observe", "observe_kind"],
    "controls": ["d", "k", "mass", "gamma"],
    "laplace": ["degree", "noise_sigma", "tail"],
    "locate": ["n", "d", "k", "mass", "gamma", "m", "at", "noise_sigma", "method"],
    "spectral": ["k", "left", "right"],
    "scene": [],
}


def _bad_value(rng: random.Random, name: str, base: Any, evaluation_grid: bool = False) -> Any:
    """A value of `name` that no call may accept (`evaluation_grid`: `t` holds
    the times to evaluate at, not a record's, as in `controls`)."""
    if name in COUNTS:
        # `fit` takes a list of observed masses (several sensors): a list
        # is bad there only with a mass outside the chain
        listed = [3] if name != "observe" else [0]
        return rng.choice([-1, -(10**6), 2.5, float("nan"), "3", listed, None if name != "observe" else -2, 1j])
    if name in SEEDS:
        return rng.choice([-1, 2.5, "x", float("nan"), [1]])
    if name in POSITIVE:
        return rng.choice([float("nan"), float("inf"), -float("inf"), -1.0, 0.0 if name != "change" else -2.0, "1", [1.0], 1j])
    if name in NONNEG:
        return rng.choice([float("nan"), float("inf"), -1.0, -1e-300, "0.1", [0.1], 1j])
    if name in REALS:
        return rng.choice([float("nan"), float("inf"), "x", [1.0], 1j])
    if name in ARRAYS:
        b = np.asarray(base)
        choices: List[Any] = [
            np.array([], dtype=float),
            np.vstack([b, b]),
            np.array(["a"] * max(len(b), 1)),
            np.where(np.arange(len(b)) == len(b) // 2, np.nan, b) if len(b) else np.array([np.nan]),
            np.where(np.arange(len(b)) == 0, np.inf, b) if len(b) else np.array([np.inf]),
            np.datetime64("2026-01-01") + np.arange(max(len(b), 1)).astype("timedelta64[s]"),
            "1,2,3",
            None,
            object(),
        ]
        if name == "s" or (name == "t" and evaluation_grid):
            # evaluated as numpy evaluates: any shape, empty included
            choices = [c for c in choices if not (isinstance(c, np.ndarray) and c.dtype == float and c.size == 0)]
            choices = [c for c in choices if not (isinstance(c, np.ndarray) and c.ndim == 2)]
        elif len(b) > 1 and name in ("x", "values", "residue"):
            choices.append(b[:-1])  # a length its partner array (t, s, omega) does not have
        return rng.choice(choices)
    if name == "defects":
        return rng.choice([-1, 2.5, float("nan"), "bogus", "auto:-1", "auto:x", [1], None])
    if name in NAMES or name in ("name", "noise"):
        return rng.choice(["bogus", "", "MASS ,,", "\u00e9\u00e9", 3.5 if name != "noise" else "x1", ["zz"]])
    raise AssertionError(f"no bad value for {name}")


def _plausible_value(rng: random.Random, name: str, base: Any) -> Any:
    """Another value of `name` that a call may accept or refuse with a message."""
    if name in COUNTS:
        if name == "n":
            return rng.choice([1, 2, 3, 4, 10**9, 2 * 10**9])
        if name == "max_evals":
            return rng.choice([1, 10, 200, 10**12])
        return rng.choice([1, 2, 3, 4, 31, 10**6])
    if name in SEEDS:
        return rng.choice([0, 1, 2**63 - 1, 2**64 - 1, 2**64])
    if name in POSITIVE or name in NONNEG or name in REALS:
        return rng.choice([1e-300, 5e-324, 1e-3, 0.5, 1.0, 3.0, 1e6, 1e300, 0.0])
    if name in ARRAYS:
        b = np.asarray(base, dtype=complex if np.iscomplexobj(base) else float)
        choices = [b * 1e-200, b * 1e200, b[::-1], b + 0.0, -b, b[:2] if len(b) > 2 else b]
        return rng.choice(choices)
    if name in NAMES:
        return rng.choice(
            {
                "kinds": ["mass", "spring", "damper", "any", "mass,spring"],
                "misfit": ["time", "laplace", "bromwich"],
                "method": ["enumerate", "greedy", "relax", "ga", "nelder-mead", "pso", "grid", "bisection"],
                "criterion": ["bic", "aic", "aicc"],
                "left": ["fixed", "free"],
                "right": ["fixed", "free"],
                "observe_kind": ["displacement", "velocity", "acceleration"],
                "tail": ["envelope", "none", "exponential"],
                "profile": ["masses", "springs", "dampers"],
            }[name]
        )
    if name == "noise":
        return rng.choice(["auto", 0.0, 1e-3, 0.5])
    if name == "defects":
        return rng.choice([0, 1, 2, 3, 4, "auto", "auto:2", 10**6])
    if name == "name":
        return rng.choice(["S1", "s2", "P4", "C3a", "k0"])
    raise AssertionError(f"no plausible value for {name}")


CSV_GOOD = "t,x1\n" + "".join(f"{tt:.6g},{xx:.9g}\n" for tt, xx in zip(T, X))


def _csv_case(rng: random.Random) -> Tuple[bytes, bool]:
    """A mutated CSV file and whether it is invalid by construction."""
    text, invalid = _csv_text(rng)
    return (text if isinstance(text, bytes) else text.encode()), invalid


def _csv_text(rng: random.Random) -> Tuple[Any, bool]:
    """A mutated CSV text (or bytes) and whether it is invalid by construction."""
    lines = CSV_GOOD.splitlines()
    row = rng.randrange(1, len(lines))
    kind = rng.randrange(10)
    if kind == 0:  # a cell that is not a number
        t, x = lines[row].split(",")
        lines[row] = f"{t},{rng.choice(['abc', '1.2.3', '--1', '0x1g', '#N/A', '1e', '+'])}"
        return "\n".join(lines) + "\n", True
    if kind == 1:  # an extra field
        lines[row] += "," + rng.choice(["5", "x", "1,2"])  # (a trailing empty field is allowed)
        return "\n".join(lines) + "\n", True
    if kind == 2:  # a repeated column name
        lines[0] = rng.choice(["t,t", "x1,x1"])
        return "\n".join(lines) + "\n", True
    if kind == 3:  # no header at all
        return "\n".join(lines[1:]) + "\n", True
    if kind == 4:  # a missing field
        lines[row] = lines[row].split(",")[0]
        return "\n".join(lines) + "\n", True
    if kind == 5:  # random bytes flipped anywhere: may or may not stay valid
        b = bytearray(CSV_GOOD.encode())
        for _ in range(rng.randint(1, 4)):
            b[rng.randrange(len(b))] = rng.randrange(256)
        return bytes(b), False
    if kind == 6:  # extreme but numbers
        t, x = lines[row].split(",")
        lines[row] = f"{t},{rng.choice(['1e308', '-1e308', '5e-324', '0', '1e-310'])}"
        return "\n".join(lines) + "\n", False
    if kind == 7:  # rows dropped or repeated
        i = rng.randrange(1, len(lines))
        lines.insert(i, lines[i]) if rng.random() < 0.5 else lines.pop(i)
        return "\n".join(lines) + "\n", False
    if kind == 8:  # other separators, line ends, units, BOM
        text = "\n".join(lines) + "\n"
        return rng.choice(
            [text.replace("\n", "\r\n"), "\ufeff" + text, text.replace(",", ";"), text.replace("t,x1", "t [s],x1 [m]"), text.replace(",", "\t")]
        ), False
    return rng.choice(["", "\n", "t,x1\n", ",\n", "\x00\x01\x02", "t,x1\n" + "1," * 5000 + "\n"]), True


def _one_case(rng: random.Random, tmp: pathlib.Path, i: int) -> Tuple[str, Callable[[], Any], bool]:
    """A case: its description, the call, and whether it is invalid by construction."""
    if rng.random() < 0.15:
        text, invalid = _csv_case(rng)
        path = tmp / f"case{i % 8}.csv"
        path.write_bytes(text)
        return f"read_csv({text[:60]!r}...)", lambda: springmass.read_csv(path), invalid
    bases = _bases()
    name = rng.choice(sorted(bases))
    fn, args, kwargs = bases[name]
    args = list(args)
    kwargs = dict(kwargs)
    names = POSITIONAL.get(name, []) + [k for k in kwargs] + EXTRA[name]
    invalid = False
    changed = []
    names = sorted(set(names))
    for arg in rng.sample(names, min(len(names), rng.choice([1, 1, 2]))):
        base = bases[name]
        current = base[1][POSITIONAL[name].index(arg)] if arg in POSITIONAL.get(name, []) else base[2].get(arg, 1.0)
        if rng.random() < 0.7:
            value = _bad_value(rng, arg, current if arg in ARRAYS else 1.0, name == "controls")
            invalid = True
        else:
            value = _plausible_value(rng, arg, current if arg in ARRAYS else 1.0)
        if arg in POSITIONAL.get(name, []):
            args[POSITIONAL[name].index(arg)] = value
        else:
            kwargs[arg] = value
        changed.append(f"{arg}={_short(value)}")
    desc = f"{name}({', '.join(changed)})"
    return desc, lambda: fn(*args, **kwargs), invalid


def _short(v: Any) -> str:
    r = repr(v).replace("\n", " ")
    return r if len(r) <= 60 else r[:57] + "..."


def _timed(call: Callable[[], Any]) -> Tuple[Optional[BaseException], float, bool]:
    """Run a call in a worker thread: (exception or None, seconds, still running)."""
    box: List[Optional[BaseException]] = [None]

    def run() -> None:
        try:
            call()
        except BaseException as e:  # noqa: BLE001 - a panic is a BaseException
            box[0] = e

    start = time.monotonic()
    worker = threading.Thread(target=run, daemon=True)
    worker.start()
    worker.join(HANG_SECONDS)
    return box[0], time.monotonic() - start, worker.is_alive()


def test_api_fuzz(tmp_path: pathlib.Path) -> None:
    rng = random.Random(SEED)
    failures: List[str] = []
    refused = accepted = 0
    slowest = (0.0, "")
    for i in range(CASES):
        desc, call, invalid = _one_case(rng, tmp_path, i)
        outcome, took, hung = _timed(call)
        slowest = max(slowest, (took, desc))
        if hung:
            # the call still runs: later cases would share its process
            failures.append(f"case {i}: {desc}: no answer after {HANG_SECONDS:.0f} s (a hang)")
            break
        if outcome is None:
            accepted += 1
            if invalid:
                failures.append(f"case {i}: {desc}: silently accepted")
        elif isinstance(outcome, REFUSALS if invalid else ACCEPTED):
            refused += 1
            if not str(outcome).strip():
                failures.append(f"case {i}: {desc}: {type(outcome).__name__} without a message")
        else:
            failures.append(f"case {i}: {desc}: {type(outcome).__name__}: {str(outcome)[:200]}")
    print(f"{CASES} cases: {accepted} returned, {refused} refused; slowest {slowest[0]:.2f} s: {slowest[1]}")
    assert not failures, f"{len(failures)} of {CASES} cases failed:\n" + "\n".join(failures[:60])
    assert refused > CASES // 4 and accepted > CASES // 50, "the case mix lost its invalid or its valid calls"
