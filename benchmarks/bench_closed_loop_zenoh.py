"""The Satory closed loop over Zenoh against its floor: in-process tick + one raw round trip.

satory_nominal (Vehicle8DOF FMU in the master, backstepping controller every
tick, planner every 10 ticks) for `--seconds` of simulated time, in
alternating repetitions of five cases measured in the same run:

- `inproc loop`: the master over the in-process hosts (`--transport inproc`),
  no observers: the in-process tick;
- `zenoh loop`: the master over the Zenoh hosts (controller and planner in
  their own processes), no observers, every process of the chain on one CPU
  as `cosim run` puts them (`--lockstep-cpu auto`, `cosim.engine.one_cpu`):
  the Zenoh tick;
- `zenoh loop, OS placement`: the same with the processes where the OS puts
  them (`--lockstep-cpu off`);
- `zenoh loop, planner inproc`: the same with the planner hosted in the
  master's process (`--place planner=inproc`), the controller in its own;
- `cosim run zenoh`: `run_scenario(..., transport="zenoh")` as `cosim run`
  does it (recorder with its writer process, live publisher), ticks 1..N only
  (`RunResult.loop_time_s`), like the `zenoh loop` case;
- `cosim run CLI` and `cosim run CLI, default pools`: the `cosim` command
  itself in a fresh process, as it comes (Zenoh's runtime on one thread in
  every process of the run, `cosim.transport.zenoh.runtime`) and with Zenoh's
  default runtime pools (`ZENOH_RUNTIME='()'`), ticks 1..N from its manifest,
  at least 60 s simulated (compared with each other only); a process chooses
  its runtime once, so these two are child processes;
- `raw round trip`: a 100-byte put/subscribe round trip between this process
  and an echo process (benchmarks/bench_zenoh.py's pair), median of a block,
  both processes on the chain's CPU; `raw round trip, OS placement`: another
  pair, where the OS puts it.

Wall-clock time per tick (the Zenoh tick waits on other processes), minimum
and median over the repeats; then the CPU time per tick of the in-process loop
and of the Zenoh loop's processes together (master and components, every
thread: Zenoh's own included), and of the raw round trip's two processes,
with the same ratio on CPU time: a loaded machine disturbs CPU time much less
than the wall clock (10 ms clock ticks: use runs of seconds). The target (DESIGN.md): Zenoh tick <= 1.25 x
(in-process tick + one raw round trip), each loop against the round trip placed
as it is (one CPU, or the OS's placement); the planner's exchange every 10th
tick makes the real floor 1.1 round trips per tick, printed too. Both transports
must end in the same signal store, bit for bit (checked: `CHECK FAILED`, exit 1).

Then, with `--breakdown` (the default), where the Zenoh tick goes
(benchmarks/zenoh_breakdown.py): each component's exchange against its
in-process step and the raw round trip, and the CPU per tick of each process
split into its Python main thread and Zenoh's runtime threads.

Then the same across network namespaces (`--netns auto|on|off`): a namespace
for the master and one for the component processes, joined by veth pairs on a
bridge (tests/helpers/netns.py; needs root and iproute2; created and removed
here), the whole measurement re-run inside the master's namespace. Without
root it prints why and skips.

    .venv/bin/python benchmarks/bench_closed_loop_zenoh.py [--seconds 20] [--repeats 5] [--netns auto]
        [--no-breakdown]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.bench_startup import run_once  # noqa: E402
from benchmarks.bench_zenoh import RawPair  # noqa: E402
from cosim.engine import one_cpu  # noqa: E402
from benchmarks.common import (compiled_as_in_a_long_run, emit_results, load_average, min_and_median, table_row,  # noqa: E402
                               outputs_read)

SCENARIO = ROOT / "scenarios" / "satory_nominal.yaml"
TARGET = 1.25
RAW_BLOCK = 2000
CPU_INPROC, CPU_ZENOH = "inproc loop, CPU", "zenoh loop, CPU of all processes"
CPU_RAW = "raw round trip, CPU of both processes"
PLANNER_IN_MASTER = "zenoh loop, planner inproc"
OS_LOOP, OS_RAW = "zenoh loop, OS placement", "raw round trip, OS placement"
CLI_RUN, POOLS_RUN = "cosim run CLI", "cosim run CLI, default pools"
CLI_SECONDS = 60.0  # at least: a 10 s run's loop lasts 0.2 s, too short a sample for this pair
CASES = ("inproc loop", "zenoh loop", OS_LOOP, PLANNER_IN_MASTER, "cosim run zenoh", CLI_RUN, POOLS_RUN,
         "raw round trip", OS_RAW, CPU_INPROC, CPU_ZENOH, CPU_RAW)
# each loop case against the round trip placed as it is
FLOOR_OF = {"zenoh loop": "raw round trip", PLANNER_IN_MASTER: "raw round trip",
            "cosim run zenoh": "raw round trip", OS_LOOP: OS_RAW}
CHAIN_CPU = one_cpu.current_cpu() if one_cpu.supported() else None


def _chain_setting(pin: bool) -> int | str:
    """The lockstep chain's CPU, or off (`pin` False, or a platform without CPU affinity)."""
    return CHAIN_CPU if pin and CHAIN_CPU is not None else one_cpu.OFF


