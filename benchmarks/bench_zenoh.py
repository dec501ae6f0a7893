"""Benchmark of the Zenoh transport against a raw Zenoh round trip, in one run.

(a) raw: put/subscribe round trip of a 100-byte payload between this process
    and an echo process (peer mode, direct TCP on 127.0.0.1);
(b) tick: one lockstep exchange (step request, outputs reply) with one trivial
    component hosted by `ZenohComponents`.
Both are set up at once and measured in alternating blocks, so that the load
of other processes on the machine weighs on both alike.
Prints median and p99 of both and the ratio of the medians (target <= 1.25),
first with the processes where the OS puts them, then again with every process
of both pairs on one CPU, as `cosim run` puts a run's chain from tick 0 on
(`--lockstep-cpu auto`, cosim.engine.one_cpu): on one CPU the raw round trip
is about a quarter, and what our stack adds to it (codec, the component's
Python, a process with more code and data to bring back into the caches) weighs
the more.

Every process runs Zenoh's runtime on one thread, as a run's processes do
(cosim.transport.zenoh.runtime). The same four measurements are then made again
in a child process with Zenoh's default pools (`ZENOH_RUNTIME='()'`, rows (p)),
and the speed-up of one thread over them is printed.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_zenoh.py [--ticks 5000] [--no-pools]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

import numpy as np
import zenoh

from cosim.transport.inproc import PythonComponentLaunch
from cosim.transport.zenoh import ZenohComponents, config, runtime

PING, PONG = "bench/raw/ping", "bench/raw/pong"


def echo(endpoint: str) -> None:
    """Echo process: send every ping back as a pong, until an empty ping."""
    with zenoh.open(config.client_peer_config(endpoint)) as session:
        pings = session.declare_subscriber(PING)
        pong = session.declare_publisher(PONG)
        while True:
            payload = pings.recv().payload.to_bytes()
            pong.put(payload)
            if not payload:
                return


class RawPair:
    """This process and an echo process, joined peer to peer on 127.0.0.1.

    Args:
        host: the address this process listens on (the echo process connects to it).
        wrap: a command prefix for the echo process (e.g. `ip netns exec NS`: another namespace).
    """

    def __init__(self, host: str = "127.0.0.1", wrap: tuple[str, ...] = ()) -> None:
        self.host, self.wrap = host, tuple(wrap)

    def __enter__(self) -> "RawPair":
        endpoint = config.free_tcp_endpoint(self.host)
        with runtime.first_session():  # the runtime of a run's processes, as a floor should
            self.session = zenoh.open(config.master_config(endpoint))
        self.pongs = self.session.declare_subscriber(PONG)
        self.ping = self.session.declare_publisher(PING)
        env = runtime.child_environment({**os.environ, "PYTHONPATH": _pythonpath()})
        self.child = subprocess.Popen([*self.wrap, sys.executable, __file__, "--echo", endpoint],
                                      env=env)
        self.payload = bytes(range(100))
        while True:  # handshake: retry until the echo answers
            self.ping.put(self.payload)
            time.sleep(0.05)
            if self.pongs.try_recv() is not None:
                break
        while self.pongs.try_recv() is not None:
            pass
        return self

    def measure(self, count: int, busy_s: float = 0.0) -> list[float]:
        """Seconds of `count` round trips, one by one.

        Args:
            count: round trips.
            busy_s: this process computes (a busy loop) for that long between round trips,
                so both processes come to each round trip after an idle or busy spell as
                in a lockstep loop (0: back to back).
        """
        times, clock = [], time.perf_counter
        ping, pongs, payload = self.ping, self.pongs, self.payload
        for _ in range(count):
            start = clock()
            ping.put(payload)
            pongs.recv().payload.to_bytes()
            end = clock()
            times.append(end - start)
            while clock() - end < busy_s:
                pass
        return times

    def __exit__(self, *exc_info: object) -> None:
        self.ping.put(b"")
        try:
            self.child.wait(timeout=10)
        finally:
            if self.child.poll() is None:
                self.child.kill()
                self.child.wait()
            self.session.close()


class TickLoop:
    """One trivial component over the transport, stepped tick after tick."""

    def __init__(self, hosted: ZenohComponents) -> None:
        self.component = hosted.components["echo"]
        self.component.start(0.0, {"u": 0.0})
        self.tick, self.value = 0, 0.0

    def measure(self, count: int) -> list[float]:
        """Seconds of `count` ticks, one by one; checks the echo chain stays exact."""
        times, clock, step = [], time.perf_counter, self.component.step
        for _ in range(count):
            self.tick += 1
            start = clock()
            outputs = step(self.tick, self.tick * 0.01, {"u": self.value})
            times.append(clock() - start)
            self.value = outputs["y"]
        if self.value != float(self.tick):
            raise RuntimeError(f"echo chain at {self.value}, expected {self.tick}")
        return times


def measure_interleaved(count: int, blocks: int,
                        one_cpu: bool = False) -> tuple[np.ndarray, np.ndarray, bool]:
    """(raw round trips, ticks) in seconds, measured in alternating blocks so that
    load from other processes on the machine weighs on both alike; with `one_cpu`,
    this thread and both pairs' other processes on the CPU this thread is on (the last
    element: whether they were)."""
    from cosim.engine.one_cpu import OFF, PinnedChain, current_cpu
    spec = PythonComponentLaunch("echo", "tests.helpers.components:Echo", {}, 1)
    raw: list[float] = []
    ticks: list[float] = []
    setting = current_cpu() if one_cpu and current_cpu() is not None else OFF
    with RawPair() as pair, ZenohComponents([spec], run_id="bench") as hosted, \
            PinnedChain(setting) as chain:
        pinned = chain.pin([pair.child.pid, *hosted.local_pids()]) is not None
        loop = TickLoop(hosted)
        pair.measure(200)
        loop.measure(200)  # warm-up
        per_block = max(1, count // blocks)
        for _ in range(blocks):
            raw += pair.measure(per_block)
            ticks += loop.measure(per_block)
        loop.component.stop()
    return np.array(raw), np.array(ticks), pinned


def _pythonpath() -> str:
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    return os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH", "")) if p)


def _summary(label: str, times: np.ndarray) -> tuple[float, float]:
    median, p99 = np.median(times) * 1e6, np.percentile(times, 99) * 1e6
    print(f"{label:<34} median {median:8.1f} us   p99 {p99:8.1f} us   (n={times.size})")
    return median, p99


def measure_both(ticks: int, blocks: int, tag: tuple[str, str, str, str]) -> dict[str, float]:
    """Both placements; prints the rows labelled `tag` (raw, tick, raw one CPU, tick one
    CPU) and returns their medians in us by tag (the one-CPU ones only where available)."""
    medians = {}
    raw, tick, _ = measure_interleaved(ticks, blocks)
    medians[tag[0]], _ = _summary(f"({tag[0]}) raw put/sub round trip, 100 B", raw)
    medians[tag[1]], _ = _summary(f"({tag[1]}) lockstep tick, 1 component", tick)
    raw, tick, pinned = measure_interleaved(ticks, blocks, one_cpu=True)
    if pinned:
        medians[tag[2]], _ = _summary(f"({tag[2]}) the same on one CPU", raw)
        medians[tag[3]], _ = _summary(f"({tag[3]}) the same on one CPU", tick)
    return medians


def default_pools(ticks: int, blocks: int) -> dict[str, float]:
    """The same measurements in a child process with Zenoh's default runtime pools."""
    env = {**os.environ, "PYTHONPATH": _pythonpath(), runtime.ENV: runtime.DEFAULT_POOLS}
    done = subprocess.run([sys.executable, __file__, "--ticks", str(ticks), "--blocks", str(blocks),
                           "--pools-child"], env=env, capture_output=True, text=True)
    print("".join(line for line in done.stdout.splitlines(keepends=True)
                  if not line.startswith("median ")), end="")
    if done.returncode != 0:
        print(f"default pools: the child failed ({done.returncode}): {done.stderr.strip()[-300:]}")
        return {}
    return {k: float(v) for k, v in (line.split("=", 1) for line in done.stdout.splitlines()
                                     if line.startswith("median "))
            for k in [k.removeprefix("median ")]}


