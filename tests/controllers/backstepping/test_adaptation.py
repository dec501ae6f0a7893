"""Robust friction adaptation against the paper's law, in closed loop with the linear plant.

Each test runs both laws on the same plant and disturbance and asserts both
sides of the comparison: side wind on a straight road (the paper's estimate
drifts to its floor, the robust one does not move), a friction drop (both
follow it), the least-squares residual of the faithful lateral law (the
paper's estimate drifts on a curve at the true friction), a stop (the robust
estimate is frozen below v_adapt). Plus the dead zone's radius and the
settings' checks.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.backstepping.component import BacksteppingController
from controllers.backstepping.lateral import AdaptationSettings
from controllers.linear_plant import LinearPlant
from controllers.vehicle_params import VehicleParams
from cosim.component import ComponentError
from tests.helpers.closed_loop import CirclePath, LinePath, make_window

PARAMS = VehicleParams()
DT = 0.01


def adaptive(adaptation: str, mu0: float, **settings) -> BacksteppingController:
    """The scenarios' adaptive controller (feedforward law, ke = 4, kz = 20, floor 0.3)."""
    options = dict(adaptive=True, adaptation=adaptation, lateral_law="feedforward", mu0=mu0,
                   mu_min=0.3, ke=4.0, kz=20.0)
    return BacksteppingController(**(options | settings))


def run(controller, path, duration: float, vx0: float = 10.0, wind=lambda t: 0.0,
        mu=lambda t: 1.0, v_ref=lambda t: 10.0) -> dict[str, np.ndarray]:
    """Closed loop with time-varying side wind, plant friction and reference speed.

    Args:
        controller: the controller under test; path: LinePath or CirclePath; duration: [s];
        vx0: initial speed; wind, mu, v_ref: functions of t (side force [N], friction, speed).
    Returns arrays t, vx and every controller output, per step.
    """
    plant = LinearPlant(PARAMS, vx0=vx0, mu=mu(0.0), substeps=2)
    record: dict[str, list[float]] = {"t": [], "vx": []}
    for k in range(int(round(duration / DT)) + 1):
        t = k * DT
        state = plant.outputs()
        if k % 10 == 0:
            signals = make_window(path, path.sigma_of(state["x"], state["y"]) - 5.0,
                                  v=v_ref(t)).to_signals("ref")
        outputs = (controller.initialize if k == 0 else controller.step)(t, state | signals)
        for name, value in outputs.items():
            record.setdefault(name, []).append(value)
        record["t"].append(t)
        record["vx"].append(state["vx"])
        plant.mu = mu(t)
        plant.step(DT, outputs["delta"], outputs["torque"], 0.0, wind(t))
    return {name: np.array(values) for name, values in record.items()}


def test_side_wind_on_a_straight_road_drifts_the_paper_estimate_not_the_robust_one():
    wind = lambda t: 1500.0                              # noqa: E731  (0.1 g, steady)
    paper = run(adaptive("paper", mu0=1.0), LinePath(), 15.0, wind=wind)
    robust = run(adaptive("robust", mu0=1.0), LinePath(), 15.0, wind=wind)
    assert paper["mu_hat"][-1] < 0.5                    # reads the wind as lost grip: 1.0 -> 0.42 in 15 s
    assert np.all(robust["mu_hat"] == 1.0)             # no excitation on a straight road: frozen
    for result in (paper, robust):                     # both still hold the lane against the wind
        assert np.max(np.abs(result["yc_cg"])) < 0.02
    # without the excitation condition the consistent regressor alone drifts as well
    blind = run(adaptive("robust", mu0=1.0, a_excite=0.0), LinePath(), 15.0, wind=wind)
    assert blind["mu_hat"][-1] < 0.9


def test_faithful_lateral_law_residual_drifts_the_paper_estimate_on_a_curve():
    """At the true friction on R = 60 m the least-squares residual alone moves the paper's estimate."""
    settings = dict(lateral_law="faithful", mu0=1.0)
    paper = run(adaptive("paper", **settings), CirclePath(60.0), 10.0)
    robust = run(adaptive("robust", **settings), CirclePath(60.0), 10.0)
    assert paper["mu_hat"][-1] == 0.3
    assert np.max(np.abs(robust["mu_hat"] - 1.0)) < 0.02


