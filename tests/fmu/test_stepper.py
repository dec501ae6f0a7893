"""The FMU host's stepping shim (fmus/stepper, cosim/fmu/stepper.py): a drop-in for the per-call path.

The host steps through the shim by default and through fmpy's per-call path
(three ctypes calls) when the shim cannot be built. Both must give the same
outputs bit for bit over realistic varying inputs (FMI 2.0 and 3.0, both
built-in models) and the same failure, naming the same FMI call with the same
status and the FMU's log. The library is compiled once per source key into
the cache folder. The FMI sequence after Fatal / Error and termination
requests are tested on both paths in test_fmi_sequence.py.
"""

from __future__ import annotations

import ctypes
import struct
from collections import namedtuple
from types import SimpleNamespace

import pytest

from cosim.component import Port
from cosim.engine.master import Master
from benchmarks.bench_fmu_step import realistic_inputs
from cosim.errors import ComponentFailure
from cosim.fmu import build, stepper
from cosim.fmu.host import FmuComponent
from cosim.fmu.interface import describe_fmu
from tests.helpers.fmus import built_fmu

H = 0.01
Edge = namedtuple("Edge", "src src_port dst dst_port delay")


@pytest.fixture(scope="module", autouse=True)
def cache(tmp_path_factory):
    """A private cache folder for the compiled shim (COSIM_CACHE_DIR)."""
    folder = tmp_path_factory.mktemp("stepper-cache")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("COSIM_CACHE_DIR", str(folder))
        yield folder


def make_host(path, use_shim: bool) -> FmuComponent:
    """An FmuComponent of one FMU on the step path asked for, started at t = 0."""
    host = FmuComponent("vehicle", path, describe_fmu(path), {}, 1, use_shim=use_shim)
    start = realistic_inputs(1)[0]
    host.start(0.0, {p.name: start.get(p.name, 0.0) for p in host.inputs})
    assert (host._stepper is not None) == use_shim
    return host


def _bits(outputs: dict[str, float]) -> tuple[list[str], bytes]:
    return list(outputs), struct.pack(f"{len(outputs)}d", *outputs.values())


def _assert_same_steps(first, second, ticks):
    """Step two started hosts with the same realistic inputs; every output the same bits; stop both."""
    inputs = realistic_inputs(ticks + 1)
    try:
        for k in range(1, ticks + 1):
            a, b = first.step(k, k * H, inputs[k]), second.step(k, k * H, inputs[k])
            assert _bits(a) == _bits(b), (k, a, b)
    finally:
        first.stop()
        second.stop()


def test_compiles_once_per_source_key_with_the_fmus_strict_flags(cache):
    first = stepper.compile_stepper()
    assert first.parent.parent == cache / "stepper"
    assert first.parent.name == stepper.source_key()
    assert stepper.compile_stepper() == first  # found, not rebuilt
    assert {"-Wall", "-Wextra", "-Wpedantic", "-Werror", "-std=c99", "-O2", "-fPIC"} <= set(build.CFLAGS)
    lib = stepper.load_stepper()
    assert lib.cosim_stepper_abi() == stepper.ABI
    assert lib.cosim_stepper_size() == ctypes.sizeof(stepper.CosimStepper)
    assert lib.cosim_stepper_time_offset() == stepper.CosimStepper.t.offset
    assert stepper.CosimStepper.h.offset == stepper.CosimStepper.t.offset + 8  # Stepper.times spans both


def test_the_times_view_is_the_structs_t_and_h(fmu_dir):
    """The host writes (t, h) through Stepper.times and calls cosim_stepper_step_at, which reads them."""
    path, _ = built_fmu(fmu_dir, "Bicycle", 2)
    host = make_host(path, True)
    try:
        times, struct_ = host._stepper.times, host._stepper.struct
        times[0], times[1] = 1.25, 0.01
        assert (struct_.t, struct_.h) == (1.25, 0.01)
        host.step(1, H, realistic_inputs(1)[0])
        assert (struct_.t, struct_.h) == (0.0, H)  # the step from t_prev = 0 over H
    finally:
        host.stop()


@pytest.mark.parametrize("model", ["Vehicle8DOF", "Bicycle"])
@pytest.mark.parametrize("version", [2, 3])
def test_outputs_bit_identical_to_the_per_call_path(fmu_dir, model, version):
    path, _ = built_fmu(fmu_dir, model, version)
    _assert_same_steps(make_host(path, False), make_host(path, True), 1500)


def _failure(path, use_shim, tick, t, inputs):
    """The ComponentFailure text of one step of a fresh host, stopped after."""
    host = make_host(path, use_shim)
    try:
        with pytest.raises(ComponentFailure) as caught:
            host.step(tick, t, inputs)
    finally:
        host.stop()
    return str(caught.value)


