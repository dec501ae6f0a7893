"""Python's garbage collector held back while a process of the platform starts.

Starting a run makes some 60,000-150,000 objects that live as long as the process
(modules, classes, the scenario, the FMU's description, numba's compiled code)
and little garbage: 0.4-0.6 MB of it at tick 0 (classes and closures made and
dropped while modules load; measured with `gc.DEBUG_SAVEALL` for lane_change and
satory_nominal in process). The collector still traverses all of them again and
again while they are made: 50-150 ms before tick 0 in the `cosim` command, and
about 70 ms in a component process that loads numba's compiled controller, on
the path to tick 0 too.

So those processes hold collection back from their first imports (`pause`) until
they are under way (`resume`): `cosim run` once tick 0 is done, any other `cosim`
command as it starts (cosim.cli.app), a component process once its component is
built (cosim.transport.zenoh.runner). `resume(freeze=True)` first moves what
exists then out of the generations the collector traverses (`gc.freeze`), so that
later collections do not go over it again, at the cost of keeping that start-up
garbage. Standard library only, so that it is cheap to import first.
"""

from __future__ import annotations

import gc

_paused = False


def pause() -> None:
    """Stop automatic collection until `resume` (nothing if it is off already)."""
    global _paused
    if gc.isenabled():
        gc.disable()
        _paused = True


def resume(freeze: bool = False) -> None:
    """Collect automatically again (nothing unless `pause` stopped it).

    Args:
        freeze: first move every object that exists now out of the collected generations.
    """
    global _paused
    if not _paused:
        return
    _paused = False
    if freeze:
        gc.freeze()
    gc.enable()


def paused() -> bool:
    """Whether `pause` holds collection back now."""
    return _paused