def main() -> None:
    """Run both measurements and print them with their ratio."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=5000, help="measured exchanges per case")
    parser.add_argument("--blocks", type=int, default=20, help="alternations raw/tick")
    parser.add_argument("--pools", action=argparse.BooleanOptionalAction, default=True,
                        help="also measure Zenoh's default runtime pools (a child process)")
    parser.add_argument("--echo", metavar="ENDPOINT", help=argparse.SUPPRESS)
    parser.add_argument("--pools-child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.echo:
        echo(args.echo)
        return
    if args.pools_child:
        for key, value in measure_both(args.ticks, args.blocks, ("p", "q", "p1", "q1")).items():
            print(f"median {key}={value}")
        return
    ours = measure_both(args.ticks, args.blocks, ("a", "b", "a1", "b1"))
    print(f"ratio tick / raw (medians): {ours['b'] / ours['a']:.2f}  (target <= 1.25)")
    if "a1" not in ours:
        print("one CPU: not available here (no CPU affinity, or a single CPU)")
    else:
        print(f"ratio tick / raw on one CPU (medians): {ours['b1'] / ours['a1']:.2f}  "
              f"(target <= 1.25)")
    if not args.pools:
        return
    print("with Zenoh's default runtime pools (ZENOH_RUNTIME='()'), in a child process:")
    pools = default_pools(args.ticks, args.blocks)
    for ours_key, pools_key, what in (("a", "p", "raw round trip"), ("b", "q", "lockstep tick"),
                                      ("a1", "p1", "raw round trip on one CPU"),
                                      ("b1", "q1", "lockstep tick on one CPU")):
        if ours_key in ours and pools_key in pools:
            print(f"default pools / one runtime thread, {what}: "
                  f"{pools[pools_key]:.1f} / {ours[ours_key]:.1f} us = "
                  f"{pools[pools_key] / ours[ours_key]:.2f}x")


if __name__ == "__main__":
    main()
