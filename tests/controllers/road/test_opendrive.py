"""OpenDRIVE roads (controllers.road.opendrive) against analytic geometry, and their errors."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from controllers.road.builders import road_from_spec
from controllers.road.opendrive import lane_borders, read_road
from controllers.spec import SpecError
from tests.helpers.paths import SCENARIOS_DIR

LOOP = SCENARIOS_DIR / "opendrive_loop.xodr"
LANES = """<lanes>{offset}<laneSection s="0"><left><lane id="1" type="driving"><width sOffset="0" a="3" b="0" c="0" d="0"/></lane></left>
<center><lane id="0" type="none"/></center><right>
<lane id="-1" type="driving"><width sOffset="0" a="{w}" b="0" c="{wc}" d="0"/></lane>
<lane id="-2" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane></right></laneSection></lanes>"""


def write_xodr(tmp_path: Path, geometry: str, length: float, w: float = 3.0, wc: float = 0.0,
               offset: str = "", rule: str = "RHT") -> Path:
    """A one-road OpenDRIVE file with `geometry` (the records inside <planView>)."""
    text = (f'<?xml version="1.0"?><OpenDRIVE><header revMajor="1" revMinor="6"/>'
            f'<road id="7" length="{length!r}" junction="-1" rule="{rule}"><planView>{geometry}</planView>'
            f'{LANES.format(offset=offset, w=w, wc=wc)}</road></OpenDRIVE>')
    path = tmp_path / "road.xodr"
    path.write_text(text)
    return path


def spec(path: Path, **extra) -> dict:
    return {"opendrive": str(path), "road": "7", **extra}


def test_arc_curvature_and_lane_centre_radius(tmp_path):
    k, length = 1 / 80.0, 120.0
    file = write_xodr(tmp_path, f'<geometry s="0" x="10" y="5" hdg="0.3" length="{length}"><arc curvature="{k}"/></geometry>', length)
    ref = read_road(file, "7").plan
    s = np.linspace(0, length, 25)
    x, y, psi, kappa, dk = ref.evaluate(s)
    cx, cy = 10 - math.sin(0.3) / k, 5 + math.cos(0.3) / k     # centre of the circle
    np.testing.assert_allclose(np.hypot(x - cx, y - cy), 1 / k, atol=1e-9)
    np.testing.assert_allclose(psi, 0.3 + k * s, atol=1e-12)
    assert np.all(kappa == k) and np.all(dk == 0)
    road = road_from_spec(spec(file, lane=-1))                 # 1.5 m right of a left turn
    _, _, _, lane_kappa = road.reference.evaluate(np.linspace(0, road.length, 9))
    np.testing.assert_allclose(lane_kappa, 1 / (80.0 + 1.5), rtol=1e-12)
    assert road.length == pytest.approx((80.0 + 1.5) * k * length, rel=1e-12)


def test_spiral_curvature_rate_and_fresnel_end(tmp_path):
    k0, k1, length = 0.0, 0.02, 60.0
    file = write_xodr(tmp_path, f'<geometry s="0" x="0" y="0" hdg="0" length="{length}"><spiral curvStart="{k0}" curvEnd="{k1}"/></geometry>', length)
    ref = read_road(file, "7").plan
    s = np.linspace(0, length, 31)
    _, _, psi, kappa, dk = ref.evaluate(s)
    c = (k1 - k0) / length
    np.testing.assert_allclose(dk, c, rtol=1e-14)
    np.testing.assert_allclose(kappa, c * s, atol=1e-15)
    np.testing.assert_allclose(psi, 0.5 * c * s ** 2, atol=1e-13)
    n = np.arange(20)                                    # Fresnel integrals by their series
    fact = np.array([math.factorial(2 * i) for i in n], float)
    xe = np.sum((-1) ** n * (c / 2) ** (2 * n) * length ** (4 * n + 1) / (fact * (4 * n + 1)))
    x, _, _, _, _ = ref.evaluate([length])
    assert x[0] == pytest.approx(xe, abs=1e-9)


def test_poly3_and_param_poly3_parabola(tmp_path):
    """v = c u^2: curvature 2c / (1 + 4 c^2 u^2)^1.5 and arc length in closed form, three ways."""
    c, u_end = 0.01, 50.0
    arc = lambda u: (2 * c * u * math.sqrt(1 + (2 * c * u) ** 2) + math.asinh(2 * c * u)) / (4 * c)
    length = arc(u_end)
    records = [f'<poly3 a="0" b="0" c="{c}" d="0"/>',
               f'<paramPoly3 aU="0" bU="{u_end}" cU="0" dU="0" aV="0" bV="0" cV="{c * u_end ** 2}" dV="0" pRange="normalized"/>',
               f'<paramPoly3 aU="0" bU="{u_end / length}" cU="0" dU="0" aV="0" bV="0" cV="{c * (u_end / length) ** 2}" dV="0" pRange="arcLength"/>']
    for record in records:
        file = write_xodr(tmp_path, f'<geometry s="0" x="0" y="0" hdg="0" length="{length!r}">{record}</geometry>', length)
        ref = read_road(file, "7").plan
        u = np.linspace(0, u_end, 11)
        s = np.array([arc(v) for v in u])
        x, y, psi, kappa, dk = ref.evaluate(s)
        np.testing.assert_allclose(x, u, atol=1e-9)
        np.testing.assert_allclose(y, c * u ** 2, atol=1e-9)
        np.testing.assert_allclose(psi, np.arctan(2 * c * u), atol=1e-11)
        np.testing.assert_allclose(kappa, 2 * c / (1 + 4 * c * c * u * u) ** 1.5, rtol=1e-9)
        dkds = -24 * c ** 3 * u / (1 + 4 * c * c * u * u) ** 3     # d kappa/du over ds/du
        np.testing.assert_allclose(dk, dkds, atol=1e-12)


def test_lane_offset_and_width_polynomials_give_the_lane_centre(tmp_path):
    """Straight reference: the lane centre is y = t(s) exactly, its curvature t'' / (1 + t'^2)^1.5."""
    length, wc = 100.0, 2e-4
    offset = '<laneOffset s="0" a="0.5" b="0.001" c="0" d="0"/>'
    file = write_xodr(tmp_path, f'<geometry s="0" x="0" y="0" hdg="0" length="{length}"><line/></geometry>',
                      length, w=3.0, wc=wc, offset=offset)
    road = road_from_spec(spec(file, lane=-1, step=0.25))
    xs = np.linspace(0, length, 41)
    t = lambda s: 0.5 + 0.001 * s - 0.5 * (3.0 + wc * s * s)
    proj = [road.reference.project(x, t(x)) for x in xs]
    assert max(abs(p.lateral) for p in proj) < 1e-6
    d1, d2 = 0.001 - wc * xs, -wc
    np.testing.assert_allclose([p.kappa for p in proj], d2 / (1 + d1 ** 2) ** 1.5, rtol=1e-3, atol=1e-9)
    assert road.lanes == 1 and road.lane_width == pytest.approx(3.0 + wc * length ** 2 / 3, rel=2e-3)
    assert road_from_spec(spec(file, lane=-2)).lanes == 2     # lane -1 drives the same way on its left


def test_left_lanes_run_against_the_reference_and_lht_swaps(tmp_path):
    file = write_xodr(tmp_path, '<geometry s="0" x="0" y="0" hdg="0" length="50"><line/></geometry>', 50.0)
    x, y, psi, _ = road_from_spec(spec(file, lane=1)).reference.evaluate([0.0])
    assert (x[0], y[0]) == pytest.approx((50.0, 1.5)) and psi[0] == pytest.approx(math.pi)
    lht = write_xodr(tmp_path, '<geometry s="0" x="0" y="0" hdg="0" length="50"><line/></geometry>', 50.0, rule="LHT")
    x, y, psi, _ = road_from_spec(spec(lht, lane=-1)).reference.evaluate([0.0])
    assert (x[0], y[0]) == pytest.approx((50.0, -1.5)) and psi[0] == pytest.approx(math.pi)


def test_shipped_loop_closes_and_its_lanes_are_offset_loops():
    road = read_road(LOOP, "1")
    x, y, psi, kappa, _ = road.plan.evaluate(np.array([0.0, road.length]))
    assert math.hypot(x[1] - x[0], y[1] - y[0]) < 1e-9
    assert psi[1] - psi[0] == pytest.approx(2 * math.pi, abs=1e-12)
    for lane, d in ((-1, -1.75), (-2, -5.25), (1, 1.75)):
        lane_road = road_from_spec({"opendrive": str(LOOP), "road": 1, "lane": lane})
        assert lane_road.closed
        # an offset loop's length is the integral of 1 - kappa d: L - 2 pi d, in either direction
        assert lane_road.length == pytest.approx(road.length - d * 2 * math.pi, rel=1e-9)
    assert road_from_spec({"opendrive": str(LOOP), "road": 1, "lane": -2}).lanes == 2
    part = road_from_spec({"opendrive": str(LOOP), "road": 1, "lane": -1, "s_start": 100, "s_end": 900})
    assert not part.closed and part.length > 800.0


def test_lane_borders_are_parallel_to_the_reference_line():
    lines = dict((lid, (x, y)) for lid, x, y in lane_borders(LOOP, "1", step=5.0))
    assert sorted(lines) == [-2, -1, 0, 1]
    gaps = {lid: np.hypot(lines[lid][0] - lines[0][0], lines[lid][1] - lines[0][1]) for lid in (-2, -1, 1)}
    np.testing.assert_allclose(gaps[-2], 7.0, atol=1e-9)
    np.testing.assert_allclose(gaps[1], 3.5, atol=1e-9)


def test_generator_writes_the_shipped_file(tmp_path):
    out = tmp_path / "loop.xodr"
    subprocess.run([sys.executable, "-m", "scenarios.opendrive_loop", str(out)], check=True,
                   cwd=SCENARIOS_DIR.parent, capture_output=True)
    assert out.read_bytes() == LOOP.read_bytes()


@pytest.mark.parametrize("change, message", [
    ({"opendrive": "missing.xodr"}, "road.opendrive: cannot read 'missing.xodr'"),
    ({"road": "9"}, "road.road: no road with id '9'"),
    ({"lane": -3}, "has no lane -3 in its lane section at s = 0"),
    ({"lane": 0}, "road.lane: expected a non-zero OpenDRIVE lane id"),
    ({"s_end": 1e5}, "road: expected 0 <= s_start < s_end <= 2529.085"),
    ({"s_end": 2529.09}, "road: expected 0 <= s_start < s_end <= 2529.085"),  # not rounded up
    ({"lanes": 0}, "road.lanes: expected an integer >= 1"),
    ({"closed": True, "s_end": 100}, "road.closed: the lane centre does not close"),
    ({"colour": "red"}, "road: unknown keys ['colour']"),
])
def test_bad_specs_name_the_field(change, message):
    with pytest.raises(SpecError, match=message.replace("(", r"\(").replace("[", r"\[")):
        road_from_spec({"opendrive": str(LOOP), "road": "1", "lane": -1, **change})


def test_bad_files_name_the_file_and_element(tmp_path):
    bad = tmp_path / "bad.xodr"
    bad.write_text("<OpenDRIVE><road id='1'")
    with pytest.raises(SpecError, match=r"not valid XML: .*line 1"):
        road_from_spec({"opendrive": str(bad), "road": "1"})
    file = write_xodr(tmp_path, '<geometry s="0" x="0" y="0" hdg="0" length="50"><clothoid/></geometry>', 50.0)
    with pytest.raises(SpecError, match="needs exactly one of line, arc, spiral, poly3, paramPoly3"):
        road_from_spec(spec(file))
    file = write_xodr(tmp_path, '<geometry s="0" x="0" y="zero" hdg="0" length="50"><line/></geometry>', 50.0)
    with pytest.raises(SpecError, match=r"<geometry y='zero'> is not a number"):
        road_from_spec(spec(file))


def test_a_road_read_from_a_file_is_read_again_each_time(tmp_path):
    """Roads are kept per process by their spec, except those of an OpenDRIVE file."""
    file = write_xodr(tmp_path, '<geometry s="0" x="0" y="0" hdg="0" length="50"><line/></geometry>', 50.0)
    first = road_from_spec(spec(file, lane=-1))
    assert road_from_spec(spec(file, lane=-1)) is not first
    write_xodr(tmp_path, '<geometry s="0" x="0" y="0" hdg="0" length="60"><line/></geometry>', 60.0)
    assert road_from_spec(spec(file, lane=-1)).length != first.length
    built = road_from_spec({"builder": "two_lane", "length": 600, "radius": 200})
    assert road_from_spec({"builder": "two_lane", "length": 600, "radius": 200}) is built
    assert road_from_spec({"builder": "two_lane", "length": 600.0, "radius": 200}) is not built
