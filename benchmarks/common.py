"""Timing helpers shared by the benchmarks in this folder.

The machine is shared with other jobs, so a benchmark that compares two ways
of doing the same work runs them in alternating repetitions (the same load
weighs on both) and reports the minimum (the run least disturbed) next to
the median. Each case is a callable that does its own set-up, times only the
part that matters, and returns seconds per unit of work.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path


def interleaved(cases: Mapping[str, Callable[[], float]], repeats: int) -> dict[str, list[float]]:
    """Run every case once per repetition, in turn, `repeats` times.

    Args:
        cases: label -> callable returning one sample (e.g. seconds per step).
        repeats: number of rounds (>= 1).
    Returns:
        label -> the samples in the order taken.
    """
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    samples: dict[str, list[float]] = {label: [] for label in cases}
    for _ in range(repeats):
        for label, case in cases.items():
            samples[label].append(case())
    return samples


def min_and_median(samples: list[float]) -> tuple[float, float]:
    """(minimum, median) of a non-empty list of samples."""
    if not samples:
        raise ValueError("no samples")
    return min(samples), statistics.median(samples)


RESULT_PREFIX = "RESULT "


def compiled_as_in_a_long_run() -> str:
    """COSIM_JIT=on when it is unset or auto and numba is installed; the setting in effect.

    The loops these benchmarks time stand for long runs, whose controllers run compiled;
    with auto, a component process built for a run of fewer than
    `controllers.jit.SHORT_RUN_STEPS` steps (every quick setting here) would run
    interpreted, and a master timed against another implementation or against itself
    at two durations would then not run the same code. Child processes inherit it. The
    planner's road search is compiled too (auto would compile it from
    `controllers.road.compiled_path.SHORT_RUN_STEPS` planner steps).
    """
    import importlib.util

    if os.environ.get("COSIM_JIT", "auto").strip().lower() in ("", "auto") \
            and importlib.util.find_spec("numba") is not None:
        os.environ["COSIM_JIT"] = "on"
    return os.environ.get("COSIM_JIT", "auto")


def load_average() -> str:
    """The 1, 5 and 15 minute load averages as "a / b / c", to print next to a figure."""
    return " / ".join(f"{x:.2f}" for x in os.getloadavg())


ANCHOR_LOOPS = 200_000


def speed_anchor(repeats: int = 5) -> float:
    """This machine's speed now: ns per iteration of a fixed pure-Python float loop (best of `repeats`).

    Figures from different sessions (or machines) compare through it: a
    benchmark figure divided by the anchor printed beside it is roughly
    independent of how fast the core was at the time. Thread CPU time.
    """
    best = float("inf")
    for _ in range(repeats):
        start = time.thread_time()
        x, y = 0.5, 0.0
        for _ in range(ANCHOR_LOOPS):
            y = y * 0.999 + x * x - 0.25
        best = min(best, time.thread_time() - start)
    return best / ANCHOR_LOOPS * 1e9


CEILING_LOOPS = 1_500_000  # iterations of the anchor's loop per process (about 0.1 s)

_CEILING_CHILD = """
import os, sys, time
cpu = int(sys.argv[1])
if cpu >= 0:
    os.sched_setaffinity(0, {cpu})
print("ready", flush=True)
sys.stdin.readline()
start = time.perf_counter()
x, y = 0.5, 0.0
for _ in range(int(sys.argv[2])):
    y = y * 0.999 + x * x - 0.25
