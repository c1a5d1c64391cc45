"""Ctrl-C during a fit: the fit stops and KeyboardInterrupt is raised."""

from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest

import springmass


@pytest.mark.skipif(not hasattr(signal, "SIGINT"), reason="needs SIGINT")
def test_ctrl_c_interrupts_a_long_fit(ctrl_c):
    # System 3 (n = 20) searched for three defects of any kind: about 10^5
    # position sets, many minutes of work; SIGINT after one second
    s3 = springmass.scene("S3")
    t = np.linspace(0.0, 200.0, 1001)
    x = springmass.simulate(t=t, noise="rel:0.01", seed=1, **s3.chain())
    timer = threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT))
    start = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            springmass.fit(t, x, n=s3.n, kinds="any", defects="3")
    finally:
        timer.cancel()
    # a generous bound: the interrupt lands within a poll (50 ms) and the
    # running value fits stop at their next iteration
    assert time.monotonic() - start < 60
    # the library is usable again afterwards: the request was cleared
    r = springmass.fit(t, x, n=s3.n, defects="2")
    assert [(e.kind, e.at) for e in r.defects] == [(d.kind, d.at) for d in s3.defects]
