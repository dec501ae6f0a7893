"""`Component.use_outputs`: which outputs the run reads, told once before initialize, the
same over both transports; the planner then holds an unread alternative window, and every
output it is read for stays bit for bit what it was."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.cli.app import main
from cosim.component import Port
from cosim.engine.wiring import Edge, outputs_read
from cosim.results.recorder import read_signals
from controllers.planning.planner import Planner
from tests.helpers.paths import REPO_ROOT

READER = """\
name: reader
duration: 0.2
tick: 0.01
components:
  reader:
    python: tests.helpers.components:OutputReader
    parameters: {{fail: {fail}}}
sources:
  u: {{kind: step, initial: 0.0, final: 1.0, at: 0.05}}
connections:
  - {{from: u.value, to: reader.u}}
record: {{exclude: [{exclude}]}}
"""


@pytest.fixture(autouse=True)
def child_can_import_test_components(monkeypatch):
    monkeypatch.setenv("PYTHONPATH", str(REPO_ROOT))


def test_scalars_carried_and_recorded_arrays_are_read():
    ports = {"p": ((), (Port("s"), Port("a", size=4), Port("b", size=4), Port("c", size=4))),
             "q": ((Port("a_in", size=4),), ())}
    edges = [Edge("p", "a", "q", "a_in")]
    read = outputs_read(edges, ports, recorded=lambda name: name == "p.c")
    assert read == {"p": frozenset({"s", "a", "c"}), "q": frozenset()}


@pytest.mark.parametrize("transport", ["inproc", "zenoh"])
@pytest.mark.parametrize("exclude, heard", [('"reader.b"', 1 + 2), ('"reader.a", "reader.b"', 1),
                                            ('"none"', 1 + 2 + 4)])
def test_the_component_hears_the_read_outputs_before_initialize(tmp_path, transport, exclude, heard):
    scenario = tmp_path / "reader.yaml"
    scenario.write_text(READER.format(fail="false", exclude=exclude))
    out = tmp_path / transport
    assert main(["run", str(scenario), "--out", str(out), "--transport", transport, "--no-figures"]) == 0
    names, rows = read_signals(out / "signals.csv")
    column = np.asarray(rows)[:, names.index("reader.heard")]
    assert set(column.tolist()) == {float(heard)}


@pytest.mark.parametrize("transport", ["inproc", "zenoh"])
def test_a_failing_use_outputs_fails_the_run_naming_the_component(tmp_path, capsys, transport):
    scenario = tmp_path / "reader.yaml"
    scenario.write_text(READER.format(fail="true", exclude='"reader.b"'))
    code = main(["run", str(scenario), "--out", str(tmp_path / "run"), "--transport", transport,
                 "--no-figures"])
    err = capsys.readouterr().err
    assert code == 1  # as a failing initialize: the run fails, its folder says why
    assert "'reader'" in err and "use_outputs() failed: ValueError: refusing the names" in err
    assert "Traceback" not in err


def _drive(planner: Planner, steps: int) -> list[dict]:
    """Initialize on the Satory stand-in's start and step along its reference line."""
    x, y, psi, _ = planner.road.reference.evaluate(0.8 * np.arange(steps + 1))
    outs = [planner.initialize(0.0, {"x": x[0], "y": y[0], "psi": psi[0], "vx": 8.0})]
    for k in range(1, steps + 1):
        outs.append(planner.step(0.1 * k, {"x": x[k], "y": y[k], "psi": psi[k], "vx": 8.0}))
    return outs


def test_an_unread_alternative_is_held_and_the_rest_is_bit_identical():
    told, plain = Planner(road="satory_standin"), Planner(road="satory_standin")
    told.use_outputs({p.name for p in Planner.outputs if not p.name.startswith("alt_")})
    held, computed = _drive(told, 40), _drive(plain, 40)
    for name in (p.name for p in Planner.outputs):
        for k, (a, b) in enumerate(zip(held, computed)):
            if name.startswith("alt_"):
                assert a[name] is held[0][name], (name, k)   # the very same read-only object
                assert not a[name].flags.writeable
            else:
                assert np.asarray(a[name]).tobytes() == np.asarray(b[name]).tobytes(), (name, k)
    assert held[0]["alt_x"].tobytes() == computed[0]["alt_x"].tobytes()  # the held one is real
    assert any(c["alt_x"].tobytes() != computed[0]["alt_x"].tobytes() for c in computed[1:])
