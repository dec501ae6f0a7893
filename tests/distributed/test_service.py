"""How the long-running services (worker, router) stop: cosim/distributed/service.py."""

from __future__ import annotations

import os
import signal
import threading

import pytest

from cosim.distributed.service import stop_event_with_signals


@pytest.fixture
def saved_handlers():
    saved = {sig: signal.getsignal(sig) for sig in (signal.SIGTERM, signal.SIGINT)}
    yield
    for sig, handler in saved.items():
        signal.signal(sig, handler)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_in_the_main_thread_sets_the_event(saved_handlers, sig):
    stop = stop_event_with_signals()
    assert not stop.is_set()
    os.kill(os.getpid(), sig)
    assert stop.wait(10.0)


def test_the_callers_event_is_the_one_set(saved_handlers):
    mine = threading.Event()
    assert stop_event_with_signals(mine) is mine
    os.kill(os.getpid(), signal.SIGTERM)
    assert mine.wait(10.0)


def test_outside_the_main_thread_the_handlers_are_left_alone(saved_handlers):
    before = signal.getsignal(signal.SIGTERM)
    mine = threading.Event()
    got = []
    thread = threading.Thread(target=lambda: got.append(stop_event_with_signals(mine)))
    thread.start()
    thread.join()
    assert got == [mine] and not mine.is_set()
    assert signal.getsignal(signal.SIGTERM) is before