@pytest.mark.parametrize("version", [2, 3])
def test_a_rejected_input_fails_as_on_the_per_call_path(fmu_dir, version):
    path, _ = built_fmu(fmu_dir, "Vehicle8DOF", version)
    bad = dict(realistic_inputs(1)[0], delta=2.0)  # outside [-0.8, 0.8]
    message = _failure(path, False, 1, H, bad)
    assert _failure(path, True, 1, H, bad) == message
    assert ("fmi2SetReal" if version == 2 else "fmi3SetFloat64") + " failed with status 3" in message
    assert "delta" in message


@pytest.mark.parametrize("version", [2, 3])
def test_a_failed_do_step_names_do_step_and_its_status(fmu_dir, version):
    path, _ = built_fmu(fmu_dir, "Bicycle", version)
    inputs = realistic_inputs(1)[0]
    message = _failure(path, False, 1, 0.0, inputs)  # h = 0: the FMU refuses the step
    assert _failure(path, True, 1, 0.0, inputs) == message
    assert ("fmi2DoStep" if version == 2 else "fmi3DoStep") + " failed with status 3" in message
    assert "step size 0" in message


def test_failure_reports_the_call_and_status():
    class Fake:
        names = stepper.CALL_NAMES[3]
        struct = stepper.CosimStepper()

    fake = Fake()
    fake.struct.status[:] = [0, 4, -1]
    assert stepper.Stepper.failure(fake, stepper.STEP_DO_STEP) == ("fmi3DoStep", 4)
    assert stepper.Stepper.failure(fake, stepper.STEP_DONE) is None
    assert stepper.Stepper.failure(fake, stepper.STEP_TERMINATE) is None


def test_fmi2_messages_go_to_their_own_instance(fmu_dir):
    """fmpy's logger proxy sends every FMI 2 instance's messages to the last one set up; the shim's does not."""
    path, _ = built_fmu(fmu_dir, "Bicycle", 2)
    inputs = realistic_inputs(1)[0]
    alone = _failure(path, True, 1, 0.0, inputs)
    first, second = make_host(path, True), make_host(path, True)
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


def test_without_a_compiler_the_host_keeps_the_per_call_path(fmu_dir, tmp_path, monkeypatch):
    path, _ = built_fmu(fmu_dir, "Vehicle8DOF", 2)
    inputs = realistic_inputs(201)
    with_shim = make_host(path, True)
    monkeypatch.setenv("COSIM_CACHE_DIR", str(tmp_path))  # no shim built there yet
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))  # and no gcc to build one
    with pytest.raises(stepper.StepperBuildError, match="gcc not found"):
        stepper.compile_stepper()
    assert stepper.library() is None
    without = FmuComponent("vehicle", path, describe_fmu(path), {}, 1)  # use_shim left at True
    without.start(0.0, {p.name: inputs[0].get(p.name, 0.0) for p in without.inputs})
    assert without._stepper is None
    _assert_same_steps(without, with_shim, 200)


class Driver:
    """A host giving the plant's inputs from realistic_inputs (mapping lane)."""

    def __init__(self, names):
        self.name, self.period_ticks = "driver", 1
        self.inputs, self.outputs = (), tuple(Port(n) for n in names)
        self.rows = realistic_inputs(401)

    def start(self, t0, inputs):
        return {p.name: self.rows[0][p.name] for p in self.outputs}

    def step(self, tick, t, inputs):
        return {p.name: self.rows[tick][p.name] for p in self.outputs}

    def stop(self):
        return {}


@pytest.mark.parametrize("version", [2, 3])
def test_in_the_master_the_fmu_steps_on_the_values_lane_with_the_same_bits(fmu_dir, version):
    path, _ = built_fmu(fmu_dir, "Vehicle8DOF", version)
    stores = {}
    for use_shim, trace in ((True, False), (True, True), (False, False)):
        plant = FmuComponent("vehicle", path, describe_fmu(path), {}, 1, use_shim=use_shim)
        names = [p.name for p in plant.inputs]
        edges = [Edge("driver", n, "vehicle", n, 0) for n in names]
        rows = []
        watch = SimpleNamespace(begin=lambda master: None,
                                after_tick=lambda k, t, values, arrays: rows.append(list(values)))
        master = Master({"driver": Driver(names), "vehicle": plant}, edges, H, 400,
                        observers=[watch], trace=trace)
        assert next(p.step_values for p in master._plans if p.name == "vehicle") is not None
        # (trace=True takes the mapping lane, to record the inputs)
        try:
            master.run()
        finally:
            master.stop_all()
        stores[use_shim, trace] = struct.pack(f"{sum(map(len, rows))}d", *(v for r in rows for v in r))
    assert stores[True, False] == stores[True, True] == stores[False, False]
