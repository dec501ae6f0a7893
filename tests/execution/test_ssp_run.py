"""Running SSP packages: as they stand, inside a YAML, against fmpy, and the export round trip."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cosim.cli.app import main
from cosim.component import Component, Port
from cosim.execution.run import run_scenario
from cosim.scenario.loader import load_scenario, scenario_from_dict
from tests.helpers.ssp import (HEADER, lag_connectors, lag_pair_resources, lag_pair_ssd,
                               write_ssp)


class Affine(Component):
    """y = scale * x + offset, in Python: the reference for a connection's transformation."""

    inputs = (Port("x"),)
    outputs = (Port("y"),)

    def __init__(self, scale: float, offset: float):
        self.scale, self.offset = scale, offset

    def step(self, t, inputs):
        return {"y": self.scale * inputs["x"] + self.offset}


class YawDamper(Component):
    """delta = -k * r: a Python controller around the exported FMU part."""

    inputs = (Port("r", unit="rad/s"),)
    outputs = (Port("delta", unit="rad"),)

    def __init__(self, k: float):
        self.k = k

    def step(self, t, inputs):
        return {"delta": -self.k * inputs["r"]}


@pytest.fixture(autouse=True)
def _cache(tmp_path, monkeypatch):
    monkeypatch.setenv("COSIM_CACHE_DIR", str(tmp_path / "cache"))


def signals(folder: Path) -> np.ndarray:
    return np.genfromtxt(folder / "signals.csv", delimiter=",", names=True)


def run(scenario, folder: Path) -> Path:
    assert run_scenario(scenario, folder, transport="inproc", progress=False).status == "ok"
    return folder


@pytest.mark.parametrize("version", ["1.0", "2.0"])
def test_ssp_runs_as_it_stands_and_applies_the_linear_transformation(tmp_path, lag_fmus,
                                                                     version, capsys):
    ssp = write_ssp(tmp_path / "pair.ssp", lag_pair_ssd(version),
                    {"resources/Lag.fmu": lag_fmus[2]}, lag_pair_resources(version))
    assert main(["run", str(ssp), "--transport", "inproc", "--out", str(tmp_path / "r")]) == 0
    ours = signals(tmp_path / "r")
    # the same system with the transformation done by a Python component between the lags
    reference = scenario_from_dict({
        "name": "ref", "duration": 2.0, "tick": 0.01,
        "components": {
            "lag2": {"fmu": str(lag_fmus[2]), "parameters": {"gain": 0.5}},
            "lag1": {"fmu": str(lag_fmus[2]), "parameters": {"tau": 0.25, "y_init": 1.0}},
            "affine": {"python": f"{__name__}:Affine", "parameters": {"scale": 1.3, "offset": 50.0}}},
        "connections": [{"from": "lag1.y_out", "to": "affine.x"},
                        {"from": "affine.y", "to": "lag2.u_cmd"}]})
    theirs = signals(run(reference, tmp_path / "ref"))
    for column in ("lag1y_out", "lag2y_out"):
        assert np.array_equal(ours[column], theirs[column])  # bit for bit
    assert ours["lag2y_out"][-1] > 20.0  # 0.5 * (1.3 * y1 + 50) drives it: not a no-op


def test_agrees_with_fmpys_own_ssp_simulation(tmp_path, lag_fmus):
    from fmpy.ssp.simulation import simulate_ssp

    ssp = write_ssp(tmp_path / "chain.ssp", CHAIN, {"resources/Lag.fmu": lag_fmus[2]})
    theirs = simulate_ssp(str(ssp), stop_time=1.0, step_size=0.01, input={"u": lambda t: 1.0})
    scenario = scenario_from_dict({
        "system": str(ssp), "tick": 0.01, "sources": {"u": {"kind": "constant", "value": 1.0}},
        "connections": [{"from": "u.value", "to": "lag1.u_cmd"}]})
    ours = signals(run(scenario, tmp_path / "r"))
    # fmpy exchanges values after every step (Jacobi, inputs 0 at the first step) and
    # labels a row with the time before its step; here lag2 is declared first, so our
    # Gauss-Seidel order gives the same sequence: fmpy's row i is our tick i. The last
    # bits differ: our step is t_k - t_(k-1) from integer ticks, fmpy's a constant h.
    rows = len(theirs)
    assert rows == 100
    for ours_name, theirs_name in (("lag1y_out", "lag1.y_out"), ("lag2y_out", "lag2.y_out")):
        np.testing.assert_allclose(ours[ours_name][:rows], theirs[theirs_name],
                                   rtol=0, atol=1e-13)
    assert ours["lag2y_out"][rows - 1] > 0.5


