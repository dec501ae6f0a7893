"""Tests of the shared C FMI framework and the FMU build (cosim/fmu/build.py):
validation by fmpy, modelDescription against the variable table, exported
symbols, self-contained sources, call-sequence errors, range checks, reset,
FMU state save/restore/serialization, FMI2 vs FMI3, build errors, ensure_fmu.
Runs on every model folder under fmus/ (Bicycle and Vehicle8DOF).
"""
from __future__ import annotations

import os
import re
import subprocess
import zipfile
from xml.etree import ElementTree
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from cosim.fmu import build as fmu_build
from tests.helpers.fmus import Plant, built_fmu, parse_variables_def

MODELS = fmu_build.MODELS
CASES = [(m, v) for m in MODELS for v in (2, 3)]
IDS = [f"{m}-fmi{v}" for m, v in CASES]
CAUSALITY = {"parameter": "parameter", "input": "input", "output": "output"}


def test_models_found():
    assert "Bicycle" in MODELS
    assert "framework" not in MODELS


@pytest.mark.parametrize("model,version", CASES, ids=IDS)
def test_fmpy_validate_reports_no_problem(fmu_dir, model, version):
    path, _ = built_fmu(fmu_dir, model, version)
    assert path.name == fmu_build.fmu_file_name(model, version)
    assert validate_fmu(str(path)) == []


@pytest.mark.parametrize("model,version", CASES, ids=IDS)
def test_simulate_fmu_matches_our_own_stepping(fmu_dir, model, version):
    """fmpy.simulate_fmu and our own stepping (fmu_fixtures.Plant) give the same trajectory."""
    path, unzip = built_fmu(fmu_dir, model, version)
    inputs = {"torque": 100.0, "delta": 0.01}
    res = fmpy.simulate_fmu(str(path), stop_time=0.5, output_interval=0.01, start_values=inputs)
    assert len(res) == 51
    assert res["vx"][-1] > res["vx"][0] and res["r"][-1] > 0.0  # drives; positive steer turns left
    plant = Plant(path, unzip)
    try:
        plant.init(inputs)
        out = plant.run({}, 50)
    finally:
        plant.free()
    for name in plant.outputs:
        np.testing.assert_allclose(res[name], plant.column(out, name), rtol=1e-13, atol=1e-13,
                                   err_msg=name)  # not bitwise: fmpy steps by (k+1) h - k h, we by h


@pytest.mark.parametrize("model,version", CASES, ids=IDS)
def test_model_description_matches_variable_table(fmu_dir, model, version):
    path, _ = built_fmu(fmu_dir, model, version)
    table = parse_variables_def(fmu_build.FMUS_DIR / model / "variables.def")
    md = fmpy.read_model_description(str(path))
    variables = [v for v in md.modelVariables if v.causality != "independent"]
    assert [v.name for v in variables] == [row["name"] for row in table]
    units = {u.name for u in md.unitDefinitions}
    for vr, (v, row) in enumerate(zip(variables, table)):
        assert v.valueReference == vr, v.name
        assert v.unit == row["unit"] and v.unit in units, v.name
        assert v.causality == CAUSALITY[row["causality"]], v.name
        assert v.description == row["description"], v.name
        if row["causality"] != "output":
            assert float(v.start) == row["start"], v.name
        expect_min = None if np.isinf(row["min"]) else row["min"]
        assert (None if v.min is None else float(v.min)) == expect_min, v.name
    outputs = [u.variable.name for u in md.outputs]
    assert outputs == [r["name"] for r in table if r["causality"] == "output"]
    if version == 3:
        (time_var,) = [v for v in md.modelVariables if v.causality == "independent"]
        assert time_var.name == "time" and time_var.unit == "s"


