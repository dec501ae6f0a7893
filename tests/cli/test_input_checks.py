"""Input checks seen from the command line: component parameters typed and located
at their YAML line, planner geometry bounded, run size bounded (--max-ticks,
--allow-large), endpoint and other option errors in one line, and `cosim sweep`
validating every sample first and failing when a sample failed."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.cli.app import main
from tests.cli.test_parameter_errors import CONTROLLER
from tests.helpers.components import GOOD

PLANNER = """\
name: planner
duration: 0.1
tick: 0.01
components:
  planner:
    python: controllers.planning:Planner
    parameters:
      road:
        builder: two_lane
        length: {length}
        radius: {radius}
"""


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(text)
    return path


def _err(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    return err.strip()


@pytest.mark.parametrize("bad, expected", [
    ("ke: x", "components.controller.parameters.ke: expected a number or a list, got 'x'"),
    ("ke: [1, x]", "components.controller.parameters.ke[1]: expected a number, got 'x'"),
    ("adaptive: yes please", "components.controller.parameters.adaptive: expected true or "
                             "false, got 'yes please'"),
    ("kz: true", "components.controller.parameters.kz: expected a number, got True"),
    ("lateral_law: 3", "components.controller.parameters.lateral_law: expected one of "
                       "'faithful' or 'feedforward', got 3"),
])
def test_parameter_types_are_checked_at_their_line(tmp_path, capsys, bad, expected):
    path = _write(tmp_path, CONTROLLER.format(bad=bad))
    assert main(["validate", str(path)]) == 2
    assert _err(capsys) == f"error: {path}:9: {expected}"


@pytest.mark.parametrize("length, radius, line, expected", [
    ("1e12", "150", 10, "road.length: must be at most 100000 in size, got 1000000000000.0"),
    ("600", "0", 11, "road.radius: must not be 0 (leave radius out for a straight road; a "
                     "negative radius bends right)"),
    ("600", "1e-300", 8, "road: path too winding: its curvature needs 1.5e+303 intervals (at "
                         "most 1000000); is a radius far too small?"),
    ("true", "150", 10, "road.length: expected a number, got True"),
])
def test_planner_geometry_is_bounded(tmp_path, capsys, length, radius, line, expected):
    path = _write(tmp_path, PLANNER.format(length=length, radius=radius))
    assert main(["validate", str(path)]) == 2
    field, _, message = expected.partition(": ")
    assert _err(capsys) == f"error: {path}:{line}: components.planner.parameters.{field}: {message}"


def test_run_size_is_bounded_unless_raised(tmp_path, capsys):
    path = _write(tmp_path, GOOD)
    out = tmp_path / "run"
    assert main(["run", str(path), "--transport", "inproc", "--out", str(out),
                 "--set", "tick=1e-9"]) == 2
    assert _err(capsys) == (
        f"error: {path}:2: duration (tick set by --set tick=1e-9): the run would have 5e+08 "
        "ticks (duration 0.5 s / tick "
        "1e-09 s), more than the limit of 1e+08: raise the limit with --max-ticks N, or pass "
        "--allow-large")
    assert not out.exists()  # refused before the run folder
    assert main(["validate", str(path), "--max-ticks", "10"]) == 2
    assert "more than the limit of 10" in _err(capsys)
    assert main(["validate", str(path), "--max-ticks", "50"]) == 0
    assert main(["validate", str(path), "--set", "duration=1e7", "--max-ticks", "1e9"]) == 2
    assert "--max-ticks" in _err(capsys)  # not an integer: click's message, one line
    assert main(["validate", str(path), "--set", "duration=1e7", "--max-ticks",
                 "2000000000"]) == 2
    assert "GB of CSV" in _err(capsys) and main(
        ["validate", str(path), "--set", "duration=1e7", "--allow-large"]) == 0


@pytest.mark.parametrize("argv, expected", [
    (["watch", "abc", "--connect", "bogus"],
     "--connect 'bogus': an endpoint reads PROTOCOL/ADDRESS, e.g. tcp/127.0.0.1:7447"),
    (["run", "{good}", "--connect", "udp//x"],
     "--connect 'udp//x': a udp endpoint reads udp/HOST:PORT (port 0..65535), e.g. "
     "tcp/127.0.0.1:7447"),
    (["run", "{good}", "--transport", "inproc", "--realtime", "1e-9"],
     "--realtime factor must be a number from 0.001 (1000 times slower than real time) up, "
     "got 1e-09"),
    (["build-fmus", "--out", "/proc/x"],
     "--out /proc/x: cannot write the FMUs there (/proc/x: No such file or directory)"),
    (["run", "{good}", "--deadline", "abc"],
     "cosim run: Invalid value for '--deadline': Input should be a valid number, unable to "
     "parse string as a number (see 'cosim run --help')"),
])
def test_option_errors_are_one_line(tmp_path, capsys, argv, expected):
    good = str(_write(tmp_path, GOOD))
    assert main([a.replace("{good}", good) for a in argv]) == 2
    assert _err(capsys) == f"error: {expected}"


SWEEP = GOOD.replace("    parameters: {k: 3.0}",
                     "    parameters: {k: 3.0}\n  mixer:\n    python: tests.helpers.components:Mixer\n"
                     "    parameters: {fail_at: 0.3}")


def test_sweep_refuses_invalid_samples_before_running_any(tmp_path, capsys):
    path = _write(tmp_path, SWEEP)
    assert main(["sweep", str(path), "--vary", "components.gain.parameters.k=-1:1", "--vary",
                 "duration=0.1:0.3", "--samples", "3", "--out", str(tmp_path / "sw")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {path}: sweep refused before its first run: 3 of 3 samples are "
                          "invalid:\nsample 0 (components.gain.parameters.k=")
    assert "is not a whole number of ticks" in err and "Traceback" not in err
    assert not (tmp_path / "sw" / "samples" / "sample_0000").exists()


def test_sweep_exits_1_when_a_sample_failed(tmp_path, capsys):
    path = _write(tmp_path, SWEEP)
    code = main(["sweep", str(path), "--vary", "components.mixer.parameters.fail_at=0.1:0.9",
                 "--samples", "4", "--seed", "3", "--out", str(tmp_path / "sw")])
    err = capsys.readouterr().err
    assert code == 1, err
    assert "sweep failed: 2 of 4 samples failed (samples " in err
