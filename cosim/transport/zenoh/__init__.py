"""The Zenoh transport: each Python component in its own OS process, driven in
lockstep by the master over Zenoh (peer mode, explicit endpoints), plus live
observation of a run's signals.

    with ZenohComponents(specs, run_id="r1") as hosted:
        master = Master(hosted.components, ...)   # HostedComponent objects
        ...
        hosted.publish(tick, t, names, values)    # live view, cheap when unwatched

`cosim.transport.zenoh.live.watch(run_id, endpoint)` is the watching side.
The names below are imported lazily, so that a component process (which only
needs `runner`) starts without loading the master side.
"""

from __future__ import annotations

from typing import Any

__all__ = ["PythonComponentLaunch", "RemoteComponent", "ZenohComponents"]


def __getattr__(name: str) -> Any:
    if name in ("ZenohComponents", "RemoteComponent"):
        from cosim.transport.zenoh import host
        return getattr(host, name)
    if name == "PythonComponentLaunch":
        from cosim.transport.inproc import PythonComponentLaunch
        return PythonComponentLaunch
    raise AttributeError(f"module 'cosim.transport.zenoh' has no attribute {name!r}")
