"""Real-time pacing with a fake clock: sleeps, deadline misses, jitter statistics."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

import cosim.engine.pacing as pacing
from cosim.engine.pacing import RealtimePacer


class FakeClock:
    """perf_counter/sleep stand-ins: time moves by sleeps and by explicit work."""

    def __init__(self):
        self.now = 100.0
        self.sleeps = []

    def perf_counter(self):
        return self.now

    def sleep(self, seconds):
        self.sleeps.append(seconds)
        self.now += seconds + 0.001  # every wake-up is 1 ms late


def test_pacer_sleeps_to_the_scaled_deadlines_and_counts_misses(monkeypatch):
    clock = FakeClock()
    monkeypatch.setattr(pacing, "time", SimpleNamespace(perf_counter=clock.perf_counter,
                                                        sleep=clock.sleep))
    pacer = RealtimePacer(factor=2.0, tick=0.1)  # 0.05 s of wall time per tick
    pacer.begin(SimpleNamespace(t0=1.0))
    pacer.after_tick(0, 1.0, [], None)            # origin: wall 100.0
    clock.now += 0.01                             # tick 1 work: 10 ms
    pacer.after_tick(1, 1.1, [], None)            # deadline 100.05: sleeps 40 ms
    clock.now += 0.2                              # tick 2 work: 200 ms, past its deadline
    pacer.after_tick(2, 1.2, [], None)            # deadline 100.10: missed, no sleep
    assert clock.sleeps == pytest.approx([0.04])
    stats = pacer.stats()
    assert stats["factor"] == 2.0 and stats["ticks"] == 2 and stats["deadline_misses"] == 1
    # resume lateness: 1 ms after the first deadline, 151 ms after the second
    assert stats["lateness_max_ms"] == pytest.approx(151.0)
    assert stats["lateness_mean_ms"] == pytest.approx(76.0)


def test_pacer_rejects_a_non_positive_factor():
    with pytest.raises(ValueError, match="must be > 0"):
        RealtimePacer(factor=0.0, tick=0.01)
