"""Our master against libcosim (the Open Simulation Platform's C++ master) on one FMU.

The Vehicle8DOF FMU (FMI 2.0, built here into a temporary folder) runs alone
for N steps of 10 ms with constant inputs, the same .fmu file in every case:

- master: `cosim.engine.master.Master` over a `cosim.fmu.host.FmuComponent`,
  as `cosim run --transport inproc` hosts an FMU; the constant inputs are the
  defaults of its unconnected inputs; without and with the `Recorder`
  writing signals.csv;
- libcosim: `libcosimpy` execution with the FMU as a local slave, fixed step
  10 ms, inputs set as initial values, `simulate_until` (all in C++), with a
  last-value observer (reads every variable each step, as our master reads
  every output) and without any observer (stepping only);
- direct: the FMU's own C functions called from a plain Python loop (set
  inputs, doStep, get outputs; no master): the floor for a Python-driven step.

Only the steps after the first are timed (instantiation and initialization
are not). The cases alternate over the repeats; min and median are printed
in microseconds per step, then the speed-up libcosim / master against the
DESIGN.md target (the master at least 2 times faster).

Honesty checks, before any figure is trusted: libcosim calls
doStep(t_{k-1}, t_k - t_{k-1}) with t_k = k * 10^7 ns / 10^9, so the direct
loop, given that time arithmetic, must end in a final state identical to
libcosim's bit for bit; the master (t_k = k * 0.01) must agree with it to
1e-9 relative; every repeat of a case must end in the same state. A failed
check exits with status 1. If libcosimpy is missing or cannot load the FMU
(libcosim reads FMI 1.0 and 2.0 only: try --fmi 3), the reason is printed
and the exit status is 0.

Run: .venv/bin/python benchmarks/bench_vs_libcosim.py [--steps 5000] [--repeats 9] [--fmi 2]
Needs: pip install libcosimpy (the `bench` extra).
"""

from __future__ import annotations

import argparse
import ctypes
import dataclasses
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.common import interleaved, min_and_median  # noqa: E402
from cosim.fmu import build as fmu_build  # noqa: E402
from cosim.fmu.host import FmuComponent  # noqa: E402
from cosim.fmu.interface import describe_fmu  # noqa: E402
from cosim.engine.master import Master  # noqa: E402
from cosim.results.recorder import Recorder  # noqa: E402

MODEL = "Vehicle8DOF"
H_NS = 10_000_000  # the step, in libcosim's integer nanoseconds
H = H_NS / 1e9
INPUTS = {"delta": 0.01, "torque": 150.0, "wind_fx": 0.0, "wind_fy": 100.0, "mu": 1.0}
TARGET_SPEEDUP = 2.0
AGREEMENT = 1e-9  # master vs libcosim, relative to max(1, |value|)

State = dict[str, float]


class LibcosimUnavailable(Exception):
    """libcosimpy is not installed or libcosim cannot run the FMU; the message says why."""


def load_libcosim() -> Any:
    """Import libcosimpy (quiet logging); returns a namespace with the classes used here.

    Raises:
        LibcosimUnavailable: with the import error.
    """
    try:
        from libcosimpy import CosimLogging
        from libcosimpy._internal import get_last_error_message
        from libcosimpy.CosimExecution import CosimExecution
        from libcosimpy.CosimObserver import CosimObserver
        from libcosimpy.CosimSlave import CosimLocalSlave
    except (ImportError, OSError) as exc:
        raise LibcosimUnavailable(f"libcosimpy cannot be imported ({exc}); install it with "
                                  "`.venv/bin/pip install libcosimpy`") from exc
    CosimLogging.log_output_level(CosimLogging.CosimLogLevel.WARNING)
    return argparse.Namespace(Execution=CosimExecution, Observer=CosimObserver,
                              LocalSlave=CosimLocalSlave, last_error=get_last_error_message)


