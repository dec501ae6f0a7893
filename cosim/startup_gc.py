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
leaves about 200,000 unreachable objects, 33 MB, that a freeze would keep.

A thread that loads such objects beside a run (cosim.beside: a controller's compiled
code, loaded while it steps) holds collection back the same way from `hold` to
`let_go`, through a `resume` that comes meanwhile: collection comes back, after a
freeze, once neither the pause nor any hold is left. Standard library only, so that
it is cheap to import first.
"""

from __future__ import annotations

import gc
import threading

# objects made since the pause (gc.get_count()[0]) at tick 0, measured: lane_change in process
# 91,000; satory_nominal with the compiled controller loaded from numba's cache 223,000, with
# numba compiling it 503,000
COLLECT_FIRST_ABOVE = 300_000

_lock = threading.Lock()
_paused = False   # pause() holds collection back until resume()
_holds = 0        # threads beside a run hold it back until their let_go()
_off = False      # this module turned collection off, and turns it back on
_freeze = False   # freeze what exists when it does


def pause() -> None:
    """Stop automatic collection until `resume` (nothing if it is off already)."""
    global _paused
    with _lock:
        if not _paused and _stop():
            _paused = True


def resume(freeze: bool = False) -> None:
    """Collect automatically again (nothing unless `pause` stopped it); while a thread holds
    it back (`hold`), once the last one lets go.

    Args:
        freeze: first move every object that exists then out of the collected generations
            (after a full collection when more than COLLECT_FIRST_ABOVE were made).
    """
    global _paused, _freeze
    with _lock:
        if not _paused:
            return
        _paused = False
        _freeze = _freeze or freeze
        _restart_when_free()


def hold() -> bool:
    """Stop automatic collection until `let_go` (a thread beside the run loading what lives as
    long as the process); False, and nothing to let go, when it is off already by another's
    choice."""
    global _holds
    with _lock:
        if not _stop():
            return False
        _holds += 1
        return True


def let_go() -> None:
    """End a `hold`: collection comes back, after a freeze, once no pause or hold is left."""
    global _holds, _freeze
    with _lock:
        _holds -= 1
        _freeze = True
        _restart_when_free()


def _stop() -> bool:
    """Turn collection off for this module; False when another turned it off."""
    global _off
    if _off:
        return True
    if not gc.isenabled():
        return False
    gc.disable()
    _off = True
    return True


def _restart_when_free() -> None:
    global _off, _freeze
    if not _off or _paused or _holds:
        return
    if _freeze:
        if gc.get_count()[0] > COLLECT_FIRST_ABOVE:
            gc.collect()
        gc.freeze()
    _off = _freeze = False
    gc.enable()


def paused() -> bool:
    """Whether `pause` holds collection back now."""
    return _paused
