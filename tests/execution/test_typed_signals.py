"""Every numeric FMU variable type recorded: FMI 2 Integer, Boolean, Enumeration; FMI 3
Float32, Int8 ... UInt64, Boolean, Enumeration and arrays.

Recorded values equal what fmpy.simulate_fmu returns for the same FMU (exactly), the
manifest gives each signal's FMI type, the CSV writes integers as integers, inproc and
zenoh (and an isolated FMU) give identical files, and the type rules of connections
(`convert: float`) and of integer inputs fail with one line and the right exit code.
The FMUs: tests/fmus/Faulty (framework) and tests/fmus/Arrays (hand-written FMI 3).
"""

from __future__ import annotations

import json
import subprocess
import sys
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest

from cosim.execution.run import run_scenario
from cosim.scenario.loader import load_scenario
from tests.helpers.paths import REPO_ROOT

COSIM = Path(sys.executable).with_name("cosim")
FAULTY_OUTPUTS = ("y", "u_echo", "y_f32", "ticks", "ticks_u8", "ticks_i16", "flag", "k_twice",
                  "b_not")
ARRAY_SCALARS = ("count", "steps", "i8", "u16", "u32", "mode", "odd", "k_out")
ARRAYS = ("x", "y32", "k")


def _scenario(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(text)
    return path


def _run(tmp_path: Path, text: str, transport: str = "inproc", folder: str = "run") -> Path:
    """Run a scenario in this process; its run folder (the run must end ok)."""
    out = tmp_path / folder
    result = run_scenario(load_scenario(_scenario(tmp_path, text)), out, transport=transport)
    assert result.status == "ok", result.error
    return out


def _cli(tmp_path: Path, command: str, text: str) -> subprocess.CompletedProcess:
    args = [str(COSIM), command, str(_scenario(tmp_path, text))]
    if command == "run":
        args += ["--out", str(tmp_path / "cli-run"), "--no-figures"]
    return subprocess.run(args, cwd=REPO_ROOT, capture_output=True, text=True, timeout=120)


def _csv(path: Path) -> tuple[list[str], list[list[str]]]:
    """(header, rows as text fields) of a CSV the recorder wrote."""
    lines = path.read_text().splitlines()
    return lines[0].split(","), [line.split(",") for line in lines[1:]]


def _column(path: Path, name: str) -> list[float]:
    header, rows = _csv(path)
    return [float(row[header.index(name)]) for row in rows]


def _same_as_fmpy(got: list[float], expected: np.ndarray, fed: bool) -> bool:
    """Whether a recorded column equals fmpy's exactly. An output fed by a source (`fed`)
    differs at t0 only: the plant initializes before the source (the step order), with
    its input at its start value 0, where fmpy sets the value before initialization."""
    want = [float(v) for v in expected]
    return got[1:] == want[1:] and got[0] == (0.0 if fed else want[0])


def _fmpy(fmu: Path, outputs: tuple[str, ...], **start_values) -> np.ndarray:
    """fmpy's co-simulation of the FMU with the run's settings (0.5 s, steps of 0.1 s)."""
    return fmpy.simulate_fmu(str(fmu), stop_time=0.5, step_size=0.1, output_interval=0.1,
                             output=list(outputs), start_values=start_values)


def _enumeration_faulty(faulty: Path, target: Path) -> Path:
    """FMI 2 Faulty whose `ticks_u8` is an Enumeration (read, as an Integer, by fmi2GetInteger)."""
    with zipfile.ZipFile(faulty) as zin, zipfile.ZipFile(target, "w") as zout:
        for info in zin.infolist():
            data = zin.read(info)
            if info.filename == "modelDescription.xml":
                text = data.decode()
                items = "".join(f'<Item name="n{i}" value="{i}"/>' for i in range(8))
                text = text.replace("</UnitDefinitions>", "</UnitDefinitions><TypeDefinitions>"
                                    f'<SimpleType name="Count"><Enumeration>{items}</Enumeration>'
                                    "</SimpleType></TypeDefinitions>", 1)
                head, rest = text.split('name="ticks_u8"', 1)
                rest = rest.replace("<Integer/>", '<Enumeration declaredType="Count"/>', 1)
                data = (head + 'name="ticks_u8"' + rest).encode()
            zout.writestr(info, data)
    return target


def _faulty_scenario(fmu: Path, sources: str, connections: str, more: str = "") -> str:
    """0.5 s in ticks of 0.1 s of the Faulty FMU `plant` (no fault), the `more` components,
    sources and connections (YAML lines)."""
    return (f"name: typed\nduration: 0.5\ntick: 0.1\ncomponents:\n  plant:\n    fmu: {fmu}\n"
            f"    parameters: {{fault_time: 100}}\n{more}sources:\n{sources}"
            f"connections:\n{connections}")


CONVERTED_K = "  - {from: k.value, to: plant.k_in, convert: float}\n"


@pytest.mark.parametrize("version", [2, 3])
def test_faulty_typed_outputs_equal_fmpy_and_are_typed_in_the_manifest(
        tmp_path, faulty_fmus, version) -> None:
    fmu = faulty_fmus["Faulty", version]
    if version == 2:
        fmu = _enumeration_faulty(fmu, tmp_path / "FaultyEnum.fmu")
    out = _run(tmp_path, _faulty_scenario(fmu, "  k: {kind: constant, value: -7}\n",
                                          CONVERTED_K))
    expected = _fmpy(fmu, FAULTY_OUTPUTS, fault_time=100, k_in=-7)
    for name in FAULTY_OUTPUTS:
        assert _same_as_fmpy(_column(out / "signals.csv", f"plant.{name}"), expected[name],
                             fed=name == "k_twice"), name
    types = {name: info["type"] for name, info in
             json.loads((out / "manifest.json").read_text())["signals"].items()}
    fmi2 = {"y": "Float64", "y_f32": "Float64", "ticks": "Integer", "ticks_u8": "Enumeration",
            "ticks_i16": "Integer", "flag": "Boolean", "k_twice": "Integer", "b_not": "Boolean"}
    fmi3 = {"y": "Float64", "y_f32": "Float32", "ticks": "Int32", "ticks_u8": "UInt8",
            "ticks_i16": "Int16", "flag": "Boolean", "k_twice": "Int32", "b_not": "Boolean"}
    assert {k: types[f"plant.{k}"] for k in fmi2} == (fmi2 if version == 2 else fmi3)
    header, rows = _csv(out / "signals.csv")
    assert rows[3][header.index("plant.ticks")] == "3"  # integers as integers
    assert rows[3][header.index("plant.flag")] == "1" and rows[0][header.index("plant.b_not")] == "1"
    assert rows[1][header.index("plant.k_twice")] == "-14"  # k_in = -7 from tick 1
    assert rows[3][header.index("plant.y")] == "0.30000000000000004"  # floats as repr


ARRAYS_SCENARIO = """\
name: arrays
duration: 0.5
tick: 0.1
components:
  plant:
    fmu: {fmu}
    {isolate}
sources:
  k: {{kind: constant, value: 5}}
connections:
  - {{from: k.value, to: plant.k_in, convert: float}}
"""


def test_fmi3_typed_and_array_outputs_equal_fmpy(tmp_path, arrays_fmu) -> None:
    out = _run(tmp_path, ARRAYS_SCENARIO.format(fmu=arrays_fmu, isolate=""))
    expected = _fmpy(arrays_fmu, ARRAY_SCALARS + ARRAYS, k_in=5)
    for name in ARRAY_SCALARS:
        assert _same_as_fmpy(_column(out / "signals.csv", f"plant.{name}"), expected[name],
                             fed=name == "k_out"), name
    for name in ARRAYS:
        header, rows = _csv(out / "arrays" / f"plant.{name}.csv")
        size = int(np.prod(expected[name].shape[1:]))
        assert header == ["time"] + [f"plant.{name}[{i}]" for i in range(size)]
        got = np.array([[float(v) for v in row[1:]] for row in rows])
        assert np.array_equal(got, expected[name].reshape(len(expected), size).astype(float)), name
    _, k_rows = _csv(out / "arrays" / "plant.k.csv")
    assert k_rows[2][1:] == ["2", "4", "6", "8"]  # an Int32 array, as integers
    manifest = json.loads((out / "manifest.json").read_text())
    assert {n: manifest["signals"][f"plant.{n}"]["type"] for n in ("count", "steps", "mode", "y32", "k")} \
        == {"count": "Int64", "steps": "UInt64", "mode": "Enumeration", "y32": "Float32", "k": "Int32"}
    assert manifest["signals"]["plant.k"]["size"] == 4
    assert manifest["fmus"]["plant"]["not_recorded"] == {"label": "String"}
    assert "plant.label" not in _csv(out / "signals.csv")[0]


def test_inproc_zenoh_and_isolated_give_identical_files(tmp_path, arrays_fmu, faulty_fmus) -> None:
    closed_loop = _faulty_scenario(
        faulty_fmus["Faulty", 3], "  ref: {kind: constant, value: 4.0}\n",
        "  - plant.ticks -> ctl.y\n  - ref.value -> ctl.ref\n  - ctl.u -> plant.u\n",
        "  ctl:\n    python: tests.helpers.components:PController\n")
    runs = {(kind, transport): _run(tmp_path, text, transport, f"{kind}-{transport}")
            for kind, text in (("loop", closed_loop),
                               ("arrays", ARRAYS_SCENARIO.format(fmu=arrays_fmu, isolate="")),
                               ("isolated", ARRAYS_SCENARIO.format(fmu=arrays_fmu,
                                                                   isolate="isolate: true")))
            for transport in (("inproc", "zenoh") if kind != "isolated" else ("inproc",))}
    files = ["signals.csv", *(f"arrays/plant.{n}.csv" for n in ARRAYS)]
    for name in files:
        reference = (runs["arrays", "inproc"] / name).read_bytes()
        assert (runs["arrays", "zenoh"] / name).read_bytes() == reference, name
        assert (runs["isolated", "inproc"] / name).read_bytes() == reference, name
    loop = (runs["loop", "inproc"] / "signals.csv").read_bytes()
    assert (runs["loop", "zenoh"] / "signals.csv").read_bytes() == loop
    u = _column(runs["loop", "inproc"] / "signals.csv", "ctl.u")
    assert u == [4.0 - n for n in range(6)]  # ticks (Int32) fed a Float64 input exactly


def test_a_connection_that_is_not_exact_is_one_line_and_exit_2(tmp_path, arrays_fmu) -> None:
    text = f"""\
name: bad
duration: 0.5
tick: 0.1
components:
  plant: {{fmu: {arrays_fmu}}}
  ctl: {{python: "tests.helpers.components:PController"}}
sources:
  k: {{kind: constant, value: 5}}
connections:
  - k.value -> plant.k_in
  - plant.count -> ctl.y
  - k.value -> ctl.ref
"""
    for command in ("validate", "run"):
        done = _cli(tmp_path, command, text)
        assert done.returncode == 2, done.stderr
        assert "Traceback" not in done.stderr
        scenario = tmp_path / "s.yaml"
        assert f"{scenario}:10: connections[0]: k.value -> plant.k_in: type mismatch: a Float64 " \
               "output into an Int32 input is not an exact conversion (add convert: float to " \
               "the connection to accept it)" in done.stderr
        assert f"{scenario}:11: connections[1]: plant.count -> ctl.y: type mismatch: an Int64 " \
               "output into a Float64 input" in done.stderr
    converted = text.replace("- k.value -> plant.k_in", "- {from: k.value, to: plant.k_in, "
                             "convert: float}").replace("- plant.count -> ctl.y",
                                                        "- {from: plant.count, to: ctl.y, convert: float}")
    done = _cli(tmp_path, "validate", converted)
    assert done.returncode == 0, done.stderr
    assert "output not recorded (only numeric signals are): label (String)" in done.stderr


def test_a_non_integer_into_an_integer_input_fails_the_run_at_its_tick(tmp_path, faulty_fmus) -> None:
    text = _faulty_scenario(faulty_fmus["Faulty", 2],  # the plant reads k one tick later
                            "  k: {kind: step, initial: 2, final: 2.5, at: 0.3}\n", CONVERTED_K)
    done = _cli(tmp_path, "run", text)
    assert done.returncode == 1, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last == ("run failed: component 'plant' failed at tick 4 (t=0.4 s): input 'k_in' = 2.5 "
                    "is not an integer (an Integer input takes integer values only)"), last
    assert _column(tmp_path / "cli-run" / "signals.csv", "plant.k_twice") == [0.0, 4.0, 4.0, 4.0]
    cause = json.loads((tmp_path / "cli-run" / "manifest.json").read_text())["cause"]
    assert (cause["kind"], cause["signal"], cause["tick"]) == ("value", "k_in", 4)


def test_an_int64_beyond_2_53_fails_the_run_instead_of_rounding(tmp_path, arrays_fmu) -> None:
    text = f"""\
name: big
duration: 0.5
tick: 0.1
components:
  plant:
    fmu: {arrays_fmu}
    parameters: {{big_start: {2.0 ** 53}}}
"""
    done = _cli(tmp_path, "run", text)
    assert done.returncode == 1, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last == ("run failed: component 'plant' failed at tick 1 (t=0.1 s): output 'count' = "
                    "9007199254740993 (Int64) cannot be recorded exactly: beyond 2^53, float64 "
                    "(the signal store) would round it"), last
    assert _csv(tmp_path / "cli-run" / "signals.csv")[1][0][1] == "9007199254740992"  # tick 0
    cause = json.loads((tmp_path / "cli-run" / "manifest.json").read_text())["cause"]
    assert (cause["kind"], cause["signal"], cause["value"], cause["tick"]) == \
        ("value", "count", "9007199254740993", 1)