def run_libcosim(lib: Any, fmu: Path, outputs: Sequence[str], steps: int,
                 observe: bool = True) -> tuple[float, State | None]:
    """One libcosim execution of `fmu` alone for `steps` steps of H with INPUTS held.

    Args:
        lib: what `load_libcosim` returned.
        fmu: the .fmu file; outputs: output names to read at the end.
        steps: total steps (>= 2; the first, which initializes, is not timed).
        observe: attach a last-value observer (needed to read the final state).
    Returns:
        (seconds per timed step, final outputs or None without observer).
    Raises:
        LibcosimUnavailable: libcosim rejects the FMU or a call, with its message.
    """
    slave = lib.LocalSlave(str(fmu), "vehicle")
    if not slave.ptr():
        raise LibcosimUnavailable(f"libcosim cannot load {fmu.name}: {lib.last_error()}")
    execution = lib.Execution.from_step_size(H_NS)
    index = execution.add_local_slave(slave)
    if index < 0:
        raise LibcosimUnavailable(f"libcosim cannot add {fmu.name}: {lib.last_error()}")
    observer = lib.Observer.create_last_value() if observe else None
    if observer is not None:
        execution.add_observer(observer)
    refs = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
    for name, value in INPUTS.items():
        if not execution.real_initial_value(index, refs[name], value):
            raise LibcosimUnavailable(f"libcosim: setting {name} = {value}: {lib.last_error()}")
    if not execution.step(1):
        raise LibcosimUnavailable(f"libcosim: first step of {fmu.name}: {lib.last_error()}")
    start = time.perf_counter()
    done = execution.simulate_until(steps * H_NS)
    elapsed = time.perf_counter() - start
    if not done:
        raise LibcosimUnavailable(f"libcosim: simulate_until failed: {lib.last_error()}")
    final = None
    if observer is not None:
        final = dict(zip(outputs, observer.last_real_values(index, [refs[n] for n in outputs])))
    return elapsed / (steps - 1), final


def run_master(fmu: Path, interface: Any, steps: int,
               record_dir: Path | None = None) -> tuple[float, State]:
    """Our master over the FMU alone, its inputs held at INPUTS (unconnected-input defaults).

    Args:
        fmu: the .fmu file; interface: `describe_fmu(fmu)`.
        steps: total ticks (>= 2; tick 1 is not timed).
        record_dir: when given, a Recorder writes signals.csv there.
    Returns:
        (seconds per timed tick, final outputs).
    """
    component = FmuComponent("vehicle", fmu, interface, {}, 1)
    component.inputs = tuple(dataclasses.replace(p, default=INPUTS[p.name])
                             for p in component.inputs)
    recorder = Recorder(record_dir) if record_dir is not None else None
    master = Master({"vehicle": component}, [], H, steps,
                    observers=[recorder] if recorder else [])
    try:
        master.initialize()
        master.step_tick(1)
        start = time.perf_counter()
        for k in range(2, steps + 1):
            master.step_tick(k)
        elapsed = time.perf_counter() - start
        final = {p.name: master.value("vehicle", p.name) for p in component.outputs}
    finally:
        master.stop_all()
        if recorder is not None:
            recorder.close()
    return elapsed / (steps - 1), final


def run_direct(fmu: Path, interface: Any, steps: int, work: Path) -> tuple[float, State]:
    """A plain Python loop over the FMU's C functions (FMI 2.0), with libcosim's time arithmetic.

    Args:
        fmu: the .fmu file (FMI 2.0); interface: `describe_fmu(fmu)`.
        steps: total steps (>= 2; the first is not timed); work: folder to unzip into.
    Returns:
        (seconds per timed step, final outputs).
    """
    from fmpy import extract
    from fmpy.fmi2 import FMU2Slave

    md = interface.model_description
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu), unzipdir=str(work)),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="vehicle")
    slave.instantiate()
    vrs = interface.value_references
    outputs = [p.name for p in interface.outputs]
    in_vr = (ctypes.c_uint * len(INPUTS))(*[vrs[n] for n in INPUTS])
    in_val = (ctypes.c_double * len(INPUTS))(*INPUTS.values())
    out_vr = (ctypes.c_uint * len(outputs))(*[vrs[n] for n in outputs])
    out_val = (ctypes.c_double * len(outputs))()
    try:
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.setReal(list(in_vr), list(in_val))
        slave.exitInitializationMode()
        step = _direct_stepper(slave, in_vr, in_val, out_vr, out_val)
        step(1)
        start = time.perf_counter()
        for k in range(2, steps + 1):
            step(k)
        elapsed = time.perf_counter() - start
        return elapsed / (steps - 1), dict(zip(outputs, out_val[:]))
    finally:
        slave.terminate()
        slave.freeInstance()


