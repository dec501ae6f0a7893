"""A component's code that calls sys.exit(), raises KeyboardInterrupt, or whose module
fails at import, fails that component with one line: it never ends the host's process
nor sets the command's exit status (`cosim.transport.inproc.USER_CODE_ERRORS`).

KeyboardInterrupt is the exception: in the master's own process it is the user's
Ctrl-C; a component process ignores SIGINT, so there it is the component's error.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

from cosim.errors import UserError
from cosim.execution.run import run_scenario
from cosim.scenario.loader import load_scenario
from tests.execution.test_fmu_faults import COSIM
from tests.helpers.paths import REPO_ROOT

SCENARIO = """\
name: exits
duration: 0.3
tick: 0.01
components:
  g:
    python: {python}
    parameters: {parameters}
sources:
  ref: {{kind: constant, value: 1.0}}
connections:
  - ref.value -> g.u
"""
MODULES = {  # module text, and what the error says after "importing module 'm' failed"
    "raises": ("x = 1\nraise RuntimeError('boom at import')\n",
               " ({path}, line 2): RuntimeError: boom at import"),
    "exits": ("import sys\nsys.exit(0)\n", " ({path}, line 2): SystemExit: 0"),
    "syntax": ("def f(:\n    pass\n", ": SyntaxError: invalid syntax (m_syntax.py, line 1)"),
}


def _scenario(tmp_path, python: str, parameters: str = "{}"):
    path = tmp_path / "exits.yaml"
    path.write_text(SCENARIO.format(python=python, parameters=parameters))
    return path


@pytest.mark.parametrize("transport", ["inproc", "zenoh"])
@pytest.mark.parametrize("code", [0, 3])
def test_sys_exit_in_a_step_fails_the_component(tmp_path, transport, code):
    scenario = load_scenario(_scenario(tmp_path, "tests.helpers.components:RaisesBaseException",
                                       f"{{what: exit, code: {code}}}"))
    result = run_scenario(scenario, tmp_path / "run", transport=transport, progress=False)
    assert (result.status, result.error) == (
        "failed", f"component 'g' failed at tick 10 (t=0.1 s): SystemExit: {code}")


def test_keyboard_interrupt_in_a_component_process_fails_the_component(tmp_path):
    scenario = load_scenario(_scenario(tmp_path, "tests.helpers.components:RaisesBaseException",
                                       "{what: interrupt}"))
    result = run_scenario(scenario, tmp_path / "run", transport="zenoh", progress=False)
    assert (result.status, result.error) == (
        "failed", "component 'g' failed at tick 10 (t=0.1 s): KeyboardInterrupt: ")


def test_sys_exit_0_in_a_step_is_a_failed_run_for_the_command(tmp_path):
    scenario = _scenario(tmp_path, "tests.helpers.components:RaisesBaseException",
                         "{what: exit, code: 0}")
    done = subprocess.run([str(COSIM), "run", str(scenario), "--transport", "inproc",
                           "--no-figures", "--out", str(tmp_path / "run")],
                          cwd=REPO_ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 1, done.stderr
    assert done.stderr.strip().splitlines()[-1] == (
        "run failed: component 'g' failed at tick 10 (t=0.1 s): SystemExit: 0")


@pytest.mark.parametrize("transport", ["inproc", "zenoh"])
@pytest.mark.parametrize("kind", MODULES)
def test_a_module_that_fails_at_import_is_one_line(tmp_path, transport, kind):
    text, said = MODULES[kind]
    module = tmp_path / f"m_{kind}.py"
    module.write_text(text)
    scenario = load_scenario(_scenario(tmp_path, f"m_{kind}:Anything"))
    with pytest.raises(UserError) as raised:
        run_scenario(scenario, tmp_path / "run", transport=transport, progress=False)
    message = str(raised.value)
    assert "\n" not in message
    assert message.endswith(f"component 'g': importing module 'm_{kind}' failed"
                            + said.format(path=module)), message
    sys.modules.pop(f"m_{kind}", None)


@pytest.mark.parametrize("transport", ["inproc", "zenoh"])
def test_a_failing_finish_is_named_at_the_last_tick_on_both_transports(tmp_path, transport):
    text = SCENARIO.format(python="tests.helpers.components:FailsToFinish", parameters="{}")
    path = tmp_path / "finish.yaml"
    path.write_text(text)
    result = run_scenario(load_scenario(path), tmp_path / "run", transport=transport, progress=False)
    assert (result.status, result.error) == (
        "failed", "component 'g' failed at tick 30 (t=0.3 s): finish() failed: "
                  "ValueError: cannot summarize")