@pytest.mark.parametrize("model,version", CASES, ids=IDS)
def test_only_fmi_api_is_exported(fmu_dir, model, version):
    path, unzip = built_fmu(fmu_dir, model, version)
    (lib,) = Path(unzip, "binaries").glob("*/*.so")
    out = subprocess.run(["nm", "-D", "--defined-only", str(lib)], capture_output=True,
                         text=True, check=True).stdout
    names = [line.split()[-1] for line in out.splitlines() if line.strip()]
    prefix = f"fmi{version}"
    assert names and all(n.startswith(prefix) for n in names), names
    header = (fmu_build.fmi_include_dir() / f"fmi{version}Functions.h").read_text()
    declared = set(re.findall(rf"FMI{version}_Export\s+\w+TYPE\s+({prefix}\w+);", header))
    if version == 2:  # Model Exchange functions are not required in a co-simulation FMU
        me_only = {"fmi2EnterEventMode", "fmi2NewDiscreteStates", "fmi2EnterContinuousTimeMode",
                   "fmi2CompletedIntegratorStep", "fmi2SetTime", "fmi2SetContinuousStates",
                   "fmi2GetDerivatives", "fmi2GetEventIndicators", "fmi2GetContinuousStates",
                   "fmi2GetNominalsOfContinuousStates"}
        declared -= me_only
    assert len(declared) > 30 and declared <= set(names), sorted(declared - set(names))


@pytest.mark.parametrize("version", [2, 3])
def test_sources_in_fmu_build_standalone(fmu_dir, tmp_path, version):
    """An importer with only the FMU and the FMI headers can compile it."""
    path, _ = built_fmu(fmu_dir, "Bicycle", version)
    with zipfile.ZipFile(path) as zf:
        zf.extractall(tmp_path)
    if version == 2:
        root = ElementTree.parse(tmp_path / "modelDescription.xml").getroot()
        sources = [f.get("name") for f in root.iterfind("CoSimulation/SourceFiles/File")]
    else:
        root = ElementTree.parse(tmp_path / "sources" / "buildDescription.xml").getroot()
        sources = [f.get("name") for f in root.iter("SourceFile")]
    assert sources and "runtime.c" in sources
    lib = tmp_path / "rebuilt.so"
    subprocess.run(["gcc", *fmu_build.CFLAGS, "-shared", f"-I{fmu_build.fmi_include_dir()}",
                    *(str(tmp_path / "sources" / s) for s in sources), "-lm", "-o", str(lib)],
                   check=True, capture_output=True)
    assert lib.stat().st_size > 0


def test_build_is_deterministic(fmu_dir, tmp_path):
    path, _ = built_fmu(fmu_dir, "Bicycle", 3)
    again = fmu_build.build_fmu("Bicycle", 3, tmp_path)
    assert again.read_bytes() == path.read_bytes()


def _sample_inputs(k: int) -> dict[str, float]:
    return {"delta": 0.03 * np.sin(0.05 * k), "torque": 300.0 * np.cos(0.03 * k),
            "wind_fy": 200.0 if k > 50 else 0.0, "mu": 0.8}


@pytest.mark.parametrize("model", MODELS)
def test_fmi2_and_fmi3_give_identical_trajectories(fmu_dir, model):
    runs = []
    for version in (2, 3):
        plant = Plant(*built_fmu(fmu_dir, model, version))
        plant.init({"vx0": 8.0})
        runs.append(plant.run(_sample_inputs, 200))
        plant.free()
    assert np.array_equal(runs[0], runs[1])


@pytest.mark.parametrize("model,version", CASES, ids=IDS)
def test_reset_and_fmu_state_reproduce_bit_for_bit(fmu_dir, model, version):
    plant = Plant(*built_fmu(fmu_dir, model, version))
    plant.init({"vx0": 8.0})
    first = plant.run(_sample_inputs, 60)
    state = plant.get_state()
    rest = plant.run(_sample_inputs, 60, k0=60)
    plant.set_state(state)
    assert np.array_equal(plant.run(_sample_inputs, 60, k0=60), rest)
    restored = plant.deserialize(plant.serialize(state))
    plant.set_state(restored)
    assert np.array_equal(plant.run(_sample_inputs, 60, k0=60), rest)
    plant.fmu.reset()
    plant.init({"vx0": 8.0})
    again = plant.run(_sample_inputs, 120)
    assert np.array_equal(again, np.vstack([first, rest[1:]]))
    plant.free()


@pytest.mark.parametrize("model,version", CASES, ids=IDS)
def test_do_step_before_initialization_fails_cleanly(fmu_dir, model, version):
    plant = Plant(*built_fmu(fmu_dir, model, version))
    with pytest.raises(FMICallException, match="DoStep"):
        plant.do_step(0.0, 0.01)
    assert any("before initialization" in m for m in plant.messages), plant.messages
    plant.fmu.reset()  # the instance is usable again after reset
    plant.init()
    plant.do_step(0.0, 0.01)
    plant.free()


