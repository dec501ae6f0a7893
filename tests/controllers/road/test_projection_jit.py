"""The compiled window projection (numba, the `jit` extra) against the interpreted one, bit for bit.

Unit level: every field of foot() on random windows, on their vertices, far
off and beyond both ends. Controller level: a backstepping closed loop with
either path (the jit_mode fixture: tests/controllers/conftest.py). Run level: `cosim run` over Zenoh with the compiled path gives
the same signals.csv bytes as in-process without it. And the switch: COSIM_JIT
off, on without numba (a clear error), a disagreeing kernel (a warning, then
the interpreted path).
"""

from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest

from controllers.backstepping.component import BacksteppingController
from controllers.tracking import InputReader
from controllers.trajectory import FIELDS
from cosim.component import ComponentError
from controllers.linear_plant import LinearPlant
from controllers.road.projection import FEET_SIZE, PreparedWindow, cg_and_preview, compiled_kernel, foot, point_at
from controllers.vehicle_params import VehicleParams
from tests.controllers.backstepping.test_fast_paths import random_windows
from tests.helpers.jit_gates import one_bit_off
from tests.helpers.closed_loop import CirclePath, make_window, run_closed_loop

numba = pytest.importorskip("numba")


def same(a, b) -> bool:
    """Equal bit for bit and type for type (repr tells -0.0 from 0.0, 0 from 0.0, np.float64 from float)."""
    return repr(a) == repr(b)


def test_numpy_and_int_inputs_give_floats_as_the_interpreted_path_gives_for_floats(jit_mode):
    assert jit_mode("on") is not None
    window = make_window(CirclePath(30.0), 0.0)
    compiled, interpreted = PreparedWindow(window), PreparedWindow(window, compiled=False)
    assert same(foot(compiled, np.float64(2.5), 1), foot(interpreted, 2.5, 1.0))
    assert same(cg_and_preview(compiled, np.float64(1.0), 0, np.float64(0.1), 5),
                cg_and_preview(interpreted, 1.0, 0.0, 0.1, 5.0))


def test_a_window_of_coincident_points_gives_the_same_on_both_paths(jit_mode):
    assert jit_mode("on") is not None
    matrix = np.array([np.full(8, 3.0), np.full(8, -1.0), np.linspace(0.0, 0.3, 8), np.zeros(8),
                       np.arange(8.0), np.ones(8), np.zeros(8)])      # all points at (3, -1), s increasing
    compiled, interpreted = PreparedWindow(matrix), PreparedWindow(matrix, compiled=False)
    for point in ((3.0, -1.0), (5.0, 2.0), (0.0, 0.0)):
        assert same(cg_and_preview(compiled, *point, 0.4, 5.0), cg_and_preview(interpreted, *point, 0.4, 5.0))


def _verdict(reader, plant, signals, t):
    """What InputReader.read makes of a window: the error message, or the CG's and preview's feet."""
    try:
        _, prepared = reader.read(plant | signals, t)
    except ComponentError as error:
        return str(error)
    if prepared is None:
        return None
    assert (prepared.compiled is not None) == reader._compiled
    return cg_and_preview(prepared, plant["x"], plant["y"], plant["psi"], 5.0)


def test_the_readers_compiled_check_refuses_and_accepts_what_the_interpreted_one_does(jit_mode):
    # the compiled path tests a new window in checked_pack; the interpreted one with numpy
    rng = np.random.default_rng(5)
    plant = {"x": 0.5, "y": 0.3, "psi": 0.05, "vx": 5.0, "vy": 0.0, "r": 0.0}
    cases = refused = 0
    for window in random_windows(rng):
        for trial in range(12):
            signals = {name: np.array(value) for name, value in window.to_signals("ref").items()}
            name, index = list(signals)[trial % 7], int(rng.integers(0, 64))
            if trial % 4 == 1:
                signals[name][index] = (math.nan, math.inf, -math.inf)[trial % 3]
            elif trial % 4 == 2:                              # s not increasing at one point
                signals["ref_s"][index] = signals["ref_s"][max(index - 1, 0)]
            elif trial % 4 == 3:
                signals["ref_s"][index] = signals["ref_s"][index] - 3.0
            verdicts = []
            for mode in ("off", "on"):
                jit_mode(mode)
                verdicts.append(_verdict(InputReader(), plant, signals, 0.5))
            assert same(verdicts[0], verdicts[1]), (trial, name, index)
            cases += 1
            refused += isinstance(verdicts[0], str)
    assert cases == 120 and 40 <= refused <= 90  # both kinds, by the construction above
    jit_mode("on")
    matrix = np.array([getattr(window, name) for name, _, _ in FIELDS])
    checked = PreparedWindow.checked(matrix, True)
    assert checked is not None and checked.compiled is not None   # the quick test's own path
    assert PreparedWindow.checked(np.array(matrix[:6]), True) is None    # not the 7 fields
    assert PreparedWindow.checked(np.array(matrix[:6]), False) is None


