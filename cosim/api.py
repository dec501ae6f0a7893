"""The Python API: run a scenario and get its results as pandas DataFrames.

    import cosim

    run = cosim.run("lane_change", set={"duration": 20})   # a shipped name, a path or a dict
    run.status, run.metrics["max_abs_yc"]                   # metrics exactly as `cosim run` prints
    run.signals["vehicle.vx"]                               # DataFrame indexed by time
    run.signals.attrs["units"]["vehicle.vx"]                # "m/s"
    run.plot()                                              # the paper-style matplotlib Figure
    run.plot(signals=["vehicle.v*", "controller.delta"])    # any signals against time, with units

Everything goes through the code paths of the `cosim` command: the same
loading and checks (a bad scenario raises the `ScenarioError` the CLI prints),
the same run folder, the same metrics (`cosim.execution.finish`). These
functions are reached as `cosim.run`, `cosim.load_run`, ... through the
package's lazy attributes, so `import cosim` itself stays cheap.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Union

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

    from cosim.analysis.rundata import RunData
    from cosim.scenario.models import Scenario

ScenarioSource = Union[str, Path, Mapping[str, Any]]
Overrides = Union[Mapping[str, Any], Sequence[str], None]

__all__ = ["Run", "load_run", "load_scenario", "run", "scenarios", "validate"]


class Run:
    """The results of one run, read from its run folder (lazily, then kept).

    Attributes:
        path: the run folder.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    def __repr__(self) -> str:
        return f"Run({str(self.path)!r}, status={self.status!r})"

    @functools.cached_property
    def _data(self) -> RunData:
        from cosim.analysis.rundata import load_run as load_run_data

        return load_run_data(self.path)

    @property
    def manifest(self) -> dict[str, Any]:
        """manifest.json: the scenario as run, FMU hashes, versions, hosts, timings, status."""
        from cosim.analysis.rundata import read_json_object

        return read_json_object(self.path / "manifest.json")

    @property
    def status(self) -> str:
        """"ok", "failed" (see `error`) or "running" (a run killed before it could finish)."""
        return str(self.manifest.get("status", "unknown"))

    @property
    def error(self) -> str | None:
        """Why the run failed (the message `cosim run` prints), or None."""
        return self.manifest.get("error")

    @property
    def metrics(self) -> dict[str, Any]:
        """metrics.json: the platform's metrics (as `cosim run` computes them) and the components'."""
        from cosim.analysis.rundata import read_json_object

        return read_json_object(self.path / "metrics.json")

    @functools.cached_property
    def signals(self) -> pd.DataFrame:
        """Scalar signals: index time (s), columns "component.signal"; units in `.attrs["units"]`."""
        from cosim.analysis.frames import signals_frame

        return signals_frame(self._data)

    @functools.cached_property
    def arrays(self) -> dict[str, pd.DataFrame]:
        """Array signals (e.g. the planner's windows): name -> DataFrame indexed by time."""
        from cosim.analysis.frames import array_frames

        return array_frames(self._data)

    def plot(self, layout: str | None = None, save: bool = False,
             signals: str | Sequence[str] = ()) -> Figure:
        """The run's figure (shown by notebooks), as `cosim plot` draws it.

        Args:
            layout: "track", "manoeuvre", "speed", "following", "signals" or None
                (chosen from the scenario: paper-style for a vehicle run, else signals).
            save: also write it into the run folder as figure_<layout>.png.
            signals: glob patterns ("ball.*") of recorded signals to draw against
                time instead, one panel each with its unit, as `cosim plot --signals`.
        Raises:
            AnalysisError (a UserError): a pattern matches no recorded signal.
        """
        from cosim.figures.layouts import build_figure, save_png

        patterns = [signals] if isinstance(signals, str) else list(signals)
        fig, chosen = build_figure([self._data], layout, patterns)
        if save:
            save_png(fig, self.path / f"figure_{chosen}.png")
        return fig


def _overrides(values: Overrides) -> list[str]:
    """`set=` as "PATH=VALUE" strings: a mapping {"duration": 10} or strings as for `--set`."""
    if values is None:
        return []
    if isinstance(values, Mapping):
        return [f"{path}={_yaml_value(value)}" for path, value in values.items()]
    if isinstance(values, str):
        return [values]
    return [str(v) for v in values]


def _yaml_value(value: Any) -> str:
    """A value as one line of YAML that reads back equal (1e-05 as 1.0e-05, strings quoted as needed)."""
    import yaml

    text = yaml.safe_dump(value, default_flow_style=True, width=float("inf"))
    return text.removesuffix("\n...\n").strip()


