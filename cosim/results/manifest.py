"""The run folder's manifest.json: what ran, where, with what, and how it went.

Written once before tick 0 (status "running") and rewritten at the end (status
"ok" or "failed" with the error), so even a killed run leaves a manifest. Its
"signals" entry gives each output's unit, description, size and FMI type
(`signal_info`); each FMU's entry lists its outputs that are not recorded
(String, Binary) under "not_recorded"; its "recording" entry gives the decimation
and the file formats (`recording_entry`).
"""

from __future__ import annotations

import datetime
import functools
import os
import platform
import socket
import sys
from importlib import metadata
from typing import Any

import cosim

PACKAGES = ("cosim-vehicle", "fmpy", "eclipse-zenoh", "numpy", "pydantic", "pyyaml",
            "typer", "rich")


@functools.lru_cache(maxsize=1)
def package_versions() -> dict[str, str | None]:
    """Installed versions of the packages a run depends on (None: not installed).

    Cached: `cosim.execution.run` calls it while the component processes start, so that
    the manifest costs nothing after their handshake.
    """
    versions: dict[str, str | None] = {}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    versions["cosim"] = cosim.__version__
    return versions


def run_identity(scenario: Any, run_id: str, transport: str, status: str,
                 error: str | None, time_key: str) -> dict[str, Any]:
    """The manifest fields that say which run this is, shared by every manifest a run writes.

    Args:
        scenario: the scenario as run (overrides applied).
        run_id: the run's id (Zenoh key scope).
        transport: "inproc" or "zenoh".
        status / error: the run's status ("running", "failed", ...) and error text.
        time_key: name of the UTC timestamp field ("started_utc", "failed_utc").
    """
    return {
        "name": scenario.name,
        "run_id": run_id,
        "status": status,
        "error": error,
        time_key: datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "scenario_file": str(scenario.source_file) if scenario.source_file else None,
        "scenario": scenario.model_dump(mode="json", by_alias=True),
        "transport": transport,
    }


def base_manifest(scenario: Any, prepared: Any, hosted: dict[str, Any], transport: str,
                  run_id: str, order: list[str]) -> dict[str, Any]:
    """The manifest before tick 0.

    Args:
        scenario: the scenario as run (overrides applied).
        prepared: the PreparedRun (FMU plans with interfaces).
        hosted: name -> HostedComponent.
        transport: "inproc" or "zenoh".
        run_id: the run's id (Zenoh key scope).
        order: the master's step order.
    """
    host = socket.gethostname()
    placement = dict(getattr(prepared, "placement", None) or {})  # component -> worker
    return {
        **run_identity(scenario, run_id, transport, "running", None, "started_utc"),
        "step_order": list(order),
        "periods_ticks": {n: int(c.period_ticks) for n, c in hosted.items()},
        "fmus": {plan.name: _fmu_entry(plan) for plan in prepared.fmus},
        "hosts": {name: placement.get(name, host) for name in hosted},
        "pids": {name: getattr(c, "pid", None) or os.getpid() for name, c in hosted.items()},
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "packages": dict(package_versions()),
        "signals": signal_info(hosted),
        "recording": recording_entry(scenario.record),
    }


def recording_entry(record: Any) -> dict[str, Any]:
    """The manifest's "recording": the tick stride, the files asked for, and what the metrics saw.

    Args:
        record: the scenario's `record` section.
    """
    every = int(getattr(record, "every", 1))
    return {"every": every, "formats": list(getattr(record, "format", ["csv"])),
            "rows": "every tick" if every == 1 else
            f"ticks 0, {every}, {2 * every}, ... and the last tick",
            "metrics_from": "every tick (the recorder's spool, before decimation)"}


def signal_info(hosted: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """"component.signal" -> {"unit", "description", "size", "type"} of every output port
    ("type": the FMI type of its values, "Float64" for Python components).

    The recorded columns (signals.csv, arrays/) are a subset: `record:` may leave some out.

    Args:
        hosted: name -> HostedComponent (its `outputs` are `cosim.component.Port`s).
    """
    info: dict[str, dict[str, Any]] = {}
    for name, component in hosted.items():
        for port in getattr(component, "outputs", ()) or ():
            info[f"{name}.{port.name}"] = {"unit": str(getattr(port, "unit", "") or ""),
                                          "description": str(getattr(port, "description", "")),
                                          "size": int(getattr(port, "size", 1)),
                                          "type": str(getattr(port, "type", "Float64"))}
    return info


def _fmu_entry(plan: Any) -> dict[str, Any]:
    interface = plan.interface
    return {
        "path": str(plan.path),
        "sha256": getattr(interface, "sha256", None),
        "fmi_version": getattr(interface, "fmi_version", None),
        "model_identifier": getattr(interface, "model_identifier", None),
        "guid": getattr(interface, "guid", None),
        "fmi_type": getattr(interface, "fmi_type", None),
        "solver": getattr(plan, "solver", None),
        "not_recorded": dict(getattr(interface, "not_recorded", None) or {}),
        "parameters": dict(plan.parameters),
    }


def finish_manifest(manifest: dict[str, Any], result: Any,
                    failure: BaseException | None = None) -> dict[str, Any]:
    """The final manifest: status, error, ticks, times, real-time factor, pacing
    stats, time to tick 0 and the start-up marks; `stopped_by` when a component
    ended the run, `cause` when a component failure says how it failed.

    Args:
        manifest: the manifest written before tick 0.
        result: the RunResult.
        failure: what ended the run, if anything did.
    """
    final = dict(manifest)
    final.update({
        "status": result.status,
        "error": result.error,
        "ticks": result.ticks,
        "sim_time_s": result.sim_time_s,
        "wall_time_s": result.wall_time_s,
        "real_time_factor": result.real_time_factor,
        "loop_time_s": getattr(result, "loop_time_s", None),     # ticks 1..N, without start-up
        "realtime": result.realtime,
        "time_to_tick0_s": result.time_to_tick0_s,
        "startup": result.startup,
    })
    if getattr(result, "stopped_by", None) is not None:
        final["stopped_by"] = result.stopped_by
    if getattr(failure, "details", None):
        final["cause"] = {**failure.details, "component": failure.component,
                          "tick": failure.tick, "time": failure.time}
    return final
