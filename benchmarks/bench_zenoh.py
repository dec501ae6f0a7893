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

Each measurement runs in a child process, since a process chooses its Zenoh
runtime once: with the runtime on one thread, as a run's processes have it
(cosim.transport.zenoh.runtime), and with Zenoh's default pools
(`ZENOH_RUNTIME='()'`, rows (p), (q), (p1), (q1)), alternating over `--rounds`;
each row is the median over its rounds, and the speed-up of one thread over the
pools is printed, medians and p99 (`--no-pools`: one thread only).

    PYTHONPATH=. .venv/bin/python benchmarks/bench_zenoh.py [--ticks 5000] [--rounds 2] [--no-pools]
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


CASES = (("raw", "raw put/sub round trip, 100 B"), ("tick", "lockstep tick, 1 component"),
         ("raw1", "the same on one CPU"), ("tick1", "the same on one CPU"))
# each runtime's row labels, as printed: ours (a)..(b1) (run_all_rows reads them), the pools' (p)..(q1)
LABELS = {"one": ("a", "b", "a1", "b1"), "pools": ("p", "q", "p1", "q1")}
RUNTIMES = {"one": runtime.ONE_THREAD, "pools": runtime.DEFAULT_POOLS}
CHILD_TIMEOUT_S = 600


def measure_cases(ticks: int, blocks: int) -> dict[str, tuple[float, float]]:
    """Both placements in this process: (median, p99) in us by case (one-CPU ones if available)."""
    found = {}
    for one_cpu in (False, True):
        raw, tick, pinned = measure_interleaved(ticks, blocks, one_cpu=one_cpu)
        if one_cpu and not pinned:
            break
        for case, times in zip(("raw1", "tick1") if one_cpu else ("raw", "tick"), (raw, tick)):
            found[case] = (float(np.median(times) * 1e6), float(np.percentile(times, 99) * 1e6))
    return found


def measure_in_child(ticks: int, blocks: int, setting: str) -> dict[str, tuple[float, float]]:
    """`measure_cases` in a child process whose Zenoh runtime is `setting` (a process chooses
    its runtime once); {} if the child failed (said on stdout)."""
    env = {**os.environ, "PYTHONPATH": _pythonpath(), runtime.ENV: setting}
    try:
        done = subprocess.run([sys.executable, __file__, "--ticks", str(ticks), "--blocks", str(blocks),
                               "--child"], env=env, capture_output=True, text=True,
                              timeout=CHILD_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        print(f"ZENOH_RUNTIME={setting!r}: the child took more than {CHILD_TIMEOUT_S} s")
        return {}
    if done.returncode != 0:
        print(f"ZENOH_RUNTIME={setting!r}: the child failed ({done.returncode}): "
              f"{done.stderr.strip()[-300:]}")
        return {}
    return parse_child(done.stdout)


def parse_child(text: str) -> dict[str, tuple[float, float]]:
    """The cases a child printed as `case median p99` lines."""
    found = {}
    for line in text.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0] in dict(CASES):
            found[parts[0]] = (float(parts[1]), float(parts[2]))
    return found


def combine(rounds: list[dict[str, tuple[float, float]]]) -> dict[str, tuple[float, float]]:
    """Per case, the median over the rounds of its median and of its p99."""
    cases = [case for case, _ in CASES if rounds and all(case in r for r in rounds)]
    return {case: (float(np.median([r[case][0] for r in rounds])),
                   float(np.median([r[case][1] for r in rounds]))) for case in cases}


def print_cases(which: str, found: dict[str, tuple[float, float]], ticks: int, rounds: int) -> None:
    for (case, what), label in zip(CASES, LABELS[which]):
        if case in found:
            median, p99 = found[case]
            print(f"{f'({label}) {what}':<34} median {median:8.1f} us   p99 {p99:8.1f} us   "
                  f"(n={ticks} x {rounds})")


def main() -> None:
    """Run the measurements under each runtime, alternating, and print them with their ratios."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=5000, help="measured exchanges per case")
    parser.add_argument("--blocks", type=int, default=20, help="alternations raw/tick")
    parser.add_argument("--rounds", type=int, default=2,
                        help="rounds of child processes, alternating the two runtimes")
    parser.add_argument("--pools", action=argparse.BooleanOptionalAction, default=True,
                        help="also measure Zenoh's default runtime pools")
    parser.add_argument("--echo", metavar="ENDPOINT", help=argparse.SUPPRESS)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.echo:
        echo(args.echo)
        return
    if args.child:
        for case, (median, p99) in measure_cases(args.ticks, args.blocks).items():
            print(case, median, p99)
        return
    which = ("one", "pools") if args.pools else ("one",)
    rounds: dict[str, list] = {w: [] for w in which}
    for _ in range(max(1, args.rounds)):
        for w in which:
            found = measure_in_child(args.ticks, args.blocks, RUNTIMES[w])
            if found:
                rounds[w].append(found)
    report({w: combine(rounds[w]) for w in which}, {w: len(r) for w, r in rounds.items()}, args.ticks)


def report(results: dict[str, dict], rounds: dict[str, int], ticks: int) -> None:
    """Print each runtime's rows (as run_all_rows reads them), the ratios and the speed-ups."""
    ours = results["one"]
    if "tick" not in ours:
        raise SystemExit("bench_zenoh: no measurement with one runtime thread")
    print(f"Zenoh's runtime on one thread in every process (as a run's processes), "
          f"{rounds['one']} child processes, medians over them:")
    print_cases("one", ours, ticks, rounds["one"])
    print(f"ratio tick / raw (medians): {ours['tick'][0] / ours['raw'][0]:.2f}  (target <= 1.25)")
    if "tick1" not in ours:
        print("one CPU: not available here (no CPU affinity, or a single CPU)")
    else:
        print(f"ratio tick / raw on one CPU (medians): {ours['tick1'][0] / ours['raw1'][0]:.2f}  "
              f"(target <= 1.25)")
    if "pools" not in results:
        return
    pools = results["pools"]
    print("with Zenoh's default runtime pools (ZENOH_RUNTIME='()'), the child processes "
          "alternating with the above:")
    print_cases("pools", pools, ticks, rounds["pools"])
    for case, what in (("raw", "raw round trip"), ("tick", "lockstep tick"),
                       ("raw1", "raw round trip on one CPU"), ("tick1", "lockstep tick on one CPU")):
        if case in ours and case in pools:
            (mine, mine_p99), (theirs, theirs_p99) = ours[case], pools[case]
            print(f"default pools / one runtime thread, {what}: {theirs:.1f} / {mine:.1f} us = "
                  f"{theirs / mine:.2f}x (p99 {theirs_p99:.0f} / {mine_p99:.0f} us = "
                  f"{theirs_p99 / mine_p99:.2f}x)")


if __name__ == "__main__":
    main()
