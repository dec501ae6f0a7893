"""Where the Zenoh tick goes: per-component exchange times and CPU per process and thread kind.

Used by `bench_closed_loop_zenoh.py --breakdown` after its headline cases, in
runs of their own (the timers wrapped around each call would otherwise weigh
on the headline figures). For one in-process loop and one Zenoh loop of the
same scenario it prints:

- each Python component's time per step: in-process, the component's own
  `step` (thread CPU time); over Zenoh, the whole exchange seen from the
  master (wall clock from the request's put to the decoded reply), and its
  share per tick (the planner steps 1 tick in 10);
- the CPU time per tick of every process of the Zenoh loop, split into its
  main thread (the Python code), Zenoh's runtime threads (named tx-N, rx-N,
  net-N, acc-N, app-N: the Rust transport) and any other thread (the master's
  watchdog);
- the same for a raw put/subscribe round trip, so that the Zenoh tick reads as
  its parts: the in-process work, one exchange per component step, and what
  each exchange costs beyond the raw round trip and the component's in-process
  step;
- the raw round trip again with this process busy for one in-process tick
  between round trips: in the loop no process sends back to back, and on this
  kind of machine (a VM) a thread that was idle or busy elsewhere for a while
  runs its next put and receive measurably slower (cold caches, a halted vCPU
  to wake). Its floor, in-process tick + that round trip, is printed beside
  the headline one.

The figures are medians over the steps of one run each, so they move with the
load like the headline ones; the CPU split moves much less.
"""

from __future__ import annotations

import os
import re
import statistics
import time
import uuid
from collections import defaultdict
from collections.abc import Callable
from typing import Any

ZENOH_THREAD = re.compile(r"^(tx|rx|net|acc|app)-\d+$")
KINDS = ("main thread", "Zenoh runtime", "other threads")


def thread_cpu(pid: int) -> dict[str, float]:
    """CPU seconds used so far by process `pid`, per thread kind (see KINDS; Linux /proc)."""
    ticks_per_s = os.sysconf("SC_CLK_TCK")
    by_kind = dict.fromkeys(KINDS, 0.0)
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            with open(f"/proc/{pid}/task/{tid}/stat") as stat:
                text = stat.read()
        except FileNotFoundError:  # the thread ended meanwhile
            continue
        name = text[text.index("(") + 1:text.rindex(")")]
        fields = text.rsplit(")", 1)[1].split()
        kind = KINDS[0] if int(tid) == pid else KINDS[1] if ZENOH_THREAD.match(name) else KINDS[2]
        by_kind[kind] += (int(fields[11]) + int(fields[12])) / ticks_per_s
    return by_kind


def _timed(step: Callable, durations: list[float], clock: Callable[[], float]) -> Callable:
    """`step` with the duration of every call appended to `durations`."""

    def timed(*args: Any) -> Any:
        start = clock()
        try:
            return step(*args)
        finally:
            durations.append(clock() - start)

    return timed


def inproc_steps(prepared, make_master) -> tuple[dict[str, list[float]], float]:
    """One in-process loop: each Python component's step durations, and the seconds per tick
    of the whole loop (thread CPU time: one thread does it all, and CPU time is what the
    machine's load disturbs least)."""
    from cosim.transport.inproc import InprocComponent

    hosts = {launch.name: InprocComponent(launch) for launch in prepared.launches}
    durations: dict[str, list[float]] = {name: [] for name in hosts}
    for name, host in hosts.items():     # the step the master calls: the values lane's, else step
        if host.value_names is not None:
            host._step_values = _timed(host._step_values, durations[name], time.thread_time)
        else:
            host.component.step = _timed(host.component.step, durations[name], time.thread_time)
    master = make_master(prepared, hosts)
    try:
        master.initialize()
        start = time.thread_time()
        for k in range(1, master.total_ticks + 1):
            master.step_tick(k)
        tick = (time.thread_time() - start) / master.total_ticks
    finally:
        master.stop_all()
    return durations, tick


def zenoh_steps(prepared, make_master) -> tuple[dict[str, list[float]], dict[str, dict[str, float]],
                                                float]:
    """One Zenoh loop: each component's exchange durations (wall seconds), the CPU seconds per
    tick of each process by thread kind, and the wall seconds per tick of the loop."""
    from cosim.transport.zenoh import ZenohComponents

    with ZenohComponents(prepared.launches, run_id=f"breakdown{uuid.uuid4().hex[:8]}") as remote:
        durations: dict[str, list[float]] = {name: [] for name in remote.components}
        for name, component in remote.components.items():  # the call the master makes, as above
            if component.value_names is not None:
                component.step_values = _timed(component.step_values, durations[name], time.perf_counter)
            else:
                component.step = _timed(component.step, durations[name], time.perf_counter)
        pids = {"master": os.getpid(), **remote.pids}
        master = make_master(prepared, remote.components)
        try:
            master.initialize()
            before = {name: thread_cpu(pid) for name, pid in pids.items()}
            start = time.perf_counter()
            for k in range(1, master.total_ticks + 1):
                master.step_tick(k)
            tick = (time.perf_counter() - start) / master.total_ticks
            after = {name: thread_cpu(pid) for name, pid in pids.items()}
        finally:
            master.stop_all()
    ticks = master.total_ticks
    cpu = {name: {kind: (after[name][kind] - before[name][kind]) / ticks for kind in KINDS}
           for name in pids}
    return durations, cpu, tick