@pytest.mark.parametrize("adaptation", ["paper", "robust"])
def test_estimate_follows_a_friction_drop(adaptation):
    """Converged at mu = 1 on R = 60 m at 10 m/s (1.67 m/s^2), the road turns wet (0.5) at 5 s."""
    result = run(adaptive(adaptation, mu0=1.0), CirclePath(60.0), 30.0, mu=lambda t: 1.0 if t < 5.0 else 0.5)
    t, mu_hat = result["t"], result["mu_hat"]
    assert np.max(np.abs(mu_hat[t < 5.0] - 1.0)) < 0.01
    assert abs(mu_hat[-1] - 0.5) < 0.01
    assert np.all(np.diff(mu_hat[t > 6.0]) <= 1e-12)    # falls toward 0.5 without overshoot above
    assert np.max(np.abs(result["yc_cg"][t > 15.0])) < 0.01


def test_estimate_is_frozen_at_a_stop_while_the_paper_one_moves():
    """Braking on R = 60 m to 0.5 m/s under gusts; excitation gate off to isolate the speed schedule."""
    gusts = lambda t: 1500.0 if 6.0 < t % 8.0 < 8.0 else 0.0     # noqa: E731
    speed = lambda t: max(0.5, 10.0 - 0.6 * t)                   # noqa: E731
    paper = run(adaptive("paper", mu0=1.0), CirclePath(60.0), 30.0, wind=gusts, v_ref=speed)
    robust = run(adaptive("robust", mu0=1.0, a_excite=0.0, v_adapt=3.0), CirclePath(60.0), 30.0,
                 wind=gusts, v_ref=speed)
    for result in (paper, robust):
        assert result["vx"][-1] < 0.6
    slow = robust["vx"][:-1] < 3.0          # mu_hat_dot of step k acts at step k + 1
    assert slow.sum() > 1000
    assert np.all(np.diff(robust["mu_hat"])[slow] == 0.0)
    assert np.count_nonzero(np.diff(robust["mu_hat"])[~slow]) > 100    # ... it did adapt above that speed
    paper_slow = np.diff(paper["mu_hat"])[paper["vx"][:-1] < 3.0]
    assert np.count_nonzero(paper_slow) > 100


def test_dead_zone_radius_is_the_lyapunov_bound():
    """adapts() switches exactly at kz |z| = |D| fwy_max + |r_ls| (speed and excitation satisfied)."""
    settings = AdaptationSettings(law="robust", fwy_max=1500.0, a_excite=0.5, v_adapt=3.0)
    d_norm = math.hypot(*PARAMS.d())
    radius = (d_norm * 1500.0 + 0.2) / 20.0
    assert radius == pytest.approx(0.0608, abs=1e-4)
    assert not settings.adapts(10.0, 0.2, radius * (1 - 1e-9), 0.2, d_norm, 20.0)
    assert settings.adapts(10.0, 0.2, radius * (1 + 1e-9), 0.2, d_norm, 20.0)
    assert not settings.adapts(2.9, 1.0, 1.0, 0.0, d_norm, 20.0)            # below v_adapt
    assert not settings.adapts(10.0, 0.049, 1.0, 0.0, d_norm, 20.0)          # |vx r| = 0.49
    assert settings.adapts(10.0, -0.05, 1.0, 0.0, d_norm, 20.0)


def test_robust_runs_are_bit_identical():
    results = [run(adaptive("robust", mu0=0.7), CirclePath(40.0), 3.0, wind=lambda t: 800.0 * (t > 1.0))
               for _ in range(2)]
    for name in results[0]:
        assert np.array_equal(results[0][name], results[1][name]), name
    assert results[0]["mu_hat"][-1] != 0.7


def test_bad_adaptation_settings_give_clear_errors():
    with pytest.raises(ComponentError, match=r"adaptation must be one of \('paper', 'robust'\), got 'sigma'"):
        BacksteppingController(adaptive=True, adaptation="sigma")
    with pytest.raises(ComponentError, match=r"fwy_max must be a number >= 0, got -1.0"):
        BacksteppingController(adaptive=True, adaptation="robust", fwy_max=-1.0)
    with pytest.raises(ComponentError, match=r"v_adapt must be a number >= 0, got nan"):
        BacksteppingController(adaptation="robust", v_adapt=float("nan"))
    with pytest.raises(ComponentError, match=r"a_excite must be a number >= 0, got True"):
        AdaptationSettings(a_excite=True)
