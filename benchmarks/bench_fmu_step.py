"""Cost of one 10 ms co-simulation step of each built-in FMU through fmpy.

For every model and FMI version, times the sequence a master does per tick
(set the 5 inputs, doStep, get all outputs) and prints it next to the same
sequence on a do-nothing FMU built here with the same variable table (so the
fmpy call overhead and the framework's checks are identical and only the
physics differs). Real and null run in alternating blocks; the minimum over
the repeats is printed, in microseconds, with the ratio physics / overhead,
and, as a cross-check, the cost of the model's do_step alone timed in C.

Second table (`--part shim`, on by default): the platform host's per-tick
step (`cosim.fmu.host.FmuComponent.step`: held inputs from a mapping, outputs
as a dict) on its two paths: fmpy's per-call path (set + doStep + get as three
ctypes calls; what a machine without a compiler gets) against the C stepping
shim (fmus/stepper, `cosim.fmu.stepper`: one ctypes call, the default),
alternating blocks, with realistic varying inputs; first both are run side by
side for `--check-steps` ticks and their outputs must be bit-identical (exit 1
if not). Prints us per step (min and median over the repeats) and the ratio;
the `raw` columns are the calls alone (no mapping in, no dict out).

`--profile` profiles the per-tick host step of Vehicle8DOF (FMI 2.0), the
per-call path and the shim (benchmarks.common.profile_call; `--profiler
pyinstrument|py-spy`, `--profile-out FILE` keeps the first one's profile).

Usage: .venv/bin/python benchmarks/bench_fmu_step.py [--steps N] [--repeats R]
           [--part all|null|shim] [--check-steps N] [--profile] [--profiler P] [--profile-out FILE]
"""
from __future__ import annotations

import argparse
import array
import math
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import fmpy
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))   # the checkout's cosim and benchmarks

from cosim.fmu import build as fmu_build  # noqa: E402
from benchmarks.common import PROFILERS, profile_call  # noqa: E402

H = 0.01
INPUTS = {"delta": 0.01, "torque": 150.0, "wind_fx": 0.0, "wind_fy": 100.0, "mu": 1.0}

NULL_MODEL_C = """
#include <math.h>
#include "model.h"
#include "variable_table.h"
static const VariableInfo VARIABLES[] = {
#define VAR MODEL_VARIABLE_TABLE_ROW
#include "variables.def"
#undef VAR
};
static ModelStatus init(double *v, void *s, double t0, const ModelLogger *l)
{ (void)v; (void)s; (void)t0; (void)l; return MODEL_OK; }
static ModelStatus step(double *v, void *s, double t, double h, const ModelLogger *l)
{ (void)v; (void)s; (void)t; (void)h; (void)l; return MODEL_OK; }
const ModelDefinition MODEL = { "%(name)s", "{null-%(name)s}", "do-nothing twin",
    VARIABLES, VR_COUNT, 8, 0.01, NULL, init, step };
"""


C_LOOP = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "model.h"
static void show(void *e, LogLevel l, const char *c, const char *m)
{ (void)e; (void)l; (void)c; fprintf(stderr, "%s\n", m); }
static int find(const char *name)
{ for (size_t i = 0; i < MODEL.n_variables; ++i)
    if (strcmp(MODEL.variables[i].name, name) == 0) return (int)i;
  return -1; }
