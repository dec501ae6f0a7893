"""The controllers' fast per-tick paths against plain reference implementations.

Exact nearest-chord search vs measuring every chord (bit-identical), the scalar
lateral law vs the numpy one, the whole backstepping step vs a literal
transcription (tests/helpers/reference_controllers.py) over closed-loop runs, and the
input reader's window cache (reuse, change in place, bad window, empty window).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.backstepping.component import BacksteppingController
from controllers.backstepping.lateral import (AdaptationSettings, LateralGains, LateralMeasurement,
                                             ScalarLateralLaw, lateral_law)
from controllers.tracking import InputReader
from controllers.linear_plant import LinearPlant
from controllers.trajectory import TrajectoryWindow
from controllers.vehicle_params import VehicleParams
from controllers.road.projection import PreparedWindow, foot, project
from cosim.component import ComponentError
from tests.helpers.reference_controllers import ReferenceBackstepping, nearest_chord_brute, project_reference
from tests.helpers.closed_loop import CirclePath, LinePath, make_window

PARAMS = VehicleParams()


def window_from_curvature(kappa: np.ndarray, step: float, x0=0.0, y0=0.0, psi0=0.0) -> TrajectoryWindow:
    """A window whose heading integrates `kappa` (midpoint rule) with points `step` apart."""
    psi = psi0 + np.concatenate([[0.0], np.cumsum(step * 0.5 * (kappa[1:] + kappa[:-1]))])
    mid = 0.5 * (psi[1:] + psi[:-1])
    x = x0 + np.concatenate([[0.0], np.cumsum(step * np.cos(mid))])
    y = y0 + np.concatenate([[0.0], np.cumsum(step * np.sin(mid))])
    n = kappa.size
    return TrajectoryWindow(x=x, y=y, psi=psi, kappa=kappa, s=step * np.arange(n),
                            v=np.linspace(5.0, 8.0, n), a=np.full(n, 0.2))


def random_windows(rng: np.random.Generator):
    """Straight, curved, S-shaped, hairpin (comes back beside itself) and spiral windows."""
    n = 64
    yield window_from_curvature(np.zeros(n), 0.5)
    yield window_from_curvature(np.full(n, 1 / 30.0), 1.0, 10.0, -4.0, 0.7)
    yield window_from_curvature(0.05 * np.sin(np.linspace(0, 6, n)), 0.8, -3.0, 2.0, -2.0)
    yield window_from_curvature(np.where(np.abs(np.arange(n) - 32) <= 2, 1 / 0.75, 0.0), 0.5, 0.0, 0.0, 0.3)
    yield window_from_curvature(np.linspace(0.05, 0.6, n), 0.4)
    for _ in range(5):
        yield window_from_curvature(np.cumsum(rng.normal(0.0, 0.03, n)), rng.uniform(0.3, 1.5),
                                    *rng.uniform(-50, 50, 2), rng.uniform(-4, 4))


def test_nearest_chord_is_the_global_minimum_bit_for_bit():
    rng = np.random.default_rng(7)
    checked = 0
    for window in random_windows(rng):
        prepared = PreparedWindow(window, compiled=False)     # the interpreted path's search
        lo, hi = np.min(window.x), np.max(window.x)
        bottom, top = np.min(window.y), np.max(window.y)
        points = [(rng.uniform(lo - 5, hi + 5), rng.uniform(bottom - 5, top + 5)) for _ in range(150)]
        points += [(window.x[k] + rng.normal(0, 0.3), window.y[k] + rng.normal(0, 0.3))
                   for k in rng.integers(0, 64, 100)]
        points += [(window.x[k], window.y[k]) for k in range(64)]          # on the vertices
        for px, py in points:
            expected = nearest_chord_brute(window, px, py)
            for hint in (0, 62, int(rng.integers(-3, 70))):
                assert prepared.nearest_chord(px, py, hint) == expected, (px, py, hint)
                checked += 1
    assert checked > 5000


def test_tracked_chord_follows_moving_points_bit_for_bit():
    rng = np.random.default_rng(5)
    renewed = 0
    for window in random_windows(rng):
        prepared = PreparedWindow(window, compiled=False)
        for slot in range(4):     # each slot a point walking along the window, with jumps now and then
            k = int(rng.integers(0, 60))
            px, py = window.x[k], window.y[k]
            for step in range(200):
                if step % 50 == 49:
                    px, py = px + rng.normal(0, 5.0), py + rng.normal(0, 5.0)
                else:
                    px, py = px + rng.normal(0.05, 0.08), py + rng.normal(0.0, 0.08)
                before = prepared.certs[slot]
                assert prepared.tracked_chord(px, py, slot) == nearest_chord_brute(window, px, py)
                renewed += prepared.certs[slot] is not before
    assert 0 < renewed < 0.5 * 4 * 200 * 10     # the certificate is reused more often than not


def test_nearest_chord_tie_goes_to_the_first_chord_whatever_the_hint():
    window = TrajectoryWindow(x=np.array([-1.0, 0.0, 1.0]), y=np.array([1.0, 0.0, 1.0]),
                              psi=np.array([-0.8, 0.0, 0.8]), kappa=np.zeros(3), s=np.array([0.0, 1.5, 3.0]),
                              v=np.ones(3), a=np.zeros(3))
    prepared = PreparedWindow(window, compiled=False)
    for hint in (0, 1):
        assert prepared.nearest_chord(0.0, 1.0, hint) == (0, 0.5)


@pytest.mark.parametrize("compiled", [False, True], ids=["interpreted", "compiled"])
def test_projection_fields_match_the_reference_on_every_window(compiled, jit_mode):
    if compiled:
        pytest.importorskip("numba")
    jit_mode("on" if compiled else "off")
    rng = np.random.default_rng(11)
    for window in random_windows(rng):
        prepared = PreparedWindow(window, compiled=compiled)
        assert (prepared.compiled is not None) == compiled
        for k in rng.integers(0, 64, 40):
            px, py = window.x[k] + rng.normal(0, 0.5), window.y[k] + rng.normal(0, 0.5)
            expected = project_reference(window, px, py)
            fast = project(prepared, px, py)
            for name, value in expected.items():
                assert getattr(fast, name) == value, name
            assert foot(prepared, px, py, int(k) % 4) == tuple(fast.__dict__.values())


@pytest.mark.parametrize("law, target, adaptation", [
    ("faithful", "cg", "paper"), ("feedforward", "cg", "paper"), ("feedforward", "preview", "paper"),
    ("faithful", "cg", "robust"), ("feedforward", "cg", "robust")])
def test_scalar_lateral_law_matches_the_numpy_law(law, target, adaptation):
    rng = np.random.default_rng(3)
    gains = LateralGains(ke=(1.3, 0.7), kz=4.0, gz=2.0e5, ls=6.0, law=law, ff_target=target)
    settings = AdaptationSettings(law=adaptation, fwy_max=100.0, a_excite=0.3, v_adapt=2.0)
    scalar = ScalarLateralLaw(PARAMS, gains, settings)
    gated = 0
    for _ in range(300):
        m = LateralMeasurement(y_l=rng.normal(0, 0.5), psi_l=rng.normal(0, 0.1), vy=rng.normal(0, 0.5),
                               r=rng.normal(0, 0.2), vx=rng.uniform(0.2, 15.0), vx_dot=rng.normal(0, 1),
                               rho=rng.normal(0, 0.02), rho_dot=rng.normal(0, 0.01))
        mu_hat = rng.uniform(0.2, 1.2)
        ref = lateral_law(m, mu_hat, PARAMS, gains, g_mu=0.5, adaptation=settings)
        got = scalar.command(m.y_l, m.psi_l, m.vy, m.r, m.vx, m.vx_dot, m.rho, m.rho_dot, mu_hat, 0.5)
        expected = (ref.delta, *ref.alpha, *ref.z, ref.mu_hat_dot, ref.V2)
        assert got == pytest.approx(expected, rel=1e-11, abs=1e-12)
        gated += ref.mu_hat_dot == 0.0
    # the robust law's conditions both freeze and let through some of the random cases
    assert (gated == 0) if adaptation == "paper" else (30 < gated < 270)


def _frozen(window: TrajectoryWindow) -> dict[str, np.ndarray]:
    """The window's ports as the in-process master hands them over (read-only copies)."""
    signals = {}
    for name, value in window.to_signals("ref").items():
        signals[name] = np.array(value)
        signals[name].flags.writeable = False
    return signals