@contextlib.contextmanager
def on_chain_cpu(pin: bool = True, processes: tuple[int, ...] = ()):
    """This thread, `processes` and what starts inside on the lockstep chain's CPU (`cosim run`'s
    default), or nothing pinned (see `_chain_setting`)."""
    with one_cpu.PinnedChain(_chain_setting(pin)) as chain:
        chain.pin(processes)
        yield chain


def prepared_run(seconds: float):
    """satory_nominal with `duration=seconds`, prepared (FMUs built, classes imported)."""
    from cosim.execution.prepare import prepare_run
    from cosim.scenario.loader import load_scenario

    return prepare_run(load_scenario(SCENARIO, [f"duration={seconds:g}"]))


def _master(prepared, python_hosts: dict):
    """The master over the FMU hosts and `python_hosts`, wired as the scenario says, no observers."""
    from cosim.engine.master import Master
    from cosim.engine.wiring import resolve_wiring
    from cosim.execution import fmu_hosting
    from cosim.fmu.host import FmuComponent

    hosted = {p.name: FmuComponent(p.name, p.path, p.interface, p.parameters, p.period_ticks)
              for p in prepared.fmus}
    hosted.update(python_hosts)
    hosted = {name: hosted[name] for name in prepared.names}
    scenario = prepared.scenario
    unsupported = {n: c.interface.unsupported for n, c in hosted.items() if isinstance(c, FmuComponent)}
    edges = resolve_wiring(scenario, {n: (c.inputs, c.outputs) for n, c in hosted.items()}, unsupported)
    return Master(hosted, edges, scenario.tick, scenario.total_ticks,
                  fmu_hosting.start_time(scenario, prepared.fmus),
                  outputs_read=outputs_read(hosted, edges, scenario))  # as `cosim run` tells them


def _cpu_seconds(pids: list[int]) -> float:
    """CPU seconds (user + system, every thread) used so far by the processes `pids` (Linux)."""
    total = 0.0
    for pid in pids:
        with open(f"/proc/{pid}/stat") as stat:
            fields = stat.read().rsplit(")", 1)[1].split()
        total += int(fields[11]) + int(fields[12])  # utime, stime in clock ticks
    return total / os.sysconf("SC_CLK_TCK")


def _timed_loop(master, pids: list[int]) -> tuple[float, float, list[float]]:
    """Wall-clock and CPU seconds per tick of the master's whole run (the CPU of `pids`: this
    process and the component processes), and its final signal store."""
    try:
        master.initialize()
        cpu, start = _cpu_seconds(pids), time.perf_counter()
        for k in range(1, master.total_ticks + 1):
            master.step_tick(k)
        elapsed, cpu = time.perf_counter() - start, _cpu_seconds(pids) - cpu
        return elapsed / master.total_ticks, cpu / master.total_ticks, list(master.values)
    finally:
        master.stop_all()


def inproc_loop(prepared) -> tuple[float, float, list[float]]:
    """One in-process run: (wall seconds per tick, CPU seconds per tick, final store)."""
    from cosim.transport.inproc import InprocComponent

    return _timed_loop(_master(prepared, {l.name: InprocComponent(l) for l in prepared.launches}),
                       [os.getpid()])