def _direct_stepper(slave: Any, in_vr: Any, in_val: Any, out_vr: Any,
                    out_val: Any) -> Callable[[int], None]:
    """step(k): set inputs, doStep from t_{k-1} to t_k (t in integer ns as libcosim), get outputs."""
    functions, comp = slave._functions, slave.component  # raw C functions, fmpy's argtypes
    set_real, do_step, get_real = (functions["fmi2SetReal"], functions["fmi2DoStep"],
                                   functions["fmi2GetReal"])
    n_in, n_out = len(in_vr), len(out_vr)

    def step(k: int) -> None:
        t_prev, t = (k - 1) * H_NS / 1e9, k * H_NS / 1e9
        status = (set_real(comp, in_vr, n_in, in_val) or do_step(comp, t_prev, t - t_prev, 1)
                  or get_real(comp, out_vr, n_out, out_val))
        if status:
            raise RuntimeError(f"direct loop: FMI status {status} at step {k}")
    return step


def max_difference(a: State, b: State) -> tuple[float, float]:
    """(max |a - b|, max |a - b| / max(1, |b|)) over the outputs of b."""
    diffs = [(abs(a[n] - b[n]), abs(a[n] - b[n]) / max(1.0, abs(b[n]))) for n in b]
    return max(d for d, _ in diffs), max(r for _, r in diffs)


MASTER = "master (Master + FmuComponent)"
RECORDED = "master + recorder (signals.csv)"
LIBCOSIM = "libcosim (last-value observer)"
LIBCOSIM_BARE = "libcosim (no observer)"
DIRECT = "direct C calls from Python, no master"


def make_cases(lib: Any, fmu: Path, interface: Any, steps: int, work: Path,
               finals: dict[str, list[State]]) -> dict[str, Callable[[], float]]:
    """The timed cases: label -> callable returning seconds per step (final states go to `finals`).

    Args:
        lib: `load_libcosim()`; fmu, interface: the FMU and `describe_fmu(fmu)`;
        steps: steps per run; work: scratch folder; finals: label -> final states, appended.
    """
    outputs = [p.name for p in interface.outputs]

    def keep(label: str, result: tuple[float, State | None]) -> float:
        seconds, state = result
        if state is not None:
            finals.setdefault(label, []).append(state)
        return seconds

    return {
        MASTER: lambda: keep(MASTER, run_master(fmu, interface, steps)),
        RECORDED: lambda: keep(RECORDED, run_master(fmu, interface, steps,
                                                    Path(tempfile.mkdtemp(dir=work)))),
        LIBCOSIM: lambda: keep(LIBCOSIM, run_libcosim(lib, fmu, outputs, steps)),
        LIBCOSIM_BARE: lambda: keep(LIBCOSIM_BARE, run_libcosim(lib, fmu, outputs, steps,
                                                                observe=False)),
        DIRECT: lambda: keep(DIRECT, run_direct(fmu, interface, steps,
                                                Path(tempfile.mkdtemp(dir=work)))),
    }


def check_finals(finals: dict[str, list[State]]) -> list[str]:
    """Problems that make the comparison dishonest (empty when all is well).

    Args:
        finals: label -> final state of every repeat (MASTER, RECORDED, LIBCOSIM, DIRECT).
    """
    problems = [f"{label}: the repeats ended in different states"
                for label, states in finals.items() if any(s != states[0] for s in states)]
    reference = finals[LIBCOSIM][0]
    if finals[DIRECT][0] != reference:
        worst = max_difference(finals[DIRECT][0], reference)[0]
        problems.append(f"{DIRECT} with libcosim's time arithmetic differs from libcosim "
                        f"(max |diff| {worst:.3g}): the two do not run the same FMU calls")
    for label in (MASTER, RECORDED):
        worst, relative = max_difference(finals[label][0], reference)
        if relative > AGREEMENT:
            problems.append(f"{label} disagrees with libcosim: max |diff| {worst:.3g}, "
                            f"relative {relative:.3g} > {AGREEMENT:g}")
    return problems