CHAIN = HEADER.format(name="chain", version="1.0") + """
  <ssd:System name="chain">
    <ssd:Connectors><ssd:Connector name="u" kind="input"><ssc:Real/></ssd:Connector></ssd:Connectors>
    <ssd:Elements>
      <ssd:Component name="lag2" source="resources/Lag.fmu">
        """ + lag_connectors("1.0") + """
      </ssd:Component>
      <ssd:Component name="lag1" source="resources/Lag.fmu">
        """ + lag_connectors("1.0") + """
      </ssd:Component>
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startConnector="u" endElement="lag1" endConnector="u_cmd"/>
      <ssd:Connection startElement="lag1" startConnector="y_out" endElement="lag2" endConnector="u_cmd"/>
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="1"/>
</ssd:SystemStructureDescription>
"""

SCENARIO = """\
name: round_trip
duration: 1.0
tick: 0.01
components:
  a: {{fmu: {lag}, parameters: {{y_init: 1.0, tau: 0.3}}, period: 0.02}}
  car: {{fmu: Bicycle, parameters: {{vx0: 8.0}}}}
  c: {{fmu: {lag}, uncertainty: {{gain: {{scale: 1.5}}}}}}
  steer: {{python: {module}:YawDamper, parameters: {{k: 0.01}}}}
sources:
  k: {{kind: step, initial: 0.0, final: 0.2, at: 0.3}}
connections:
  - {{from: a.y_out, to: c.u_cmd, scale: 2.0, offset: -0.5}}
  - {{from: c.y_out, to: car.torque, scale: 100.0}}
  - {{from: car.r, to: steer.r}}
  - {{from: steer.delta, to: car.delta}}
  - {{from: k.value, to: a.u_cmd}}
"""


@pytest.mark.parametrize("version", ["1.0", "2.0"])
def test_export_then_import_gives_bit_identical_signals(tmp_path, lag_fmus, version, capsys):
    (tmp_path / "s.yaml").write_text(SCENARIO.format(lag=lag_fmus[2], module=__name__))
    original = load_scenario(tmp_path / "s.yaml")
    assert main(["export-ssp", str(tmp_path / "s.yaml"), str(tmp_path / "plant.ssp"),
                 "--ssp-version", version]) == 0
    printed = capsys.readouterr().out
    assert "3 FMU components, 2 connections" in printed
    assert "left out (not FMU-to-FMU): connection car.r -> steer.r" in printed
    # the YAML keeps its Python part and brings the FMU part in from the package
    (tmp_path / "t.yaml").write_text(
        "name: round_trip\nsystem: plant.ssp\n"
        f"components:\n  steer: {{python: {__name__}:YawDamper, parameters: {{k: 0.01}}}}\n"
        "sources:\n  k: {kind: step, initial: 0.0, final: 0.2, at: 0.3}\n"
        "connections:\n  - {from: car.r, to: steer.r}\n  - {from: steer.delta, to: car.delta}\n"
        "  - {from: k.value, to: a.u_cmd}\n")
    imported = load_scenario(tmp_path / "t.yaml")
    assert imported.components["a"].period == 0.02 and imported.tick == 0.01
    assert imported.components["c"].parameters == {"gain": 3.0}  # uncertainty applied
    first = run(original, tmp_path / "r1") / "signals.csv"
    second = run(imported, tmp_path / "r2") / "signals.csv"
    assert first.read_bytes() == second.read_bytes()
    assert main(["validate", str(tmp_path / "plant.ssp")]) == 0
    assert "plant.ssp: ok (3 components, 2 connections" in capsys.readouterr().out


def test_export_refuses_a_delay_between_fmus_and_validate_reports_ssp_problems(tmp_path,
                                                                               lag_fmus, capsys):
    (tmp_path / "d.yaml").write_text(
        f"name: d\nduration: 0.1\ntick: 0.01\ncomponents:\n  a: {{fmu: {lag_fmus[2]}}}\n"
        f"  b: {{fmu: {lag_fmus[2]}}}\nconnections:\n  - {{from: a.y_out, to: b.u_cmd, delay: 1}}\n")
    assert main(["export-ssp", str(tmp_path / "d.yaml"), str(tmp_path / "d.ssp")]) == 2
    assert "connection a.y_out -> b.u_cmd has delay: 1, which SSP cannot express" in \
        capsys.readouterr().err
    broken = lag_pair_ssd("1.0").replace('endConnector="u_cmd"', 'endConnector="u_cmdd"')
    ssp = write_ssp(tmp_path / "b.ssp", broken, {"resources/Lag.fmu": lag_fmus[2]},
                    lag_pair_resources("1.0"))
    assert main(["validate", str(ssp)]) == 2
    err = capsys.readouterr().err
    assert "b.ssp: SystemStructure.ssd:" in err and "unknown connector lag2.u_cmdd" in err
    assert "Traceback" not in err
