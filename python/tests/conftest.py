"""Shared fixtures: the command-line binary, small simulated records."""

from __future__ import annotations

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

import springmass

REPO = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def cli() -> pathlib.Path:
    """The `springmass` command-line binary of this checkout.

    `SPRINGMASS_CLI` names it (`.ci/run` sets it to the binary `cargo test`
    built); otherwise it is built with cargo. A missing binary fails the
    tests that need it: they compare the package with the command line.
    """
    env = os.environ.get("SPRINGMASS_CLI")
    if env:
        path = pathlib.Path(env)
        if not path.is_file():
            pytest.fail(f"SPRINGMASS_CLI={env} is not a file")
        return path
    try:
        out = subprocess.run(
            ["cargo", "build", "--quiet", "--bin", "springmass", "--message-format=json"],
            cwd=REPO,
            check=True,
            capture_output=True,
            text=True,
        )
    except (OSError, subprocess.CalledProcessError) as e:
        pytest.fail(f"cannot build the springmass binary with cargo (set SPRINGMASS_CLI): {e}")
    for line in out.stdout.splitlines():
        msg = json.loads(line)
        if msg.get("reason") == "compiler-artifact" and msg.get("executable"):
            if msg["target"]["name"] == "springmass":
                return pathlib.Path(msg["executable"])
    pytest.fail("cargo built no springmass executable")


def run_cli(cli: pathlib.Path, *args: str) -> str:
    """Run the CLI; its stdout (a failure shows its stderr)."""
    out = subprocess.run([str(cli), *map(str, args)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return out.stdout


def write_csv(path: pathlib.Path, t: np.ndarray, x: np.ndarray) -> None:
    """A `t,x1` CSV with every float written exactly (shortest round trip)."""
    lines = ["t,x1"] + [f"{a!r},{b!r}" for a, b in zip(t.tolist(), x.tolist())]
    path.write_text("\n".join(lines) + "\n")


@pytest.fixture(scope="session")
def s1_record():
    """Table 1's System 1 (n = 5, masses 3 at 2 and 0.5 at 4), 0.1% noise."""
    s1 = springmass.scene("S1")
    t = np.arange(0, 150, 0.25)
    x = springmass.simulate(t=t, noise="rel:1e-3", seed=11, **s1.chain())
    return t, x


@pytest.fixture
def ctrl_c():
    """Python's own Ctrl-C handler for the length of a test.

    A process started in the background by a shell without job control
    inherits SIGINT ignored, and Python then installs no handler: a SIGINT
    sent to it does nothing. The interrupt tests install the handler an
    interactive session has (and restore the one they found).
    """
    import signal

    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)