def raw_cpu(pair, count: int, busy_s: float = 0.0) -> tuple[float, dict[str, dict[str, float]]]:
    """Median wall seconds of `count` raw round trips (this process busy for `busy_s` between
    them), and the CPU seconds per round trip of both processes per thread kind (the busy
    spell's CPU not counted)."""
    pids = {"this process": os.getpid(), "echo process": pair.child.pid}
    before = {name: thread_cpu(pid) for name, pid in pids.items()}
    times = pair.measure(count, busy_s)
    median = statistics.median(times)
    after = {name: thread_cpu(pid) for name, pid in pids.items()}
    split = {name: {kind: (after[name][kind] - before[name][kind]) / count for kind in KINDS}
             for name in pids}
    split["this process"][KINDS[0]] -= busy_s
    return median, split


def table_rows(figures: dict[str, Any]) -> list[dict]:
    """The performance-table rows of the breakdown (figures, no target: they explain the ratio)."""
    from benchmarks.common import table_row

    parts = "; ".join(
        f"{name} {c['exchange']:.0f} µs per step ({c['steps']} steps) = in-process step "
        f"{c['inproc step']:.0f} + raw round trip {figures['raw round trip median']:.0f} + "
        f"{c['beyond']:.0f} beyond, {c['per tick']:.0f} µs per tick"
        for name, c in figures["components"].items())
    cpu = "; ".join(f"{name} " + " + ".join(f"{split[kind]:.0f}" for kind in KINDS[:2])
                    for name, split in figures["cpu"].items())
    busy = figures["raw round trip after a busy tick median"]
    ratio = figures["ratio to floor, round trip after a busy tick"]
    return [table_row("Zenoh tick, where it goes (one run with timers): each exchange seen from the master",
                      parts, "-", None),
            table_row("Zenoh tick: CPU µs per tick (per raw round trip for raw:), main thread + Zenoh "
                      "runtime threads", cpu, "-", None),
            table_row("Zenoh tick / (in-process tick + raw round trip with the requester busy one "
                      "in-process tick between round trips)",
                      f"{figures['zenoh tick']:.0f} µs vs {figures['inproc tick']:.0f} + {busy:.0f} µs: "
                      f"{ratio:.2f}", "-", None)]


def report(prepared, make_master, pair, raw_count: int) -> dict[str, Any]:
    """Run the breakdown, print it, and return its figures (microseconds)."""
    inproc, inproc_tick = inproc_steps(prepared, make_master)
    remote, cpu, zenoh_tick = zenoh_steps(prepared, make_master)
    ticks = prepared.scenario.total_ticks
    raw_median, raw_split = raw_cpu(pair, raw_count)
    busy_median, _ = raw_cpu(pair, raw_count, inproc_tick)
    us = 1e6
    figures: dict[str, Any] = {"raw round trip median": raw_median * us,
                               "raw round trip after a busy tick median": busy_median * us,
                               "inproc tick": inproc_tick * us, "zenoh tick": zenoh_tick * us,
                               "components": {}, "cpu": {}}
    print("\nwhere the Zenoh tick goes (one run each, medians over the steps; wrapped timers):")
    print(f"{'component':<12}{'steps':>7}{'in-process step':>17}{'Zenoh exchange':>16}"
          f"{'beyond step + raw RT':>22}{'exchange per tick':>19}")
    for name, exchanges in remote.items():
        step, exchange = statistics.median(inproc[name]) * us, statistics.median(exchanges) * us
        beyond = exchange - step - raw_median * us
        per_tick = sum(exchanges) / ticks * us
        figures["components"][name] = {"steps": len(exchanges), "inproc step": step,
                                       "exchange": exchange, "beyond": beyond, "per tick": per_tick}
        print(f"{name:<12}{len(exchanges):>7}{step:>15.1f}us{exchange:>14.1f}us{beyond:>20.1f}us"
              f"{per_tick:>17.1f}us")
    print(f"raw round trip (median of {raw_count}): {raw_median * us:.1f} us back to back, "
          f"{busy_median * us:.1f} us with this process busy {inproc_tick * us:.0f} us (one "
          f"in-process tick) between round trips")
    for label, rt in (("back to back", raw_median), ("after a busy tick", busy_median)):
        floor = inproc_tick + rt
        figures[f"ratio to floor, round trip {label}"] = zenoh_tick / floor
        print(f"this run's Zenoh tick {zenoh_tick * us:.0f} us / (in-process tick "
              f"{inproc_tick * us:.0f} + round trip {label} {rt * us:.0f} us) = {zenoh_tick / floor:.2f}")
    print("\nCPU per tick of the Zenoh loop's processes (us), and per raw round trip:")
    print(f"{'process':<16}" + "".join(f"{kind:>16}" for kind in KINDS) + f"{'all':>10}")
    rows = {name: {kind: value * us for kind, value in split.items()} for name, split in cpu.items()}
    rows.update({f"raw: {name}": {kind: value * us for kind, value in split.items()}
                 for name, split in raw_split.items()})
    for name, split in rows.items():
        figures["cpu"][name] = split
        print(f"{name:<16}" + "".join(f"{split[kind]:>16.1f}" for kind in KINDS)
              + f"{sum(split.values()):>10.1f}")
    totals = defaultdict(float)
    for name, split in rows.items():
        totals["raw round trip" if name.startswith("raw: ") else "zenoh loop"] += sum(split.values())
    print("all processes: " + ", ".join(f"{k} {v:.1f} us" for k, v in totals.items()))
    return figures
