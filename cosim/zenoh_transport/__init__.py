"""The Zenoh transport: each Python component in its own OS process, driven in
lockstep by the master over Zenoh (peer mode, explicit endpoints), plus live
observation of a run's signals.

    with ZenohComponents(specs, run_id="r1") as hosted:
        master = Master(hosted.components, ...)   # HostedComponent objects
        ...
        hosted.publish(tick, t, names, values)    # live view, cheap when unwatched

`cosim.zenoh_transport.live.watch(run_id, endpoint)` is the watching side.
"""

from cosim.inproc import PythonComponentLaunch
from cosim.zenoh_transport.host import RemoteComponent, ZenohComponents

__all__ = ["PythonComponentLaunch", "RemoteComponent", "ZenohComponents"]
