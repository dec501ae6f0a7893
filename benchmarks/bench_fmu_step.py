"""Cost of one 10 ms co-simulation step of each built-in FMU through fmpy.

For every model and FMI version, times the sequence a master does per tick
(set the 5 inputs, doStep, get all outputs) and prints it next to the same
sequence on a do-nothing FMU built here with the same variable table (so the
fmpy call overhead and the framework's checks are identical and only the
physics differs). Real and null run in alternating blocks; the minimum over
the repeats is printed, in microseconds, with the ratio physics / overhead,
and, as a cross-check, the cost of the model's do_step alone timed in C.

Usage: .venv/bin/python benchmarks/bench_fmu_step.py [--steps N] [--repeats R]
"""
from __future__ import annotations

import argparse
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import fmpy
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

try:
    from cosim.fmu import build as fmu_build
except ModuleNotFoundError:  # run as a script from a checkout without installing
    import sys
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
    from cosim.fmu import build as fmu_build

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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=500, help="ticks per timed block")
    parser.add_argument("--repeats", type=int, default=30,
                        help="blocks per FMU, alternating real/null (minimum is shown)")
    args = parser.parse_args()
    print(f"one {H * 1000:.0f} ms step through fmpy: set {len(INPUTS)} inputs + doStep + "
          f"get outputs; min of {args.repeats} x {args.steps} ticks")
    print(f"{'FMU':22s} {'step us':>8s} {'null us':>8s} {'step-null':>10s} "
          f"{'C-loop us':>10s} {'step/null':>10s} {'C-loop/null':>12s}")
    with tempfile.TemporaryDirectory(prefix="bench-fmu-") as tmp:
        work = Path(tmp)
        for model in fmu_build.MODELS:
            c_loop = physics_in_c(model, work)
            for version in (2, 3):
                real = fmu_build.build_fmu(model, version, work / "real")
                null = build_null_twin(model, version, work)
                t_real, t_null = compare(real, null, work, args.steps, args.repeats)
                phys = t_real - t_null
                print(f"{real.name:22s} {t_real:8.2f} {t_null:8.2f} {phys:10.2f} "
                      f"{c_loop:10.2f} {t_real / t_null:10.2f} {c_loop / t_null:12.2f}")
    print("null = same fmpy calls on a do-nothing twin FMU with the same variables (the "
          "overhead);\nstep-null = physics seen through fmpy (noisy on a shared machine); "
          "C-loop = MODEL.do_step\nalone in a C loop (the physics, no fmpy, no runtime checks); "
          "C-loop/null = physics / overhead.")


if __name__ == "__main__":
    main()