def load_scenario(scenario: ScenarioSource, *, set: Overrides = None) -> Scenario:  # noqa: A002
    """Load and check a scenario (schema and cross-field checks; no FMU or class yet).

    Args:
        scenario: a YAML file, a shipped scenario's name ("lane_change") or a mapping
            of the scenario's fields.
        set: overrides, {"components.controller.parameters.ke": 2.0} or
            ["duration=10", ...] as `cosim run --set`.
    Raises:
        ScenarioError: every problem found, each with its file, line and field.
    """
    from cosim.scenario.loader import load_scenario as load_file, scenario_from_dict

    overrides = _overrides(set)
    if isinstance(scenario, Mapping):
        return scenario_from_dict(dict(scenario), overrides)
    from cosim.scenario.shipped import resolve_scenario

    return load_file(resolve_scenario(scenario), overrides=overrides)


def validate(scenario: ScenarioSource, *, set: Overrides = None) -> dict[str, Any]:  # noqa: A002
    """Check a scenario as `cosim validate` does: FMUs, parameters, classes, wiring, step order.

    Args:
        scenario: as for `load_scenario`.
        set: as for `load_scenario`.
    Returns:
        {"components": name -> (inputs, outputs), "edges": [...], "order": [...]}.
    Raises:
        UserError (ScenarioError, WiringError, FmuInterfaceError, ...): the first class of problems.
    """
    from cosim.execution.validate import validate_scenario

    return validate_scenario(load_scenario(scenario, set=set))


def run(scenario: ScenarioSource, *, set: Overrides = None,  # noqa: A002
        transport: str = "inproc", out: str | Path | None = None,
        progress: bool = False, place: Sequence[str] = (),
        deploy: str | Path | None = None, lockstep_cpu: str | int = "auto",
        force: bool = False) -> Run:
    """Run a scenario to its run folder, compute its metrics, and return its results.

    Args:
        scenario: a YAML file, a shipped scenario's name or a mapping of fields.
        set: overrides, as for `load_scenario`.
        transport: "inproc" (default here: one process) or "zenoh" (a process per component).
        out: the run folder; default runs/<name>-<UTC time> under the working directory.
            An existing non-empty folder is refused unless `force`.
        progress: draw a progress bar on stderr.
        place: "COMPONENT=WORKER" items, as `cosim run --place` (they override the
            scenario's `host:`; WORKER `inproc` hosts a Python component in this process);
            they need transport "zenoh".
        deploy: a deployment settings YAML (workers' endpoints, TLS), as `cosim run --deploy`.
        lockstep_cpu: "auto", "off" or a CPU number, as `cosim run --lockstep-cpu`: when the
            run starts processes, this thread and they run on that one CPU until it ends.
        force: replace an earlier run's folder at `out` (its files are removed first), as
            `cosim run --force`; only a run folder (one with a manifest.json) is replaced.
    Returns:
        The Run. A component failing mid-run does not raise: `status` is then "failed",
        `error` says why, and everything up to the last complete tick is in the folder.
    Raises:
        UserError (ScenarioError, WiringError, FmuInterfaceError, ...): anything wrong
        before tick 0, with the message `cosim run` prints.
    """
    from cosim.execution.finish import analyse_run_folder
    from cosim.engine.one_cpu import check_setting
    from cosim.execution.run import check_out_folder, check_run_options, run_scenario
    from cosim.results.folders import stamped_folder

    check_run_options(transport, None)
    if out is not None:
        check_out_folder(out, force, "out")
    check_setting(lockstep_cpu, "lockstep_cpu")
    if isinstance(place, str):      # one item given bare, not a list of one
        place = [place]
    settings = None
    if deploy is not None:
        from cosim.distributed.deploy import load_deploy, merge_endpoints
        settings = merge_endpoints(load_deploy(deploy))
    loaded = load_scenario(scenario, set=set)
    folder = Path(out) if out is not None else stamped_folder("runs", loaded.name)
    result = run_scenario(loaded, folder, transport=transport, progress=progress, place=list(place),
                          deploy=settings, lockstep_cpu=lockstep_cpu, replace=force)
    if result.ticks > 0:
        analyse_run_folder(result, figures=False)
    return Run(result.out_dir)


def load_run(path: str | Path) -> Run:
    """Open an existing run folder (from `cosim run` or `cosim.run`).

    Raises:
        AnalysisError (a UserError): not a run folder.
    """
    from cosim.analysis.rundata import AnalysisError

    folder = Path(path)
    if not (folder / "signals.csv").is_file() and not (folder / "manifest.json").is_file():
        raise AnalysisError(f"{folder}: not a run folder (no signals.csv or manifest.json)")
    return Run(folder)


def scenarios() -> list[str]:
    """The names of the shipped scenarios (each runs by name: `cosim.run("lane_change")`)."""
    from cosim.scenario.shipped import shipped_scenarios

    return list(shipped_scenarios())

