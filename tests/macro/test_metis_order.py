"""The nested-dissection order of the projection's factorisations (METIS) and the signals that stop a run."""

import os
import signal
import subprocess
import threading
import time

import numpy as np
import pytest
import scipy.sparse as sp

from femcrowd.macro.projection.solvers import metis_order


@pytest.mark.slow
@pytest.mark.skipif(not hasattr(signal, "SIGTERM") or os.name != "posix", reason="POSIX signals")
def test_a_sigterm_while_metis_orders_reaches_the_handler_and_the_order_is_kept():
    """METIS traps SIGTERM while it runs and fails: a kill in that window used to end a run with METIS's error
    (driver/loop.py's handler never saw it). The ordering is returned and the handler gets the signal once.
    In the slow tier: METIS leaves its handler by a long jump, and a signal that lands inside malloc leaves the
    process waiting on malloc's lock for ever (seen once, 2026-11-28, in a default-tier run)."""
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signals are handled in the main thread")
    n = 400   # a grid graph of 160000 nodes: METIS takes a few tenths of a second
    graph = sp.diags([1.0, 1.0, 1.0, 1.0], [-1, 1, -n, n], shape=(n * n, n * n), format="csr")
    tic = time.perf_counter()
    expected = metis_order(graph)
    took = time.perf_counter() - tic
    received = []
    previous = signal.signal(signal.SIGTERM, lambda signum, frame: received.append(signum))
    try:
        # from another process: a thread of this one would wait for the GIL, which METIS holds
        kill = subprocess.Popen(["sh", "-c", f"sleep {took / 3:.3f}; kill -TERM {os.getpid()}"])
        ordering = metis_order(graph)
        kill.wait(timeout=60)
        for _ in range(100):   # the handler runs between two bytecodes of the main thread
            if received:
                break
            time.sleep(0.01)
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert received == [signal.SIGTERM]
    np.testing.assert_array_equal(ordering[1], expected[1])
