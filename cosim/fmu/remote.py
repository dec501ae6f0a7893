"""A plant FMU placed on a worker: the file travels, checked by sha256, and runs
there in an ordinary component process behind the same lockstep protocol.

Master side: `fmu_launch(name, path, variables, parameters, period_ticks)` turns
an FMU component into a launch of `RemoteFmu`; the worker client sends the
file's bytes with the start request, and the worker (started with
`--allow-fmu`) checks them against the sha256 before writing them to its cache
and starting the process. Worker side: `RemoteFmu` checks the hash once more,
describes the FMU with the same name map and hosts it through the same
`FmuComponent` the master uses locally, so the results are bit-identical.
"""

from __future__ import annotations

import base64
import hashlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from cosim.component import Component, ComponentError, Value
from cosim.transport.inproc import PythonComponentLaunch

FMU_HOST_CLASS = "cosim.fmu.remote:RemoteFmu"


def sha256_of(data: bytes) -> str:
    """Hex sha256 of `data`."""
    return hashlib.sha256(data).hexdigest()


def fmu_launch(name: str, path: str | Path, variables: Mapping[str, str],
               parameters: Mapping[str, float], period_ticks: int) -> PythonComponentLaunch:
    """The launch of a `RemoteFmu` hosting the FMU component `name` on a worker.

    Args:
        name: the component's name in the scenario.
        path: the .fmu file on the master.
        variables: canonical name -> FMU variable name (foreign FMUs), as in the scenario.
        parameters: canonical parameter values, already checked by the master.
        period_ticks: master ticks between two steps.
    """
    data = Path(path).read_bytes()
    return PythonComponentLaunch(name, FMU_HOST_CLASS, {
        "fmu_file": str(path), "sha256": sha256_of(data), "component": name,
        "variables": dict(variables), "parameters": {k: float(v) for k, v in parameters.items()},
        "period_ticks": int(period_ticks)}, int(period_ticks))


def fmu_payload(launch: PythonComponentLaunch) -> dict[str, str]:
    """What a start request carries for a RemoteFmu launch: the hash and the bytes (base64).

    Args:
        launch: made by `fmu_launch`.
    """
    data = Path(launch.parameters["fmu_file"]).read_bytes()
    return {"sha256": sha256_of(data), "data": base64.b64encode(data).decode("ascii")}


def store_fmu(payload: Mapping[str, Any], cache: Path) -> Path:
    """Check a received FMU against its sha256 and write it to `cache` (named by hash).

    Args:
        payload: {"sha256", "data"} from the start request.
        cache: the worker's FMU folder.
    Raises:
        ValueError when the bytes do not match the hash or are not base64.
    """
    digest = str(payload.get("sha256", ""))
    try:
        data = base64.b64decode(str(payload.get("data", "")), validate=True)
    except ValueError as exc:
        raise ValueError(f"FMU bytes are not valid base64: {exc}") from None
    if len(digest) != 64 or sha256_of(data) != digest:
        raise ValueError(f"FMU bytes do not match their sha256 {digest!r} "
                         f"(got {sha256_of(data)}); refusing to run them")
    cache.mkdir(parents=True, exist_ok=True)
    target = cache / f"{digest}.fmu"
    if not target.exists():
        partial = target.with_suffix(".part")
        partial.write_bytes(data)
        partial.replace(target)
    return target


class RemoteFmu(Component):
    """An FMU hosted in a component process on a worker.

    Args:
        fmu_file: the FMU in the worker's cache.
        sha256: the hash the master computed of the file.
        component: the component's name in the scenario (for messages).
        variables: canonical name -> FMU variable name.
        parameters: canonical parameter values.
        period_ticks: master ticks between two steps (gives the tick of a failure).
    """

    def __init__(self, fmu_file: str, sha256: str, component: str,
                 variables: Mapping[str, str] | None = None,
                 parameters: Mapping[str, float] | None = None, period_ticks: int = 1) -> None:
        from cosim.errors import UserError
        from cosim.fmu.interface import describe_fmu
        from cosim.fmu.typed import hosted_fmu

        path = Path(fmu_file)
        if sha256_of(path.read_bytes()) != sha256:
            raise ComponentError(f"{path}: content does not match sha256 {sha256}")
        try:
            interface = describe_fmu(path, dict(variables or {}))
        except UserError as exc:
            raise ComponentError(str(exc)) from None
        self._fmu = hosted_fmu(component, path, interface, dict(parameters or {}), period_ticks)
        self.inputs = tuple(interface.inputs)
        self.outputs = tuple(interface.outputs)
        self._period_ticks = int(period_ticks)
        self._steps = 0

    def initialize(self, t0: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Instantiate and initialize the FMU at t0."""
        return self._call(self._fmu.start, t0, inputs)

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """doStep to t with the held inputs."""
        self._steps += 1
        return self._call(self._fmu.step, self._steps * self._period_ticks, t, inputs)

    def finish(self) -> dict[str, float]:
        """Terminate and free the instance."""
        return self._call(self._fmu.stop)

    @staticmethod
    def _call(method: Any, *args: Any) -> Any:
        from cosim.errors import ComponentFailure

        try:
            return method(*args)
        except ComponentFailure as exc:  # the master adds component, tick and time itself
            raise ComponentError(exc.cause) from None