int main(int argc, char **argv)
{
    long n = argc > 1 ? atol(argv[1]) : 100000;
    double *v = calloc(MODEL.n_variables, sizeof *v);
    void *s = calloc(1, MODEL.state_size + 1);
    ModelLogger log = { NULL, show };
    struct timespec a, b;
    for (size_t i = 0; i < MODEL.n_variables; ++i) v[i] = MODEL.variables[i].start;
@INPUTS@
    if (MODEL.initialize(v, s, 0.0, &log)) return 1;
    clock_gettime(CLOCK_MONOTONIC, &a);
    for (long k = 0; k < n; ++k)
        if (MODEL.do_step(v, s, k * @H@, @H@, &log)) return 1;
    clock_gettime(CLOCK_MONOTONIC, &b);
    printf("%.4f\n", ((b.tv_sec - a.tv_sec) * 1e9 + (b.tv_nsec - a.tv_nsec)) / n / 1e3);
    return 0;
}
"""


def physics_in_c(model: str, work: Path, steps: int = 20000) -> float:
    """Cost of MODEL.do_step alone (one 10 ms step), timed in a C loop, in microseconds."""
    inputs = "\n".join(f'    if (find("{k}") >= 0) v[find("{k}")] = {v!r};'
                       for k, v in INPUTS.items())
    src = work / f"loop_{model}.c"
    src.write_text(C_LOOP.replace("@INPUTS@", inputs).replace("@H@", repr(H)))
    exe = work / f"loop_{model}"
    model_dir = fmu_build.FMUS_DIR / model
    fmu_build._run_gcc([*fmu_build.CFLAGS, *fmu_build._includes(model_dir), str(src),
                        str(fmu_build.FRAMEWORK_DIR / "runtime.c"),
                        *(str(p) for p in sorted(model_dir.glob("*.c"))), "-lm", "-o", str(exe)],
                       f"{model}: compiling the C timing loop")
    runs = [float(subprocess.run([str(exe), str(steps)], capture_output=True, text=True,
                                 check=True).stdout) for _ in range(9)]
    return min(runs)


def build_null_twin(model: str, version: int, work: Path) -> Path:
    """Build a do-nothing FMU with the variable table of `model`."""
    name = f"Null{model}"
    model_dir = work / name
    model_dir.mkdir(exist_ok=True)
    shutil.copy(fmu_build.FMUS_DIR / model / "variables.def", model_dir / "variables.def")
    (model_dir / "model.c").write_text(NULL_MODEL_C % {"name": name})
    return fmu_build.build_fmu_from(model_dir, version, work / "out")


def open_slave(path: Path, work: Path):
    """Instantiate and initialize an FMU; return (slave, set, get, input vrs, output vrs)."""
    md = fmpy.read_model_description(str(path))
    unzip = fmpy.extract(str(path), unzipdir=str(work / f"{path.stem}-unzip"))
    args = dict(guid=md.guid, unzipDirectory=unzip, instanceName="bench",
                modelIdentifier=md.coSimulation.modelIdentifier)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    outs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
    if md.fmiVersion.startswith("2"):
        slave = FMU2Slave(**args)
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        setter, getter = slave.setReal, slave.getReal
    else:
        slave = FMU3Slave(**args)
        slave.instantiate()
        slave.enterInitializationMode(startTime=0.0)
        setter, getter = slave.setFloat64, slave.getFloat64
    slave.exitInitializationMode()
    return slave, setter, getter, [vr[n] for n in INPUTS], outs


def time_block(slave, setter, getter, in_vrs, out_vrs, k0: int, steps: int) -> float:
    """Mean wall time of one tick over `steps` ticks from tick k0, in microseconds."""
    values = list(INPUTS.values())
    start = time.perf_counter()
    for k in range(k0, k0 + steps):
        setter(in_vrs, values)
        slave.doStep(k * H, H)
        getter(out_vrs)
    return (time.perf_counter() - start) / steps * 1e6


def compare(real: Path, null: Path, work: Path, steps: int, repeats: int) -> tuple[float, float]:
    """Time the real FMU and its null twin in alternating blocks (the machine is
    shared, so interleaving exposes both to the same load); return the minimum
    per-tick cost of each, in microseconds."""
    slaves = [open_slave(real, work), open_slave(null, work)]
    samples: list[list[float]] = [[], []]
    for rep in range(repeats):
        for i, (slave, setter, getter, in_vrs, out_vrs) in enumerate(slaves):
            samples[i].append(time_block(slave, setter, getter, in_vrs, out_vrs,
                                         rep * steps, steps))
    for slave, *_ in slaves:
        slave.terminate()
        slave.freeInstance()
    return min(samples[0]), min(samples[1])


def realistic_inputs(count: int) -> list[dict[str, float]]:
    """`count` ticks of varying plant inputs: steering and torque sweeps, gusts, a friction change."""
    rows = []
    for k in range(count):
        t = k * H
        rows.append({"delta": 0.04 * math.sin(0.6 * t) + 0.01 * math.sin(3.1 * t),
                     "torque": 150.0 + 400.0 * math.sin(0.25 * t),
                     "wind_fx": -80.0 * math.cos(0.3 * t),
                     "wind_fy": 250.0 * math.sin(0.9 * t) ** 3,
                     "mu": 0.85 + 0.15 * math.cos(0.05 * t)})
    return rows


def make_host(path: Path, shim: bool):
    """The platform's FmuComponent of one FMU on the shim (or fmpy's per-call) path, started at t = 0."""
    from cosim.fmu.host import FmuComponent
    from cosim.fmu.interface import describe_fmu

    interface = describe_fmu(path)
    host = FmuComponent("vehicle", path, interface, {}, 1, use_shim=shim)
    start = realistic_inputs(1)[0]
    host.start(0.0, {p.name: start.get(p.name, 0.0) for p in host.inputs})
    if (host._stepper is not None) != shim:
        sys.exit("the stepping shim could not be built (is gcc on PATH?)")
    return host


def host_pair(path: Path):
    """(per-call FmuComponent, shim FmuComponent) of one FMU, both started at t = 0."""
    return make_host(path, False), make_host(path, True)


def check_identical(path: Path, steps: int) -> str | None:
    """Step the per-call host and the shim host side by side; None if every output is bit-identical."""
    inputs = realistic_inputs(steps + 1)
    per_call, shim = host_pair(path)
    try:
        for k in range(1, steps + 1):
            a, b = per_call.step(k, k * H, inputs[k]), shim.step(k, k * H, inputs[k])
            if list(a) != list(b) or array.array("d", a.values()).tobytes() != array.array("d", b.values()).tobytes():
                diff = {n: (a[n], b.get(n)) for n in a if a[n] != b.get(n)}
                return f"{path.name}: outputs differ at tick {k}: {diff}"
    finally:
        per_call.stop()
        shim.stop()
    return None


def time_hosts(path: Path, steps: int, repeats: int) -> dict[str, list[float]]:
    """us per step of each way, alternating blocks of `steps` ticks: host steps and raw calls."""
    inputs = realistic_inputs(steps)
    per_call, shim = host_pair(path)
    tick = [0]

    def host_block(host) -> float:
        k0 = tick[0]
        step = host.step
        start = time.perf_counter()
        for j in range(steps):
            k = k0 + j + 1
            step(k, k * H, inputs[j])
        return (time.perf_counter() - start) / steps * 1e6

    def raw_per_call(host) -> float:           # FmuComponent's bound calls, as its step makes them
        in_val, out_val, values = host._in_val, host._out_val, [list(row.values()) for row in inputs]
        raw_set, do_step, raw_get = host._raw_set, host._do_step, host._raw_get
        t_prev = host._t_prev
        start = time.perf_counter()
        for j in range(steps):
            t = (tick[0] + j + 1) * H
            in_val[:] = values[j]
            if raw_set() > 1 or do_step(t_prev, t - t_prev) > 1 or raw_get() > 1:
                raise RuntimeError("FMI call failed")
            out_val[:]
            t_prev = t
        host._t_prev = t_prev
        return (time.perf_counter() - start) / steps * 1e6

    def raw_shim(host) -> float:
        in_val, out_val, values = host._in_val, host._out_val, [list(row.values()) for row in inputs]
        call, address, times = host._shim_call, host._shim_address, host._shim_times
        t_prev = host._t_prev
        start = time.perf_counter()
        for j in range(steps):
            t = (tick[0] + j + 1) * H
            in_val[:] = values[j]
            times[0] = t_prev
            times[1] = t - t_prev
            if call(address):
                raise RuntimeError("FMI call failed")
            out_val[:]
            t_prev = t
        host._t_prev = t_prev
        return (time.perf_counter() - start) / steps * 1e6

    cases = {"per-call": lambda: host_block(per_call), "shim": lambda: host_block(shim),
             "raw per-call": lambda: raw_per_call(per_call), "raw shim": lambda: raw_shim(shim)}
    samples: dict[str, list[float]] = {label: [] for label in cases}
    try:
        for _ in range(repeats):
            for label, case in cases.items():
                samples[label].append(case())
                if label.endswith("shim"):
                    tick[0] += steps     # both hosts have now done the same ticks
    finally:
        per_call.stop()
        shim.stop()
    return samples


def shim_table(fmus: list[Path], steps: int, repeats: int, check_steps: int) -> bool:
    """Print the per-call-vs-shim table; False if some outputs were not bit-identical."""
    print(f"\nper-tick host step: FmuComponent.step, fmpy per-call path (3 ctypes calls) vs C shim (1 call); "
          f"us per step, min / median of {repeats} x {steps} ticks; bit-identity over {check_steps} ticks")
    print(f"{'FMU':22s} {'per-call':>15s} {'shim':>15s} {'ratio':>6s} {'raw per-call':>15s} "
          f"{'raw shim':>15s} {'ratio':>6s}  outputs")
    ok = True
    for path in fmus:
        problem = check_identical(path, check_steps)
        ok = ok and problem is None
        samples = time_hosts(path, steps, repeats)
        mins = {k: min(v) for k, v in samples.items()}
        meds = {k: statistics.median(v) for k, v in samples.items()}
        cell = lambda k: f"{mins[k]:6.2f} / {meds[k]:6.2f}"   # noqa: E731
        print(f"{path.name:22s} {cell('per-call'):>15s} {cell('shim'):>15s} "
              f"{meds['per-call'] / meds['shim']:6.2f} {cell('raw per-call'):>15s} {cell('raw shim'):>15s} "
              f"{meds['raw per-call'] / meds['raw shim']:6.2f}  {'bit-identical' if problem is None else 'DIFFER'}")
        if problem:
            print(f"CHECK FAILED: {problem}")
    print("ratio = per-call / shim (medians); raw = the FMI calls alone from preallocated arrays.")
    return ok


def profile_hosts(path: Path, steps: int, profiler: str, out: str | None) -> None:
    """Profile `steps` host steps of each kind on one FMU."""
    inputs = realistic_inputs(steps)
    for label, host in zip(("per-call FmuComponent.step", "shim FmuComponent.step"), host_pair(path)):
        def loop(host=host) -> None:
            step = host.step
            for k in range(1, steps + 1):
                step(k, k * H, inputs[k - 1])

        print(f"\n{label}, {path.name}, {steps} steps:")
        try:
            profile_call(loop, units=steps, unit="step", profiler=profiler, out=out, top=12,
                         groups={"host step": lambda function, file: function == "step"
                                 and Path(file).name == "host.py"})
        finally:
            host.stop()
        out = None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=500, help="ticks per timed block")
    parser.add_argument("--repeats", type=int, default=30,
                        help="blocks per FMU, alternating real/null (minimum is shown)")
    parser.add_argument("--part", choices=("all", "null", "shim"), default="all",
                        help="null: the physics-vs-overhead table; shim: the per-call-vs-shim table")
    parser.add_argument("--check-steps", type=int, default=5000,
                        help="ticks over which per-call and shim outputs must be bit-identical")
    parser.add_argument("--profile", action="store_true",
                        help="profile the per-tick host step (per-call and shim) of Vehicle8DOF FMI 2.0")
    parser.add_argument("--profiler", choices=PROFILERS, default="pyinstrument")
    parser.add_argument("--profile-out", metavar="FILE", help="with --profile: keep the per-call path's profile")
    args = parser.parse_args()
    ok = True
    with tempfile.TemporaryDirectory(prefix="bench-fmu-") as tmp:
        work = Path(tmp)
        if args.part in ("all", "null"):
            null_table(work, args.steps, args.repeats)
        fmus = [fmu_build.build_fmu(model, version, work / "real")
                for model in ("Vehicle8DOF", "Bicycle") for version in (2, 3)]
        if args.part in ("all", "shim"):
            ok = shim_table(fmus, args.steps, args.repeats, args.check_steps)
        if args.profile or args.profile_out:
            profile_hosts(fmus[0], 100 * args.steps, args.profiler, args.profile_out)
    if not ok:
        sys.exit(1)


def null_table(work: Path, steps: int, repeats: int) -> None:
    """The physics-vs-overhead table (real FMU vs do-nothing twin through fmpy, C loop)."""
    print(f"one {H * 1000:.0f} ms step through fmpy: set {len(INPUTS)} inputs + doStep + "
          f"get outputs; min of {repeats} x {steps} ticks")
    print(f"{'FMU':22s} {'step us':>8s} {'null us':>8s} {'step-null':>10s} "
          f"{'C-loop us':>10s} {'step/null':>10s} {'C-loop/null':>12s}")
    for model in fmu_build.MODELS:
        c_loop = physics_in_c(model, work)
        for version in (2, 3):
            real = fmu_build.build_fmu(model, version, work / "real")
            null = build_null_twin(model, version, work)
            t_real, t_null = compare(real, null, work, steps, repeats)
            phys = t_real - t_null
            print(f"{real.name:22s} {t_real:8.2f} {t_null:8.2f} {phys:10.2f} "
                  f"{c_loop:10.2f} {t_real / t_null:10.2f} {c_loop / t_null:12.2f}")
    print("null = same fmpy calls on a do-nothing twin FMU with the same variables (the "
          "overhead);\nstep-null = physics seen through fmpy (noisy on a shared machine); "
          "C-loop = MODEL.do_step\nalone in a C loop (the physics, no fmpy, no runtime checks); "
          "C-loop/null = physics / overhead.")


if __name__ == "__main__":
    main()