def test_compiled_foot_equals_the_interpreted_one_bit_for_bit(jit_mode):
    assert jit_mode("on") is not None
    rng = np.random.default_rng(21)
    compared = beyond = 0
    for window in random_windows(rng):
        compiled, interpreted = PreparedWindow(window), PreparedWindow(window, compiled=False)
        assert compiled.compiled is not None and interpreted.compiled is None
        lo, hi = np.min(window.x) - 30, np.max(window.x) + 30
        bottom, top = np.min(window.y) - 30, np.max(window.y) + 30
        points = [(rng.uniform(lo, hi), rng.uniform(bottom, top)) for _ in range(300)]
        points += [(float(window.x[k]), float(window.y[k])) for k in range(64)]       # on the vertices
        points += [(window.x[k] + rng.normal(0, 0.2), window.y[k] + rng.normal(0, 0.2))
                   for k in rng.integers(0, 64, 200)]
        for px, py in points:
            px, py = float(px), float(py)
            expected = foot(interpreted, px, py, 0)
            assert same(foot(compiled, px, py, 0), expected), (px, py)
            assert same(foot(compiled, px, py), foot(interpreted, px, py)), (px, py)
            psi, ls = float(rng.uniform(-4.0, 4.0)), float(rng.uniform(0.5, 15.0))
            pair = cg_and_preview(interpreted, px, py, psi, ls)
            assert same(cg_and_preview(compiled, px, py, psi, ls), pair)
            assert same(_finished_feet(compiled, px, py, psi, ls), pair), (px, py, psi, ls)
            compared += 1
            beyond += expected[9] != 0
    assert compared > 5000 and beyond > 200        # both ends' extrapolation reached


def _finished_feet(window: PreparedWindow, x: float, y: float, psi: float, ls: float) -> tuple:
    """cg_and_preview as a compiled step takes it: cg_and_preview_into's buffer, then finished on it."""
    kernel, feet = compiled_kernel(), np.full(FEET_SIZE, np.nan)
    dx_cg, dy_cg, dx_preview, dy_preview = window.compiled_feet(x, y, psi, ls, feet)
    preview_x, preview_y = feet[24:26].tolist()
    return (kernel.finished(feet, 0, x, y, math.hypot(dx_cg, dy_cg)),
            kernel.finished(feet, 12, preview_x, preview_y, math.hypot(dx_preview, dy_preview)))


def test_backstepping_closed_loop_is_the_same_on_both_paths(jit_mode):
    def run() -> dict[str, bytes]:
        controller = BacksteppingController(lateral_law="feedforward", adaptive=True, mu0=0.6)
        plant = LinearPlant(VehicleParams(), substeps=2, vx0=9.0, y0=0.4, mu=0.9)
        record = run_closed_loop(controller, plant, CirclePath(40.0), 15.0)
        return {name: values.tobytes() for name, values in record.items()}

    assert jit_mode("off") is None
    interpreted = run()
    assert jit_mode("on") is not None
    assert same(run(), interpreted)