@pytest.mark.parametrize("settings, path, start", [
    ({}, LinePath(), {"y0": 1.0, "psi0": 0.05, "vx0": 8.0}),
    ({"adaptive": True, "mu0": 0.8}, CirclePath(50.0), {"vx0": 10.0, "y0": 0.3, "mu": 0.9}),
    ({"lateral_law": "feedforward", "adaptive": True, "mu0": 0.4}, CirclePath(40.0), {"vx0": 9.0}),
    ({"lateral_law": "feedforward", "adaptive": True, "adaptation": "robust", "mu0": 0.6,
      "fwy_max": 50.0}, CirclePath(40.0), {"vx0": 9.0, "y0": 0.2}),
    ({"lateral_law": "feedforward", "ff_target": "preview", "ke": [1.0, 2.0]}, CirclePath(80.0), {"vx0": 11.0}),
    ({"max_delta": 0.05, "max_delta_rate": 0.1, "max_torque": 500.0}, CirclePath(30.0), {"vx0": 6.0, "y0": 2.0}),
])
def test_backstepping_step_matches_the_reference_in_closed_loop(settings, path, start):
    controller = BacksteppingController(**settings)
    reference = ReferenceBackstepping(controller)
    plant = LinearPlant(PARAMS, substeps=2, **start)
    worst = 0.0
    for k in range(2000):
        state = plant.outputs()
        if k % 10 == 0:         # a new window every 0.1 s, alternately frozen (master) and writeable
            window = make_window(path, path.sigma_of(state["x"], state["y"]) - 5.0, v=10.0)
            signals = _frozen(window) if k % 20 == 0 else window.to_signals("ref")
        inputs = state | signals
        fast = controller.step(0.01 * k, inputs)
        slow = reference.step(0.01 * k, inputs)
        assert list(fast) == list(slow)
        for name, value in slow.items():
            worst = max(worst, abs(fast[name] - value) / max(1.0, abs(value)))
        plant.step(0.01, fast["delta"], fast["torque"])
    assert worst <= 1e-9