def zenoh_loop(prepared, hosts_class=None, endpoint: str | None = None,
               in_master: tuple[str, ...] = (), pin: bool = True) -> tuple[float, float, list[float]]:
    """One run with the Python components in their own processes, but those named in `in_master`
    (in-process hosts, as `--place NAME=inproc`), all on one CPU unless `pin` is False:
    (wall seconds per tick, CPU seconds per tick of the master and the component processes,
    final store)."""
    from cosim.transport.inproc import InprocComponent
    from cosim.transport.zenoh import ZenohComponents

    cls = hosts_class or ZenohComponents
    own = [launch for launch in prepared.launches if launch.name not in in_master]
    with one_cpu.PinnedChain(_chain_setting(pin)) as chain, \
            cls(own, run_id=f"bench{uuid.uuid4().hex[:8]}", endpoint=endpoint) as remote:
        chain.pin(remote.local_pids())  # once all have started, as `cosim run` does
        pids = [os.getpid(), *remote.pids.values()]
        hosts = dict(remote.components)
        hosts.update({l.name: InprocComponent(l) for l in prepared.launches if l.name in in_master})
        return _timed_loop(_master(prepared, hosts), pids)


def cosim_run_zenoh(prepared) -> float:
    """One `run_scenario` over Zenoh (recorder, live publisher): seconds per tick of its loop,
    ticks 1..N as the `zenoh loop` case times them (tick 0, the components' initialization,
    is `bench_startup`'s; counted here it was ~60 ms, 60 us per tick of a 10 s run)."""
    from cosim.execution.run import run_scenario

    with tempfile.TemporaryDirectory(prefix="bench-cl-zenoh-") as tmp:
        result = run_scenario(prepared.scenario, Path(tmp) / "run", transport="zenoh", progress=False)
    if result.status != "ok" or result.loop_time_s is None:
        raise SystemExit(f"bench_closed_loop_zenoh: cosim run failed: {result.error}")
    return result.loop_time_s / result.ticks


def cosim_run_cli(seconds: float, pools: bool) -> float:
    """`cosim run` over Zenoh in its own process, with one runtime thread (as it comes) or
    Zenoh's default pools: seconds per tick of ticks 1..N (its manifest's `loop_time_s`)."""
    from cosim.transport.zenoh import runtime

    env = {k: v for k, v in os.environ.items() if k != runtime.ENV}
    if pools:
        env[runtime.ENV] = runtime.DEFAULT_POOLS
    with tempfile.TemporaryDirectory(prefix="bench-cl-cli-") as tmp:
        manifest = run_once(SCENARIO, "zenoh", Path(tmp) / "run", seconds, env)
    return manifest["loop_time_s"] / manifest["ticks"]


def measure(seconds: float, repeats: int, hosts_class=None, endpoint_host: str = "127.0.0.1",
            echo_wrap: tuple[str, ...] = (), full_run: bool = True) -> dict[str, list[float]]:
    """The cases, alternated `repeats` times: label -> seconds per tick (or per round trip)."""
    prepared = prepared_run(seconds)
    samples: dict[str, list[float]] = {c: [] for c in CASES
                                       if full_run or c not in ("cosim run zenoh", CLI_RUN, POOLS_RUN)}
    with RawPair(endpoint_host, echo_wrap) as pinned_pair, RawPair(endpoint_host, echo_wrap) as os_pair:
        _alternate(prepared, repeats, samples, pinned_pair, os_pair, hosts_class, endpoint_host,
                   full_run)
    return samples


