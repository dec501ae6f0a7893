"""Tests of the FMU stepping shim (fmus/stepper, benchmarks/stepper_binding.py), no timing.

The shim must be a drop-in for the platform's per-call step: the same
outputs bit for bit over realistic varying inputs (FMI 2.0 and 3.0, both
built-in models), and the same failure, naming the same FMI call with the
same status and the FMU's log, when a call fails. The library is compiled
once per source hash into the cache folder it is given.
"""

from __future__ import annotations

import ctypes

import pytest

from benchmarks import bench_fmu_step as bench
from benchmarks import stepper_binding as binding
from cosim.errors import ComponentFailure
from tests.helpers.fmus import built_fmu


@pytest.fixture(scope="module", autouse=True)
def cache(tmp_path_factory):
    """A private cache folder for the compiled shim (COSIM_CACHE_DIR)."""
    folder = tmp_path_factory.mktemp("stepper-cache")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("COSIM_CACHE_DIR", str(folder))
        yield folder


def test_compiles_once_per_source_hash_with_the_strict_flags(cache):
    first = binding.compile_stepper()
    assert first.parent.parent == cache / "stepper"
    assert binding.compile_stepper() == first               # found, not rebuilt
    assert {"-Wall", "-Wextra", "-Wpedantic", "-Werror", "-std=c99", "-O2", "-fPIC"} <= set(binding.CFLAGS)
    lib = binding.load_stepper()
    assert lib.cosim_stepper_abi() == binding.ABI
    assert lib.cosim_stepper_size() == ctypes.sizeof(binding.CosimStepper)


@pytest.mark.parametrize("model", ["Vehicle8DOF", "Bicycle"])
@pytest.mark.parametrize("version", [2, 3])
def test_outputs_bit_identical_to_the_per_call_path(fmu_dir, model, version):
    path, _ = built_fmu(fmu_dir, model, version)
    assert bench.check_identical(path, 1500) is None


def _failure(path, shim, tick, t, inputs):
    """The ComponentFailure text of one step of a fresh host (platform or shim), stopped after."""
    host = bench.make_host(path, shim)
    try:
        with pytest.raises(ComponentFailure) as caught:
            host.step(tick, t, inputs)
    finally:
        host.stop()
    return str(caught.value)


@pytest.mark.parametrize("version", [2, 3])
def test_a_rejected_input_fails_as_the_per_call_path(fmu_dir, version):
    path, _ = built_fmu(fmu_dir, "Vehicle8DOF", version)
    bad = dict(bench.realistic_inputs(1)[0], delta=2.0)          # outside [-0.8, 0.8]
    message = _failure(path, False, 1, bench.H, bad)
    assert _failure(path, True, 1, bench.H, bad) == message
    assert ("fmi2SetReal" if version == 2 else "fmi3SetFloat64") + " failed with status 3" in message
    assert "delta" in message


@pytest.mark.parametrize("version", [2, 3])
def test_a_failed_do_step_names_do_step_and_its_status(fmu_dir, version):
    path, _ = built_fmu(fmu_dir, "Bicycle", version)
    inputs = bench.realistic_inputs(1)[0]
    message = _failure(path, False, 1, 0.0, inputs)                 # h = 0: the FMU refuses the step
    assert _failure(path, True, 1, 0.0, inputs) == message
    assert ("fmi2DoStep" if version == 2 else "fmi3DoStep") + " failed with status 3" in message
    assert "step size 0" in message


def test_failure_reports_the_call_and_status():
    class Fake:
        names = binding.CALL_NAMES[3]
        struct = binding.CosimStepper()

    stepper = Fake()
    stepper.struct.status[:] = [0, 4, -1]
    assert binding.Stepper.failure(stepper, binding.STEP_DO_STEP) == ("fmi3DoStep", 4)
    assert binding.Stepper.failure(stepper, binding.STEP_DONE) is None
    assert binding.Stepper.failure(stepper, binding.STEP_TERMINATE) is None


def test_fmi2_messages_go_to_their_own_instance(fmu_dir):
    """fmpy's logger proxy sends every FMI 2 instance's messages to the last one set up; the shim's does not."""
    path, _ = built_fmu(fmu_dir, "Bicycle", 2)
    inputs = bench.realistic_inputs(1)[0]
    alone = _failure(path, True, 1, 0.0, inputs)
    first, second = bench.make_host(path, True), bench.make_host(path, True)
    try:
        messages = []
        for host in (first, second):
            with pytest.raises(ComponentFailure) as caught:
                host.step(1, 0.0, inputs)
            messages.append(str(caught.value))
    finally:
        first.stop()
        second.stop()
    assert messages == [alone, alone]
    assert alone.count("step size 0") == 1
