"""Messages a first-time user met while writing broken scenarios (first-hour dry run).

Each test is one mistake made by hand, with the exact message it must give.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.errors import ScenarioError
from cosim.scenario.loader import load_scenario
from tests.helpers.paths import REPO_ROOT

HEAD = ("name: s\nduration: 1\ntick: 0.01\ncomponents:\n  v: {fmu: Bicycle}\n"
        "sources:\n")   # the source is on line 7


def messages(tmp_path: Path, text: str) -> list[str]:
    """The lines of the ScenarioError of `text`, without the file name."""
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    return [line.removeprefix(str(path)) for line in str(info.value).splitlines()]


def test_field_of_another_source_kind_names_that_kind(tmp_path: Path) -> None:
    # A gust's fields under kind: step; "did you mean 'amplitude'?" used to suggest the name itself.
    got = messages(tmp_path, HEAD + "  w: {kind: step, initial: 0, final: 1, at: 1, "
                   "amplitude: 5}\n")
    assert got == [":7: sources.w.amplitude: unknown field 'amplitude' for kind 'step', "
                   "whose fields are: period, host, unit, initial, final, at "
                   "('amplitude' belongs to kind gust)"]


def test_field_of_several_kinds_lists_them(tmp_path: Path) -> None:
    got = messages(tmp_path, HEAD + "  w: {kind: constant, value: 0, start: 1}\n")
    assert got == [":7: sources.w.start: unknown field 'start' for kind 'constant', "
                   "whose fields are: period, host, unit, value ('start' belongs to kind "
                   "ramp, gust)"]


def test_misspelt_source_field_still_gets_a_suggestion(tmp_path: Path) -> None:
    got = messages(tmp_path, HEAD + "  w: {kind: step, initial: 0, final: 1, att: 1}\n")
    assert got == [":7: sources.w.at: field 'at' is required",
                   ":7: sources.w.att: unknown field 'att' (did you mean 'at'?)"]


def test_a_valid_field_in_the_wrong_place_is_not_suggested_as_itself(tmp_path: Path) -> None:
    # `unit` is a field of sources, not of an FMU component.
    got = messages(tmp_path, "name: s\nduration: 1\ntick: 0.01\ncomponents:\n"
                   "  v: {fmu: Bicycle, unit: N}\n")
    assert len(got) == 1 and got[0].startswith(":5: components.v.unit: unknown field 'unit'")
    assert "did you mean 'unit'" not in got[0]


def test_misspelt_class_names_the_module_and_its_components() -> None:
    from cosim.errors import UserError
    from cosim.transport.inproc import import_component_class
    with pytest.raises(UserError) as info:
        import_component_class("controllers.baselines:StanlyController", "controller")
    assert str(info.value) == (
        "component 'controller': module 'controllers.baselines' has no class "
        "'StanlyController' (did you mean 'StanleyController'?); its components: "
        "PurePursuitController, SpeedLoop, StanleyController")


def test_a_name_that_is_not_a_component_keeps_its_message() -> None:
    from cosim.errors import UserError
    from cosim.transport.inproc import import_component_class
    with pytest.raises(UserError, match="'cosim.transport.inproc:UserError' is not a "
                                        "cosim.component.Component subclass"):
        import_component_class("cosim.transport.inproc:UserError", "c")


@pytest.mark.parametrize("where", ["a_file", "a_file/below"])
def test_run_folder_that_cannot_be_made_is_a_user_error(tmp_path: Path, where: str) -> None:
    # `cosim run --out /proc/nope` used to end in a FileNotFoundError traceback.
    from cosim.errors import UserError
    from cosim.execution.run import run_scenario
    path = tmp_path / "s.yaml"
    path.write_text("name: m\nduration: 0.2\ntick: 0.1\n"
                    "components:\n  src:\n    python: cosim.sources:Constant\n"
                    "    parameters: {value: 0}\n")
    (tmp_path / "a_file").write_text("not a folder")
    out = tmp_path / where
    with pytest.raises(UserError) as info:
        run_scenario(load_scenario(path), out, transport="inproc", progress=False)
    reason = "File exists" if where == "a_file" else "Not a directory"
    assert str(info.value) == f"cannot create the run folder {str(out)!r}: {reason}"


CLOCK_PROBE = ("import cosim.engine.startup as s; s.IDLE_BEFORE_EXEC_S = {limit}; "
               "c = s.StartupClock.from_process_start(); c.mark('m'); "
               "print(c.origin_kind, c.marks['m'])")


@pytest.mark.parametrize("exec_after_s, limit, kind", [
    (0.0, 5.0, "process start"),
    (1.5, 1.0, "cosim import (process forked before exec)"),
])
def test_startup_clock_after_a_shell_exec(exec_after_s: float, limit: float, kind: str) -> None:
    # README's first command, bash -c "... pip install ... && cosim run", execs cosim in a
    # process forked before pip ran: 'time to tick 0' read 95 s for a 3 s start-up.
    import subprocess
    import sys
    code = CLOCK_PROBE.format(limit=limit)
    shell = f"sleep {exec_after_s} && exec {sys.executable} -c \"{code}\""
    out = subprocess.run(["bash", "-c", shell], capture_output=True, text=True, check=True,
                         cwd=REPO_ROOT).stdout.split()
    assert " ".join(out[:-1]) == kind
    seconds = float(out[-1])
    assert 0.0 <= seconds < exec_after_s or exec_after_s == 0.0


def test_override_through_a_misspelt_component_suggests_the_real_one(tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text("name: s\nduration: 1\ntick: 0.01\ncomponents:\n"
                    "  controller: {python: cosim.sources:Constant, parameters: {value: 1}}\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, ["components.controler.parameters.value=2"])
    assert str(info.value) == (
        f"{path}: components.controler: a component needs exactly one of 'fmu:' (built-in "
        "name or path to a .fmu) or 'python:' (module:Class) (set by --set "
        "components.controler.parameters.value=2; it made a new 'controler' "
        "(did you mean 'controller'?))")


def test_watch_of_an_ended_run_says_nothing_answers(capsys: pytest.CaptureFixture[str]) -> None:
    # A Zenoh peer opens on a dead endpoint and waits in silence: watching an ended
    # run used to print "watching ..." and nothing else, forever.
    import socket

    from cosim.cli.app import main
    from cosim.cli.watch import check_reachable
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen()
        port = listener.getsockname()[1]
        check_reachable(f"tcp/127.0.0.1:{port}")  # a listener: no error
    assert main(["watch", "r1", "--connect", f"tcp/127.0.0.1:{port}"]) == 2
    assert capsys.readouterr().err.strip() == (
        f"error: nothing answers at tcp/127.0.0.1:{port} (Connection refused): the run has "
        "ended, or the endpoint is not the one `cosim run` printed")