def _alternate(prepared, repeats: int, samples: dict[str, list[float]], pinned_pair, os_pair,
               hosts_class, endpoint_host: str, full_run: bool) -> None:
    """`repeats` rounds of every case, into `samples`."""
    import numpy as np
    from cosim.transport.zenoh import config

    pinned = (pinned_pair.child.pid,)  # its echo process on the chain's CPU whenever it measures
    with on_chain_cpu(processes=pinned):
        pinned_pair.measure(200)  # warm-up
    os_pair.measure(200)
    for repeat in range(repeats):
        tick, cpu, inproc_store = inproc_loop(prepared)
        samples["inproc loop"].append(tick)
        samples[CPU_INPROC].append(cpu)
        endpoint = None if hosts_class is None else config.free_tcp_endpoint(endpoint_host)
        tick, cpu, zenoh_store = zenoh_loop(prepared, hosts_class, endpoint)
        samples["zenoh loop"].append(tick)
        samples[CPU_ZENOH].append(cpu)
        tick, _, os_store = zenoh_loop(prepared, hosts_class, endpoint and
                                       config.free_tcp_endpoint(endpoint_host), pin=False)
        samples[OS_LOOP].append(tick)
        tick, _, mixed_store = zenoh_loop(prepared, hosts_class, endpoint and
                                          config.free_tcp_endpoint(endpoint_host), ("planner",))
        samples[PLANNER_IN_MASTER].append(tick)
        for store, what in ((zenoh_store, "zenoh"), (os_store, "zenoh, OS placement"),
                            (mixed_store, "zenoh with the planner in the master")):
            if store != inproc_store:
                differ = sum(a != b for a, b in zip(store, inproc_store))
                raise SystemExit(f"CHECK FAILED: {what} and inproc signal stores differ ({differ} values)")
        if full_run:
            samples["cosim run zenoh"].append(cosim_run_zenoh(prepared))
            cli_seconds = max(prepared.scenario.duration, CLI_SECONDS)
            for pools in (False, True) if repeat % 2 == 0 else (True, False):  # either goes first
                samples[POOLS_RUN if pools else CLI_RUN].append(cosim_run_cli(cli_seconds, pools))
        pids = [os.getpid(), pinned_pair.child.pid]
        cpu = _cpu_seconds(pids)
        with on_chain_cpu(processes=pinned):
            samples["raw round trip"].append(float(np.median(pinned_pair.measure(RAW_BLOCK))))
        samples[CPU_RAW].append((_cpu_seconds(pids) - cpu) / RAW_BLOCK)
        samples[OS_RAW].append(float(np.median(os_pair.measure(RAW_BLOCK))))


def summarize(samples: dict[str, list[float]], where: str) -> dict[str, float]:
    """Print the cases and the ratios against the floor; return the figures (us)."""
    figures: dict[str, float] = {}
    print(f"{'case':<34}{'min us':>10}{'median us':>11}")
    for label, values in samples.items():
        low, mid = min_and_median(values)
        figures[f"{label} min"], figures[f"{label} median"] = low * 1e6, mid * 1e6
        print(f"{label:<34}{low * 1e6:>10.1f}{mid * 1e6:>11.1f}")
    for stat in ("min", "median"):
        for case, raw in FLOOR_OF.items():
            if f"{case} {stat}" not in figures:
                continue
            floor = figures[f"inproc loop {stat}"] + figures[f"{raw} {stat}"]
            floor_11 = figures[f"inproc loop {stat}"] + 1.1 * figures[f"{raw} {stat}"]
            ratio = figures[f"ratio {case} {stat}"] = figures[f"{case} {stat}"] / floor
            print(f"{where}, {stat}s: {case} / (inproc tick + 1 {raw} = {floor:.1f} us) = "
                  f"{ratio:.2f}  (target <= {TARGET}: {'met' if ratio <= TARGET else 'not met'}); "
                  f"against 1.1 round trips ({floor_11:.1f} us): {figures[f'{case} {stat}'] / floor_11:.2f}")
        for case in ("zenoh loop", "cosim run zenoh"):  # the floor: the round trip as the OS places it
            if f"{case} {stat}" in figures:
                floor = figures[f"inproc loop {stat}"] + figures[f"{OS_RAW} {stat}"]
                ratio = figures[f"ratio {case} to the OS-placed floor {stat}"] = figures[f"{case} {stat}"] / floor
                print(f"{where}, {stat}s: {case} (one CPU) / (inproc tick + 1 {OS_RAW} = {floor:.1f} us) "
                      f"= {ratio:.2f}")
        if f"{POOLS_RUN} {stat}" in figures:
            gain = figures[f"one runtime thread {stat}"] = (figures[f"{POOLS_RUN} {stat}"]
                                                            / figures[f"{CLI_RUN} {stat}"])
            print(f"{where}, {stat}s: cosim run, Zenoh's default pools / one runtime thread = {gain:.2f}")
        if f"zenoh loop {stat}" in figures:
            speedup = figures[f"speed-up of one CPU {stat}"] = (figures[f"{OS_LOOP} {stat}"]
                                                                / figures[f"zenoh loop {stat}"])
            print(f"{where}, {stat}s: zenoh loop, OS placement / on one CPU = {speedup:.2f}")
    if CPU_RAW in samples:
        floor = figures[f"{CPU_INPROC} median"] + figures[f"{CPU_RAW} median"]
        ratio = figures["ratio cpu median"] = figures[f"{CPU_ZENOH} median"] / floor
        print(f"{where}, CPU medians: zenoh loop / (inproc tick + 1 round trip = {floor:.1f} us) = "
              f"{ratio:.2f}")
    return figures


