"""The plan view of an ASAM OpenDRIVE road: its reference line as a function of s.

OpenDRIVE 1.4-1.8 describe the reference line as a chain of `<geometry>`
records, each with a start (s, x, y, hdg), a length and one primitive:
`line`, `arc` (curvature), `spiral` (curvStart, curvEnd: curvature linear in
s), `poly3` (v = a + b u + c u^2 + d u^3 in the record's local u/v frame) and
`paramPoly3` (u(p), v(p) cubic in p, pRange "arcLength" or "normalized").

`PlanView.evaluate(s)` gives x, y, heading, curvature and d curvature / ds
at reference-line stations s. Lines, arcs and spirals are exact (evaluated by
`controllers.road.geometry.Path`, whose curvature is linear in s by
construction). The two cubic primitives are not parameterised by arc length:
a station s is first mapped to the curve parameter p by inverting the arc
length integral (10-point Gauss-Legendre per table interval, then Newton on
s(p) with ds/dp = |r'(p)|), and heading, curvature and its rate come from
the exact derivatives of the cubics.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from controllers.road.geometry import Path
from controllers.spec import SpecError

_GL_T, _GL_W = np.polynomial.legendre.leggauss(10)
TABLE_INTERVALS = 64     # arc-length table of a cubic primitive: intervals in p
NEWTON_STEPS = 6         # the table's linear guess is already within ~1e-6 of the root


@dataclass(frozen=True)
class Geometry:
    """One `<geometry>` record: where it starts, its length, its primitive and parameters."""

    s: float
    x: float
    y: float
    hdg: float
    length: float
    kind: str                       # line | arc | spiral | poly3 | paramPoly3
    params: tuple[float, ...] = ()  # arc: (k,); spiral: (k0, k1); poly3: (a..d); paramPoly3: (aU..dV)
    normalized: bool = True         # paramPoly3 pRange


class _Cubic:
    """A poly3 / paramPoly3 record: u(p), v(p) cubic, evaluated by arc length."""

    def __init__(self, g: Geometry):
        if g.kind == "poly3":
            a, b, c, d = g.params
            self.cu, self.cv = np.array([0.0, 1.0, 0.0, 0.0]), np.array([a, b, c, d])
            self.p_end = None        # u range: found from the length below
        else:
            self.cu, self.cv = np.array(g.params[:4]), np.array(g.params[4:])
            self.p_end = 1.0 if g.normalized else g.length
        self.g = g
        if self.p_end is None:
            self.p_end = self._u_for_length(g.length)
        self.table_p = np.linspace(0.0, self.p_end, TABLE_INTERVALS + 1)
        self.table_s = np.concatenate([[0.0], np.cumsum(self._arc(self.table_p[:-1], self.table_p[1:]))])

    def _derivs(self, p):
        """(u, v), (u', v'), (u'', v''), (u''', v''') at parameters p."""
        out = []
        for c in (self.cu, self.cv):
            out.append((c[0] + p * (c[1] + p * (c[2] + p * c[3])),
                        c[1] + p * (2 * c[2] + 3 * c[3] * p), 2 * c[2] + 6 * c[3] * p,
                        np.full_like(p, 6 * c[3])))
        return tuple(zip(*out))

    def _speed(self, p):
        _, (du, dv), _, _ = self._derivs(p)
        return np.hypot(du, dv)

    def _arc(self, pa, pb):
        """Arc length from pa to pb (arrays), by 10-point Gauss-Legendre."""
        q = pa[..., None] + 0.5 * (_GL_T + 1.0) * (pb - pa)[..., None]
        return 0.5 * (pb - pa) * (self._speed(q) @ _GL_W)

    def _u_for_length(self, length: float) -> float:
        """poly3: the local u where the curve's arc length reaches `length`."""
        u = length
        for _ in range(50):
            step = (self._arc(np.array(0.0), np.array(u)) - length) / self._speed(np.array(u))
            u -= float(step)
            if abs(step) < 1e-13 * max(1.0, length):
                break
        return u

    def parameter(self, u):
        """Curve parameter p at arc lengths u from the record's start."""
        u = np.clip(u, 0.0, self.table_s[-1])
        j = np.clip(np.searchsorted(self.table_s, u, side="right") - 1, 0, TABLE_INTERVALS - 1)
        frac = (u - self.table_s[j]) / (self.table_s[j + 1] - self.table_s[j])
        p = self.table_p[j] + frac * (self.table_p[j + 1] - self.table_p[j])
        for _ in range(NEWTON_STEPS):
            p = p - (self.table_s[j] + self._arc(self.table_p[j], p) - u) / self._speed(p)
        return p

    def evaluate(self, u):
        """World x, y, heading, curvature, d curvature / ds at arc lengths u."""
        p = self.parameter(u)
        (pu, pv), (du, dv), (ddu, ddv), (d3u, d3v) = self._derivs(p)
        speed2 = du * du + dv * dv
        cross = du * ddv - dv * ddu
        kappa = cross / speed2 ** 1.5
        dcross = du * d3v - dv * d3u
        dkappa_dp = (dcross * speed2 - 3.0 * cross * (du * ddu + dv * ddv)) / speed2 ** 2.5
        c, s = np.cos(self.g.hdg), np.sin(self.g.hdg)
        x = self.g.x + c * pu - s * pv
        y = self.g.y + s * pu + c * pv
        return x, y, self.g.hdg + np.arctan2(dv, du), kappa, dkappa_dp / np.sqrt(speed2)


class PlanView:
    """The reference line of one road: its geometry records, evaluated by station s."""

    def __init__(self, records: list[Geometry], road_length: float, where: str):
        if not records:
            raise SpecError(f"{where}: the road has no <planView> geometry")
        self.records = sorted(records, key=lambda g: g.s)
        self.length = road_length
        self.starts = np.array([g.s for g in self.records])
        self._eval = [self._evaluator(g, f"{where} geometry at s = {g.s}") for g in self.records]

    @staticmethod
    def _evaluator(g: Geometry, where: str):
        if not (np.isfinite(g.length) and g.length > 0):
            raise SpecError(f"{where}: length must be > 0, got {g.length}")
        if g.kind in ("poly3", "paramPoly3"):
            return _Cubic(g).evaluate
        k0, k1 = {"line": (0.0, 0.0), "arc": g.params * 2, "spiral": g.params}[g.kind]
        path = Path.from_pieces([(g.length, k0, k1)], g.x, g.y, g.hdg)

        def evaluate(u):
            x, y, psi, kappa = path.evaluate(u)
            return x, y, psi, kappa, np.full_like(u, (k1 - k0) / g.length)
        return evaluate

    def evaluate(self, s) -> tuple[np.ndarray, ...]:
        """x, y, heading, curvature and d curvature / ds of the reference line at stations s.

        Args:
            s: stations in [0, road length]; a station on a record boundary
                belongs to the record that starts there.
        """
        s = np.atleast_1d(np.asarray(s, dtype=float))
        idx = np.clip(np.searchsorted(self.starts, s, side="right") - 1, 0, len(self.records) - 1)
        out = [np.empty_like(s) for _ in range(5)]
        for i in np.unique(idx):
            mask = idx == i
            for arr, values in zip(out, self._eval[i](s[mask] - self.starts[i])):
                arr[mask] = values
        return tuple(out)