@pytest.mark.parametrize("model,version", CASES, ids=IDS)
def test_invalid_parameter_fails_initialization_with_message(fmu_dir, model, version):
    plant = Plant(*built_fmu(fmu_dir, model, version))
    plant.set({"m": -1500.0})
    with pytest.raises(FMICallException, match="ExitInitializationMode"):
        plant.init()
    assert any("parameter m = -1500" in m and "outside" in m for m in plant.messages), \
        plant.messages
    plant.fmu.freeInstance()


@pytest.mark.parametrize("version", [2, 3])
def test_bad_set_calls_fail_with_message(fmu_dir, version):
    cases = [({"delta": 2.0}, "input delta = 2 is outside"),
             ({"torque": float("nan")}, "torque = nan is not finite"),
             ({"vx": 1.0}, "vx is an output"),
             ({"m": 1000.0}, "fixed parameter m")]
    for values, text in cases:
        plant = Plant(*built_fmu(fmu_dir, "Bicycle", version))
        plant.init()
        plant.do_step(0.0, 0.01)
        with pytest.raises(FMICallException):
            plant.set(values)
        assert any(text in m for m in plant.messages), (text, plant.messages)
        with pytest.raises(FMICallException):  # the instance is now in error
            plant.do_step(0.01, 0.01)
        plant.fmu.freeInstance()


@pytest.mark.parametrize("version", [2, 3])
def test_debug_messages_only_when_logging_is_on(fmu_dir, version):
    for logging_on in (False, True):
        plant = Plant(*built_fmu(fmu_dir, "Bicycle", version), logging_on=logging_on)
        plant.init()
        plant.fmu.reset()
        expected = ["Bicycle initialized at t = 0", "Bicycle reset to its start values"]
        assert plant.messages == (expected if logging_on else [])
        plant.fmu.freeInstance()


@pytest.mark.parametrize("version", [2, 3])
def test_wrong_communication_point_fails(fmu_dir, version):
    plant = Plant(*built_fmu(fmu_dir, "Bicycle", version))
    plant.init()
    with pytest.raises(FMICallException):
        plant.do_step(0.5, 0.01)
    assert any("differs from the FMU time" in m for m in plant.messages)
    plant.fmu.freeInstance()


def test_fmi3_time_variable_and_unknown_value_reference(fmu_dir):
    plant = Plant(*built_fmu(fmu_dir, "Bicycle", 3))
    plant.init(t0=2.0)
    plant.run({}, 3, k0=200)
    assert plant.fmu.getFloat64([plant.vr["time"]]) == [202 * 0.01 + 0.01]  # t_k + h
    with pytest.raises(FMICallException):
        plant.fmu.getFloat64([999])
    assert any("unknown value reference 999" in m for m in plant.messages)
    plant.fmu.freeInstance()


def test_outputs_readable_in_initialization_mode(fmu_dir):
    plant = Plant(*built_fmu(fmu_dir, "Bicycle", 2))
    plant.set({"vx0": 12.0, "x0": 5.0})
    plant.fmu.setupExperiment(startTime=0.0)
    plant.fmu.enterInitializationMode()
    assert plant.get(["vx", "x", "omega_fl"]) == [12.0, 5.0, 12.0 / 0.3]
    plant.fmu.exitInitializationMode()
    plant.free()


def _model_dir(tmp_path: Path, model_c: str, unit: str = "m", variability="FIXED") -> Path:
    model_dir = tmp_path / "Broken"
    model_dir.mkdir()
    (model_dir / "variables.def").write_text(
        f'VAR(a, PARAMETER, {variability}, "{unit}", 1.0, 0.0, 2.0, "a")\n'
        'VAR(b, OUTPUT, CONTINUOUS, "m", 0.0, -INFINITY, INFINITY, "b")\n')
    (model_dir / "model.c").write_text(model_c)
    return model_dir