# ------------------------------------------------------------------ network namespaces
def netns_measure(seconds: float, repeats: int, component_ns: str, master_host: str) -> None:
    """Inside the master's namespace: the measurement with the component (and echo) processes
    in `component_ns`; prints the samples as one JSON line."""
    from cosim.transport.zenoh import ZenohComponents
    from cosim.transport.zenoh.processes import ChildProcess

    wrap = ("ip", "netns", "exec", component_ns)

    class NamespacedChild(ChildProcess):
        def _start(self, name, run_id, argv, import_path=(), one_runtime_thread=True):
            super()._start(name, run_id, [*wrap, *argv], import_path, one_runtime_thread)

    class NamespacedComponents(ZenohComponents):
        def _spawn(self, spec):
            return NamespacedChild(spec, self.run_id, self.endpoint, credential=self.credential)

    samples = measure(seconds, repeats, NamespacedComponents, master_host, wrap, full_run=False)
    print("SAMPLES " + json.dumps(samples))


def across_namespaces(seconds: float, repeats: int, mode: str) -> dict[str, float] | None:
    """Create the namespaces, re-run the measurement inside them, remove them; the figures."""
    from tests.helpers import netns

    why = netns.unavailable()
    if why:
        print(f"across network namespaces: skipped ({why})")
        if mode == "on":
            raise SystemExit(1)
        return None
    with netns.NetLab(["comp"]) as lab:
        argv = lab.exec(netns.MASTER, [sys.executable, __file__, "--seconds", str(seconds),
                                       "--repeats", str(repeats), "--netns-child", lab.namespaces["comp"],
                                       "--master-host", lab.address(netns.MASTER)])
        done = subprocess.run(argv, capture_output=True, text=True, cwd=ROOT)
    lines = [l for l in done.stdout.splitlines() if l.startswith("SAMPLES ")]
    if done.returncode != 0 or not lines:
        raise SystemExit(f"across network namespaces failed: {done.stderr.strip()[-1500:]}")
    print("across network namespaces (master in one, controller, planner and echo in another, veth + bridge):")
    return summarize(json.loads(lines[-1][len("SAMPLES "):]), "across namespaces")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="simulated seconds per run")
    parser.add_argument("--repeats", type=int, default=5, help="rounds of the alternating cases")
    parser.add_argument("--netns", choices=("auto", "on", "off"), default="auto",
                        help="also measure across network namespaces (auto: if root and iproute2)")
    parser.add_argument("--breakdown", action=argparse.BooleanOptionalAction, default=True,
                        help="also print where the Zenoh tick goes (one more run of each loop)")
    parser.add_argument("--netns-child", metavar="NS", help=argparse.SUPPRESS)
    parser.add_argument("--master-host", default="127.0.0.1", help=argparse.SUPPRESS)
    args = parser.parse_args()
    compiled_as_in_a_long_run()  # a quick run's controller would otherwise run interpreted
    if not (args.seconds >= 1 and args.repeats >= 1):
        parser.error(f"need --seconds >= 1 and --repeats >= 1, got {args.seconds} and {args.repeats}")
    if args.netns_child:
        netns_measure(args.seconds, args.repeats, args.netns_child, args.master_host)
        return
    if CHAIN_CPU is None:
        print("this platform does not let a process choose its CPUs: the 'one CPU' cases below run "
              "where the OS puts them")
    before = load_average()
    samples = measure(args.seconds, args.repeats)
    print(f"satory_nominal, {args.seconds:g} s simulated ({args.seconds * 100:.0f} ticks), {args.repeats} "
          f"alternating repeats, wall clock; load average {before} before, {load_average()} after")
    figures = {"loopback": summarize(samples, "loopback")}
    if args.breakdown:
        from benchmarks import zenoh_breakdown

        with on_chain_cpu(), RawPair() as pair:  # on the chain's CPU, as the headline loop
            pair.measure(200)  # warm-up
            figures["breakdown"] = zenoh_breakdown.report(prepared_run(args.seconds), _master, pair,
                                                          RAW_BLOCK)
    if args.netns != "off":
        netns_figures = across_namespaces(args.seconds, args.repeats, args.netns)
        if netns_figures:
            figures["netns"] = netns_figures
    rows = [row for where, f in figures.items() if where != "breakdown" for row in table_rows(where, f)]
    if "breakdown" in figures:
        from benchmarks import zenoh_breakdown

        rows += zenoh_breakdown.table_rows(figures["breakdown"])
    emit_results("bench_closed_loop_zenoh", {**figures, "seconds": args.seconds, "repeats": args.repeats,
                                             "load": f"{before} -> {load_average()}"}, rows)


