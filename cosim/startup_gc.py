"""Python's garbage collector held back while a process of the platform starts.

Starting a run makes some 60,000-150,000 objects that live as long as the process
(modules, classes, the scenario, the FMU's description, numba's compiled code)
and little garbage: 0.4-0.6 MB of it at tick 0 (classes and closures made and
dropped while modules load; measured with `gc.DEBUG_SAVEALL` for lane_change and
satory_nominal in process). The collector still traverses all of them again and
again while they are made: 50-150 ms before tick 0 in the `cosim` command, and
about 70 ms in a component process that loads numba's compiled controller, on
the path to tick 0 too.

So those processes hold collection back while they start (`pause`) until they are
under way (`resume`): the `cosim` command from the CLI's import until tick 0 for
`run`, until it starts for any other command (cosim.cli.app), its supervisor
collecting again once forked; a component process from its `main` (its module's
imports done) until its component is built (cosim.transport.zenoh.runner); never in
a sweep's worker, which a spawn starts from the command's script
(`cosim.cli.interrupts.is_cosim_program`). `resume(freeze=True)` then moves what
exists out of the generations the collector traverses (`gc.freeze`), so that later
collections do not go over it again, at the cost of keeping that start-up garbage;
above `COLLECT_FIRST_ABOVE` objects made since the pause it collects first: numba
compiling afresh (an empty cache, one that cannot be written, an edited controller)
leaves about 200,000 unreachable objects, 33 MB, that a freeze would keep. Standard
library only, so that it is cheap to import first.
"""

from __future__ import annotations

import gc

# objects made since the pause (gc.get_count()[0]) at tick 0, measured: lane_change in process
# 91,000; satory_nominal with the compiled controller loaded from numba's cache 223,000, with
# numba compiling it 503,000
COLLECT_FIRST_ABOVE = 300_000

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
        freeze: first move every object that exists now out of the collected generations
            (after a full collection when more than COLLECT_FIRST_ABOVE were made).
    """
    global _paused
    if not _paused:
        return
    _paused = False
    if freeze:
        if gc.get_count()[0] > COLLECT_FIRST_ABOVE:
            gc.collect()
        gc.freeze()
    gc.enable()


def paused() -> bool:
    """Whether `pause` holds collection back now."""
    return _paused