GOOD_MODEL_C = """
#include <math.h>
#include "model.h"
#include "variable_table.h"
static const VariableInfo VARIABLES[] = {
#define VAR MODEL_VARIABLE_TABLE_ROW
#include "variables.def"
#undef VAR
};
static ModelStatus init(double *v, void *s, double t0, const ModelLogger *l)
{ (void)s; (void)t0; (void)l; v[VR_b] = v[VR_a]; return MODEL_OK; }
static ModelStatus step(double *v, void *s, double t, double h, const ModelLogger *l)
{ (void)s; (void)t; (void)l; v[VR_b] += h; return MODEL_OK; }
const ModelDefinition MODEL = { "Broken", "{0}", "test", VARIABLES, 2, 8, 0.01,
                                NULL, init, step };
"""


def test_minimal_model_builds_and_validates(tmp_path):
    path = fmu_build.build_fmu_from(_model_dir(tmp_path, GOOD_MODEL_C), 3, tmp_path / "out")
    assert validate_fmu(str(path)) == []
    res = fmpy.simulate_fmu(str(path), stop_time=1.0, output_interval=0.25)
    np.testing.assert_allclose(res["b"], [1.0, 1.25, 1.5, 1.75, 2.0])


@pytest.mark.parametrize("version", [2, 3])
def test_tunable_parameter_is_range_checked_in_step_mode(tmp_path, version):
    path = fmu_build.build_fmu_from(_model_dir(tmp_path, GOOD_MODEL_C, variability="TUNABLE"),
                                    version, tmp_path / "out")
    assert validate_fmu(str(path)) == []
    plant = Plant(path, fmpy.extract(str(path)))
    plant.init()
    plant.set({"a": 1.5})
    assert plant.get(["a"]) == [1.5]
    with pytest.raises(FMICallException):
        plant.set({"a": 2.5})
    assert any("parameter a = 2.5 is outside its valid range [0, 2]" in m
               for m in plant.messages), plant.messages
    plant.fmu.freeInstance()


def test_compiler_error_raises_with_gcc_message(tmp_path):
    broken = GOOD_MODEL_C.replace("return MODEL_OK; }\nstatic", "return MODEL_OK }\nstatic")
    with pytest.raises(fmu_build.FmuBuildError, match=r"(?s)Broken.*gcc failed.*model\.c.*error"):
        fmu_build.build_fmu_from(_model_dir(tmp_path, broken), 2, tmp_path / "out")


def test_unused_variable_warning_is_an_error(tmp_path):
    warned = GOOD_MODEL_C.replace("{ (void)s; (void)t0;", "{ int unused; (void)s; (void)t0;")
    with pytest.raises(fmu_build.FmuBuildError, match="unused"):
        fmu_build.build_fmu_from(_model_dir(tmp_path, warned), 2, tmp_path / "out")


def test_unknown_unit_is_rejected_naming_the_variable(tmp_path):
    model_dir = _model_dir(tmp_path, GOOD_MODEL_C, unit="furlong")
    with pytest.raises(fmu_build.FmuBuildError, match="variable a: unknown unit 'furlong'"):
        fmu_build.build_fmu_from(model_dir, 3, tmp_path / "out")


def test_unknown_model_and_version_are_rejected(tmp_path):
    with pytest.raises(fmu_build.FmuBuildError, match="unknown model 'Nope'"):
        fmu_build.build_fmu("Nope", 2, tmp_path)
    with pytest.raises(fmu_build.FmuBuildError, match="fmi_version must be 2 or 3"):
        fmu_build.build_fmu("Bicycle", 1, tmp_path)
    with pytest.raises(fmu_build.FmuBuildError, match="not a built-in FMU"):
        fmu_build.ensure_fmu("Nope-fmi3", tmp_path)


def test_ensure_fmu_builds_when_missing_or_stale(tmp_path, monkeypatch):
    path = fmu_build.ensure_fmu("Bicycle-fmi3", tmp_path)  # missing: a real build
    assert path == tmp_path / "Bicycle-fmi3.fmu"
    assert fmpy.read_model_description(str(path)).fmiVersion == "3.0"
    builds = []  # from here on, record the builds ensure_fmu asks for instead of compiling
    monkeypatch.setattr(fmu_build, "build_fmu", lambda *args: builds.append(args) or path)
    assert fmu_build.ensure_fmu("Bicycle-fmi3.fmu", tmp_path) == path
    assert builds == []  # up to date: no build
    os.utime(path, (0, 0))  # older than every source: must be rebuilt
    assert fmu_build.ensure_fmu("Bicycle-fmi3", tmp_path) == path
    assert builds == [("Bicycle", 3, tmp_path)]