def table_rows(where: str, f: dict[str, float]) -> list[dict]:
    """The performance-table rows of one setting (loopback or netns), from the medians."""
    rows = []
    for case, what in (("zenoh loop", "master loop, one CPU"),
                       ("cosim run zenoh", "`cosim run`, recorder on, one CPU"),
                       (PLANNER_IN_MASTER, "master loop, one CPU, planner in the master's process as "
                                           "with `--place planner=inproc`"),
                       (OS_LOOP, "master loop, `--lockstep-cpu off`")):
        if f"ratio {case} median" in f:
            ratio, raw = f[f"ratio {case} median"], FLOOR_OF[case]
            placed = "OS-placed" if raw == OS_RAW else "one-CPU"
            floor = f"inproc {f['inproc loop median']:.0f} + round trip {f[f'{raw} median']:.0f} µs"
            rows.append(table_row(f"Satory loop over Zenoh ({what}, {where}) / (in-process tick + 1 "
                                  f"{placed} raw round trip)",
                                  f"{f[f'{case} median']:.0f} µs/tick vs {floor}: {ratio:.2f}",
                                  f"<= {TARGET}", ratio <= TARGET))
    for case, what in (("zenoh loop", "master loop, one CPU"), ("cosim run zenoh", "`cosim run`, one CPU")):
        if f"ratio {case} to the OS-placed floor median" in f:
            ratio = f[f"ratio {case} to the OS-placed floor median"]
            floor = f"inproc {f['inproc loop median']:.0f} + round trip {f[f'{OS_RAW} median']:.0f} µs"
            # for reference only: a one-CPU loop over a floor placed otherwise is no target's ratio
            rows.append(table_row(f"Satory loop over Zenoh ({what}, {where}) / (in-process tick + 1 OS-placed "
                                  f"raw round trip: the floor as the issue defined it, placed unlike the loop)",
                                  f"{f[f'{case} median']:.0f} µs/tick vs {floor}: {ratio:.2f}", "-", None))
    if "one runtime thread median" in f:
        rows.append(table_row(f"`cosim run` over Zenoh ({where}): Zenoh's default runtime pools / one "
                              f"runtime thread (as it comes)",
                              f"{f[f'{POOLS_RUN} median']:.0f} vs {f[f'{CLI_RUN} median']:.0f} µs/tick: "
                              f"{f['one runtime thread median']:.2f}x", "-", None))
    if "speed-up of one CPU median" in f:
        rows.append(table_row(f"Satory loop over Zenoh ({where}): OS placement / one CPU",
                              f"{f['speed-up of one CPU median']:.2f}x", "-", None))
    return rows


if __name__ == "__main__":
    main()