def print_report(samples: dict[str, list[float]], finals: dict[str, list[State]]) -> None:
    """Print the timing table, the state cross-check and the speed-up against the target.

    Args:
        samples: label -> seconds per step of every repeat; finals: as for `check_finals`.
    """
    best = {label: min_and_median(values)[0] * 1e6 for label, values in samples.items()}
    print(f"{'case':<42}{'us/step min':>12}{'median':>10}")
    for label, values in samples.items():
        low, mid = min_and_median(values)
        print(f"{label:<42}{low * 1e6:>12.2f}{mid * 1e6:>10.2f}")
    reference = finals[LIBCOSIM][0]
    worst, relative = max_difference(finals[MASTER][0], reference)
    print(f"final state: libcosim vx = {reference['vx']!r} m/s, x = {reference['x']!r} m; "
          f"direct loop == libcosim bit for bit; master vs libcosim max |diff| {worst:.2g} "
          f"(relative {relative:.2g}; the master's t_k = k*0.01 s, libcosim's k*1e7 ns)")
    print(f"speed-up = libcosim us / master us (min){'vs observer':>16}{'vs bare':>10}")
    for label in (MASTER, RECORDED):
        print(f"{label:<42}{best[LIBCOSIM] / best[label]:>14.2f}"
              f"{best[LIBCOSIM_BARE] / best[label]:>10.2f}")
    speedup = best[LIBCOSIM] / best[MASTER]
    verdict = "holds" if speedup >= TARGET_SPEEDUP else "NOT MET"
    print(f"target (DESIGN.md): master at least {TARGET_SPEEDUP:g}x faster per step than libcosim: "
          f"{verdict} ({speedup:.2f}x against libcosim with observer)")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the comparison; returns the exit status (0 also when libcosim is unavailable).

    Args:
        argv: command-line arguments (default: sys.argv[1:]).
    """
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=5000, help="steps of 10 ms per run (>= 2)")
    parser.add_argument("--repeats", type=int, default=9, help="alternating runs of each case")
    parser.add_argument("--fmi", type=int, choices=(2, 3), default=2, help="FMI version of the FMU")
    args = parser.parse_args(argv)
    if args.steps < 2 or args.repeats < 1:
        parser.error(f"--steps must be >= 2 and --repeats >= 1, got {args.steps}, {args.repeats}")
    try:
        lib = load_libcosim()
    except LibcosimUnavailable as exc:
        print(f"libcosim comparison not run: {exc}")
        return 0
    with tempfile.TemporaryDirectory(prefix="bench-libcosim-") as tmp:
        work = Path(tmp)
        fmu = fmu_build.build_fmu(MODEL, args.fmi, work / "fmu")
        interface = describe_fmu(fmu)
        finals: dict[str, list[State]] = {}
        try:
            run_libcosim(lib, fmu, [p.name for p in interface.outputs], 2)  # can it run at all?
            samples = interleaved(make_cases(lib, fmu, interface, args.steps, work, finals),
                                  args.repeats)
        except LibcosimUnavailable as exc:
            print(f"libcosim comparison not run: {exc}")
            return 0
    print(f"{fmu.name} (FMI {args.fmi}.0) alone, {args.steps} steps of {H * 1e3:g} ms, inputs "
          f"held at {INPUTS}; min and median of {args.repeats} alternating runs; "
          f"libcosimpy {_version('libcosimpy')}")
    problems = check_finals(finals)
    for problem in problems:
        print(f"CHECK FAILED: {problem}")
    if problems:
        return 1
    print_report(samples, finals)
    return 0


def _version(package: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(package)
    except PackageNotFoundError:
        return "?"


if __name__ == "__main__":
    sys.exit(main())