def _reader(jit_mode, mode: str) -> InputReader:
    """An InputReader on the interpreted window path (off) or the compiled one (on)."""
    if mode == "on":
        pytest.importorskip("numba")
    jit_mode(mode)
    reader = InputReader()
    assert reader._compiled == (mode == "on")
    return reader


@pytest.mark.parametrize("mode", ["off", "on"])
def test_input_reader_reuses_a_window_only_while_it_is_unchanged(jit_mode, mode):
    reader = _reader(jit_mode, mode)
    plant = {"x": 0.0, "y": 0.2, "psi": 0.0, "vx": 5.0, "vy": 0.0, "r": 0.0}
    signals = make_window(LinePath(), -5.0).to_signals("ref")
    _, first = reader.read(plant | signals, 0.0)
    assert reader.read(plant | signals, 0.01)[1] is first                       # same arrays, same bytes
    assert reader.read(plant | {k: v.copy() for k, v in signals.items()}, 0.02)[1] is first
    signals["ref_y"][:] = 1.0                                                     # changed in place
    _, moved = reader.read(plant | signals, 0.03)
    assert moved is not first and moved.y == [1.0] * 64
    frozen = _frozen(make_window(LinePath(), -5.0))
    _, kept = reader.read(plant | frozen, 0.04)
    assert reader.read(plant | frozen, 0.05)[1] is kept
    bad = dict(frozen, ref_s=np.zeros(64) + np.arange(64) % 3)
    with pytest.raises(ComponentError, match=r"bad trajectory window at t = 0.06: ref_s must increase"):
        reader.read(plant | bad, 0.06)
    with pytest.raises(ComponentError, match=r"at t = 0.07: ref_s must increase"):
        reader.read(plant | bad, 0.07)                                            # not cached as good
    short = dict(frozen, ref_v=np.ones(10))
    with pytest.raises(ComponentError, match=r"at t = 0.071: ref_v: expected 64 values, got shape \(10,\)"):
        reader.read(plant | short, 0.071)
    holed = dict(frozen, ref_kappa=np.where(np.arange(64) == 3, np.inf, 0.0))
    with pytest.raises(ComponentError, match=r"at t = 0.072: ref_kappa\[3\] is not finite: inf"):
        reader.read(plant | holed, 0.072)
    empty = {k: np.zeros(64) for k in frozen}
    assert reader.read(plant | empty, 0.08)[1] is None
    with pytest.raises(ComponentError, match=r"input 'vy' is not finite at t = 0.09: nan"):
        reader.read(plant | {"vy": math.nan} | frozen, 0.09)


@pytest.mark.parametrize("mode", ["off", "on"])
def test_input_reader_takes_read_only_views_of_a_read_only_block_by_identity(jit_mode, mode):
    # the in-process master hands out read-only views of one read-only copy of the planner's arrays
    reader = _reader(jit_mode, mode)
    plant = {"x": 0.0, "y": 0.2, "psi": 0.0, "vx": 5.0, "vy": 0.0, "r": 0.0}
    signals = make_window(LinePath(), -5.0).to_signals("ref")
    block = np.array(list(signals.values()))
    block.flags.writeable = False
    views = dict(zip(signals, block))
    _, first = reader.read(plant | views, 0.0)
    assert reader._frozen and reader.read(plant | views, 0.01)[1] is first
    writable = np.array(list(signals.values()))       # views of a block that can still change
    loose = {name: row.view() for name, row in zip(signals, writable)}
    for row in loose.values():
        row.flags.writeable = False
    _, second = reader.read(plant | loose, 0.02)
    assert not reader._frozen
    writable[1] = 1.0                                  # changed in place under the read-only views
    _, moved = reader.read(plant | loose, 0.03)
    assert moved is not second and moved.y == [1.0] * 64
