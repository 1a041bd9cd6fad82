"""Long calls release the GIL and stop on Ctrl-C; the solid stays usable afterwards."""

import _thread
import signal
import threading
import time

import numpy as np
import pytest

import solidsynth


@pytest.fixture(scope="module")
def slow(fixture_path):
    # Small groups: many cancellation points, and a box that takes seconds on the CPU backend.
    return solidsynth.Solid(
        fixture_path("cells32.png"), seed=2, periodic=True, balance_rounds=0, backend="cpu",
        max_group=16,
    )


@pytest.fixture
def ctrl_c_raises():
    # Python leaves SIGINT alone when it starts with the signal ignored (a background job of a
    # shell without job control, as some CI runners start their steps): interrupt_main then does
    # nothing. The test is about what a request does on Ctrl-C, so give SIGINT its usual handler.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def test_ctrl_c_cancels_a_request(slow, ctrl_c_raises):
    before = slow.region((0, 0, 0), (8, 8, 8))
    # What Ctrl-C does: the signal flag the interpreter checks (here from another thread).
    timer = threading.Timer(0.05, _thread.interrupt_main)
    start = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            # 320^3 in 16^3 groups on the CPU backend: tens of seconds even on 16 cores
            # (each small group recomputes its padding), so only a cancelled request ends soon.
            slow.region((0, 0, 0), (320, 320, 320))
    finally:
        timer.join()
    assert time.monotonic() - start < 5
    # A fresh token: the next request runs, and gives the same voxels.
    np.testing.assert_array_equal(slow.region((0, 0, 0), (8, 8, 8)), before)


def test_other_threads_run_during_a_request(slow):
    ticks = 0
    done = threading.Event()

    def work():
        slow.region((0, 0, 0), (64, 64, 64))
        done.set()

    worker = threading.Thread(target=work)
    worker.start()
    while not done.is_set():
        ticks += 1
        time.sleep(0.001)
    worker.join()
    # With the GIL held for the whole request this thread would not have run meanwhile.
    assert ticks > 10


def test_ctrl_c_reaches_a_request_waiting_behind_another(fixture_path, ctrl_c_raises):
    solid = solidsynth.Solid(
        fixture_path("cells32.png"), seed=2, periodic=True, balance_rounds=0, backend="cpu",
        max_group=8,
    )
    # Another thread's request holds the solid for seconds (64^3 in groups of 8).
    other = threading.Thread(target=lambda: solid.region((0, 0, 0), (64, 64, 64)))
    other.start()
    time.sleep(0.2)
    timer = threading.Timer(0.1, _thread.interrupt_main)
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            solid.region((100, 0, 0), (108, 8, 8))
        # Raised while the other request still runs, not when it ends.
        assert other.is_alive()
    finally:
        timer.join()
        other.join()
    assert solid.region((0, 0, 0), (4, 4, 4)).shape == (4, 4, 4, 3)