print(time.perf_counter() - start, flush=True)
"""


def _loops_on(cpus: Sequence[int], loops: int) -> float:
    """The longest of len(cpus) processes' own times (wall seconds, from their start signal)
    for `loops` iterations of the anchor's loop, each on its CPU (-1: anywhere), all
    signalled at once."""
    children = [subprocess.Popen([sys.executable, "-S", "-c", _CEILING_CHILD, str(cpu), str(loops)],
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
                for cpu in cpus]
    try:
        for child, cpu in zip(children, cpus):
            if child.stdout is None or child.stdout.readline().strip() != "ready":
                raise RuntimeError(f"the ceiling's process for CPU {cpu} did not start "
                                   f"(exit status {child.wait()})")
        for child in children:
            if child.stdin is not None:
                child.stdin.write("go\n")
                child.stdin.flush()
        return max(float(child.communicate()[0]) for child in children)
    finally:
        for child in children:
            if child.poll() is None:
                child.kill()
                child.wait()


def two_process_ceiling(rounds: int = 3, loops: int = CEILING_LOOPS) -> float:
    """How much faster two CPU-bound processes get through twice the work than one does
    the work alone: 2 x alone / together, medians over `rounds` alternating rounds.

    Each process runs the speed anchor's pure-Python loop, the first on the first CPU
    this process may use and the second on the second, as a sweep's workers are placed
    (`cosim.execution.worker_cpus`; anywhere when this platform cannot pin; the lone
    process is pinned too, where a 1-worker sweep is not). 2.0 on cores that share
    nothing; less where the two CPUs share a physical core or the host's time: the most
    2 sweep workers can scale here. A single round of 0.1 s loops can come out above 2
    when the lone process met a slow moment: use several.
    """
    allowed = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
    cpus = allowed[:2] if len(allowed) >= 2 else [-1, -1]
    alone, together = [], []
    for _ in range(rounds):
        alone.append(_loops_on(cpus[:1], loops))
        together.append(_loops_on(cpus, loops))
    return 2.0 * statistics.median(alone) / statistics.median(together)


def table_row(measure: str, figure: str, target: str, met: bool | None) -> dict[str, object]:
    """One row of the performance table (`benchmarks/run_all.py`): what, the figure, the target, met?"""
    return {"measure": measure, "figure": figure, "target": target, "met": met}


def emit_results(benchmark: str, figures: Mapping[str, object],
                 rows: Sequence[Mapping[str, object]] = ()) -> None:
    """Print the benchmark's figures as one machine-readable line (`benchmarks/run_all.py` reads it).

    Args:
        benchmark: the benchmark's name (its file name without .py).
        figures: JSON-able figures (numbers, strings, nested mappings and lists).
        rows: its rows of the performance table (`table_row`).
    """
    print(RESULT_PREFIX + json.dumps({"benchmark": benchmark, "figures": figures, "rows": list(rows)}),
          flush=True)


PROFILERS = ("pyinstrument", "py-spy")
_PY_SPY_FRAME = re.compile(r"^(.*) \((.*):(\d+)\)$")


def profile_call(run: Callable[[], object], *, units: int, unit: str = "tick",
                 groups: Mapping[str, Callable[[str, str], bool]] | None = None,
                 out: str | None = None, profiler: str = "pyinstrument", top: int = 25) -> dict[str, float]:
    """Run `run()` once under a sampling profiler and print where the time went.

    Prints, per unit of work (e.g. per tick): the time inside each group (the
    outermost frames a group's predicate accepts, their callees included), then
    the `top` functions by self time (lines of one function merged).

    pyinstrument (in-process, a sample every 100 us) hooks every Python call
    and so inflates Python-heavy code about 2x: read its shares, not its
    microseconds. py-spy (`profiler="py-spy"`) samples this process from
    outside at 1 kHz (it needs ptrace rights: root, or
    kernel.yama.ptrace_scope = 0) and does not slow the code down; its
    figures are scaled to the run's elapsed time.

    Args:
        run: the work to profile (e.g. a whole closed-loop run).
        units: how many units `run` does (ticks, steps), to print us per unit.
        unit: the unit's name, for the printout.
        groups: label -> predicate(function name without its class, file path) marking a
            group's frames (a sample counts once per group however deep the group's frames nest).
        out: also keep the profile there: pyinstrument writes HTML if it ends in .html,
            else the text tree; py-spy writes its collapsed stacks (flamegraph.pl input).
        profiler: "pyinstrument" or "py-spy".
        top: how many functions to list by self time.
    Returns:
        label -> us per unit inside that group, plus "total" (the whole run).
    """
    if profiler not in PROFILERS:
        raise ValueError(f"profiler must be one of {PROFILERS}, got {profiler!r}")
    stacks, note = (_pyinstrument_stacks if profiler == "pyinstrument" else _py_spy_stacks)(run, out)
    per = 1e6 / units
    inside = {label: 0.0 for label in (groups or {})}
    selfs: dict[tuple[str, str], float] = {}
    total = 0.0
    for stack, seconds in stacks:
        total += seconds
        for label, accepts in (groups or {}).items():
            if any(accepts(function.rpartition(".")[2], path) for function, path in stack):
                inside[label] += seconds
        if stack:
            selfs[stack[-1]] = selfs.get(stack[-1], 0.0) + seconds
    if not total:
        print(f"profile ({profiler}): no samples")
        return {}
    print(f"profile ({note}): {total * per:.2f} us/{unit} under the profiler")
    figures = {label: seconds * per for label, seconds in inside.items()}
    for label, seconds in inside.items():
        print(f"  {label:<40}{seconds * per:>9.2f} us/{unit}{100 * seconds / total:>7.1f}%")
    print(f"top {top} functions by self time:")
    for (function, path), seconds in sorted(selfs.items(), key=lambda kv: -kv[1])[:top]:
        print(f"  {seconds * per:>8.2f} us/{unit}{100 * seconds / total:>6.1f}%  {function}  {path}")
    if out:
        print(f"profile written to {out}")
    figures["total"] = total * per
    return figures


Stack = tuple[tuple[str, str], ...]      # (function, file) from the outermost frame to the innermost


def _pyinstrument_stacks(run: Callable[[], object], out: str | None) -> tuple[list[tuple[Stack, float]], str]:
    """Profile run() with pyinstrument: (stack, self seconds) per frame, and a note for the printout."""
    try:
        from pyinstrument import Profiler
        from pyinstrument.renderers import ConsoleRenderer, HTMLRenderer
    except ModuleNotFoundError:
        raise SystemExit("profiling needs pyinstrument: pip install -e '.[bench]'") from None
    interval = 1e-4
    profiler = Profiler(interval=interval)
    profiler.start()
    try:
        run()
    finally:
        session = profiler.stop()
    if out:
        renderer = (HTMLRenderer() if out.endswith(".html")
                    else ConsoleRenderer(unicode=False, color=False, show_all=False))
        Path(out).write_text(renderer.render(session), encoding="utf-8")
    stacks: list[tuple[Stack, float]] = []
    root = session.root_frame()
    todo = [(root, ())] if root is not None else []
    while todo:
        frame, above = todo.pop()
        if frame.is_synthetic:            # "[self]" and the like: time of the frame above
            stacks.append((above, frame.time))
            continue
        here = above + ((frame.function or "", frame.file_path_short or frame.file_path or ""),)
        own = frame.time - sum(child.time for child in frame.children)
        stacks.append((here, own))
        todo.extend((child, here) for child in frame.children)
    return stacks, f"pyinstrument, {interval * 1e6:g} us sampling, {session.sample_count} samples"


def _py_spy_stacks(run: Callable[[], object], out: str | None) -> tuple[list[tuple[Stack, float]], str]:
    """Profile run() with py-spy attached to this process: (stack, seconds) per sampled stack."""
    exe = shutil.which("py-spy") or str(Path(sys.executable).with_name("py-spy"))
    if not Path(exe).exists():
        raise SystemExit("profiling with py-spy needs py-spy: pip install -e '.[bench]'")
    rate = 1000
    with tempfile.TemporaryDirectory(prefix="bench-py-spy-") as tmp:
        raw = Path(out) if out else Path(tmp) / "stacks.txt"
        spy = subprocess.Popen([exe, "record", "--pid", str(os.getpid()), "--rate", str(rate), "--format",
                                "raw", "--output", str(raw)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        time.sleep(1.0)                   # let it attach
        if spy.poll() is not None:
            raise SystemExit(f"py-spy could not attach: {spy.stdout.read().decode(errors='replace')}")
        start = time.perf_counter()
        run()
        elapsed = time.perf_counter() - start
        spy.send_signal(signal.SIGINT)
        spy.communicate(timeout=60)
        lines = raw.read_text(encoding="utf-8").splitlines()
    marker = (run.__qualname__, run.__code__.co_filename) if hasattr(run, "__code__") else None
    counted: list[tuple[Stack, int]] = []
    for line in lines:
        frames, _, count = line.rpartition(" ")
        stack = tuple(_split_py_spy_frame(f) for f in frames.split(";"))
        at = [i for i, (function, path) in enumerate(stack)       # keep the samples inside run()
              if marker and function == marker[0] and marker[1].endswith(path)]
        if at:
            counted.append((stack[at[0]:], int(count)))
    samples = sum(c for _, c in counted)
    seconds = elapsed / samples if samples else 0.0
    return ([(stack, c * seconds) for stack, c in counted],
            f"py-spy, {rate} Hz, {samples} samples over {elapsed:.2f} s")


def _split_py_spy_frame(frame: str) -> tuple[str, str]:
    """'function (file.py:123)' -> ('function', 'file.py')."""
    match = _PY_SPY_FRAME.match(frame)
    return (match.group(1), match.group(2)) if match else (frame, "")



def outputs_read(hosted: Mapping[str, object], edges, scenario) -> dict[str, frozenset[str]]:
    """The outputs the run reads as `cosim run` finds them (its recorder's selection from the
    scenario's `record:`), for a benchmark's master over its own hosts to do the same work."""
    from cosim.engine.wiring import outputs_read as read
    from cosim.results.recorder import selected

    include, exclude = scenario.record.include, scenario.record.exclude
    ports = {name: (c.inputs, c.outputs) for name, c in hosted.items()}
    return read(edges, ports, lambda name: selected(name, include, exclude))