def test_zenoh_run_with_the_compiled_path_gives_the_in_process_bytes(tmp_path):
    def cosim(transport: str, jit: str) -> bytes:
        out = tmp_path / f"{transport}-{jit}"
        env = dict(os.environ, COSIM_JIT=jit)
        subprocess.run([sys.executable, "-m", "cosim.cli.app", "run", "lane_change", "--transport", transport,
                        "--set", "duration=4", "--no-figures", "--out", str(out)],
                       env=env, check=True, capture_output=True, timeout=120)
        return (out / "signals.csv").read_bytes()

    assert cosim("zenoh", "on") == cosim("inproc", "off")


def test_off_keeps_the_interpreted_path(jit_mode):
    assert jit_mode("off") is None
    assert PreparedWindow(make_window(CirclePath(30.0), 0.0)).compiled is None


def test_on_without_numba_is_a_clear_error(jit_mode, monkeypatch):
    import controllers.road

    monkeypatch.setitem(sys.modules, "controllers.road.projection_jit", None)   # as if numba were missing
    monkeypatch.delattr(controllers.road, "projection_jit", raising=False)
    with pytest.raises(ImportError, match=r"COSIM_JIT=on: the compiled projection needs numba "
                                          r"\(pip install 'cosim\[jit\]'\)"):
        jit_mode("on")
    assert jit_mode("auto") is None


def test_an_unknown_mode_names_the_variable_and_value(jit_mode):
    with pytest.raises(ValueError, match=r"COSIM_JIT='fast': expected auto, on or off"):
        jit_mode("fast")


def _disagreeing(monkeypatch) -> list[str]:
    """projection_jit.foot_fields made one bit off; its recompile() recorded, not run. Returns the record."""
    from controllers.road import projection_jit
    return one_bit_off(monkeypatch, projection_jit, "foot_fields")


def test_a_kernel_that_disagrees_is_compiled_afresh_once_then_not_used(jit_mode, monkeypatch):
    calls = _disagreeing(monkeypatch)
    with pytest.warns(RuntimeWarning, match=r"the compiled projection is not used: at \(-20.0, -60.0\) it gives"):
        assert jit_mode("auto") is None
    assert calls == ["recompile"]       # a stale numba cache (hermite.py edited) is rebuilt before giving up


def test_on_with_a_kernel_that_disagrees_is_an_error(jit_mode, monkeypatch):
    _disagreeing(monkeypatch)
    with pytest.raises(RuntimeError, match=r"COSIM_JIT=on: the compiled projection disagrees with the "
                                           r"interpreted one: at \(-20.0, -60.0\)"):
        jit_mode("on")


class _BrokenNumba:
    """A meta-path finder that makes importing projection_jit fail as a broken numba install would."""

    def find_spec(self, name, path=None, target=None):
        if name == "controllers.road.projection_jit":
            raise RuntimeError("numba: LLVM failed to initialise")
        return None


def test_a_numba_that_does_not_load_warns_in_auto_and_is_an_error_in_on(jit_mode, monkeypatch):
    import controllers.road

    monkeypatch.delitem(sys.modules, "controllers.road.projection_jit", raising=False)
    monkeypatch.delattr(controllers.road, "projection_jit", raising=False)
    monkeypatch.setattr(sys, "meta_path", [_BrokenNumba(), *sys.meta_path])
    with pytest.warns(RuntimeWarning, match=r"numba does not load: RuntimeError\('numba: LLVM failed"):
        assert jit_mode("auto") is None
    with pytest.raises(RuntimeError, match=r"COSIM_JIT=on: numba does not load: RuntimeError"):
        jit_mode("on")


def test_a_compiled_window_makes_its_field_lists_only_when_asked_and_they_are_the_same(jit_mode):
    jit_mode("on")
    for window in random_windows(np.random.default_rng(9)):
        compiled, interpreted = PreparedWindow(window), PreparedWindow(window, compiled=False)
        assert compiled.compiled is not None and "s" not in vars(compiled)     # not made per window
        for s in np.linspace(window.s[0] - 3.0, window.s[-1] + 3.0, 40).tolist():
            assert same(point_at(compiled, s), point_at(interpreted, s)), s
        assert same((compiled.x, compiled.s, compiled.a), (interpreted.x, interpreted.s, interpreted.a))
        with pytest.raises(AttributeError, match="no attribute 'nope'"):
            compiled.nope  # noqa: B018
