"""Silo shapes: from the [geometry] section to an :class:`Outline` (analytic wall, outlet, fill).

Every shape is reduced to one description: a :class:`~silo_dolfinx.geometry.wall.Wall`
from the outlet edge (r = outlet_radius, z = 0) up to the top, plus the outlet radius and the
fill height. The material domain is bounded by the axis (r = 0), the outlet (z = 0,
r < outlet_radius), the wall, and the flat top surface at z = fill_height.

``resolve_geometry`` checks that the numbers describe a silo (outlet narrower than the silo,
a fillet that fits, a profile that rises and does not cross itself, a fill inside the wall),
fills the derived defaults, and reports problems naming the key. It is pure Python: it runs
before any meshing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from silo_dolfinx.geometry.wall import Arc, Segment, Wall
from silo_dolfinx.scene.errors import Problem
from silo_dolfinx.scene.schema import DERIVED


class _GeometryProblem(Exception):
    def __init__(self, key: str, message: str):
        self.problem = Problem("geometry", key, message)


@dataclass
class Outline:
    """The silo as exact geometry. Heights from the outlet, radii from the axis (metres)."""

    shape: str
    wall: Wall
    outlet_radius: float
    fill_height: float
    floor_pieces: int  # number of horizontal wall pieces at z = 0 (a flat floor)
    transition_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    #: the free surface as a polyline (m, 2) from the axis to the wall, when it is not the flat
    #: top at fill_height (a rezoned discharge: :meth:`with_surface`)
    surface: np.ndarray | None = None

    def with_surface(self, points: np.ndarray) -> Outline:
        """This silo holding material up to the surface ``points`` (m, 2): from the axis
        (r = 0) to the wall, its last point on the wall. Its fill height is the surface's top."""
        from dataclasses import replace

        pts = np.array(points, float)
        if pts.ndim != 2 or pts.shape[0] < 2 or abs(pts[0, 0]) > 1e-9 * max(self.r_max, 1.0):
            raise ValueError("a surface runs from the axis (r = 0) to the wall: (m ≥ 2, 2) points")
        pts[0, 0] = 0.0
        return replace(self, fill_height=float(pts[:, 1].max()), surface=pts)

    @property
    def height(self) -> float:
        """Height of the wall top."""
        return float(self.wall.end[1])

    @property
    def floor_radius(self) -> float:
        """Radius where the wall starts to rise (= outlet_radius without a floor)."""
        return float(self.wall.pieces[self.floor_pieces].start[0]) if self.floor_pieces < len(
            self.wall.pieces) else float(self.wall.end[0])

    @property
    def has_floor(self) -> bool:
        """Whether the wall starts with a flat floor beyond the outlet edge."""
        return self.outlet_radius < self.floor_radius - 1e-12

    @property
    def wall_length_below_fill(self) -> float:
        """Arclength of the wall up to the material's top corner on it."""
        z = self.fill_height if self.surface is None else float(self.surface[-1, 1])
        return float(self.wall.s_at_height(z)[0])

    @property
    def r_max(self) -> float:
        """Largest wall radius below the fill height."""
        pts = [p for p in self.wall.vertices if p[1] <= self.fill_height]
        pts.append((float(self.wall.radius_at(self.fill_height)[0]), self.fill_height))
        rmax = max(p[0] for p in pts)
        for p in self.wall.pieces:  # an arc may bulge beyond its end points
            if isinstance(p, Arc):
                ss = np.linspace(0, p.length, 65)
                s0 = self.wall.s_at_height(p.start[1])[0]
                xy = self.wall.point_at(s0 + ss)
                rmax = max(rmax, float(xy[xy[:, 1] <= self.fill_height, 0].max(initial=0)))
        return rmax

    def contact_wall(self, extension: float | None = None) -> Wall:
        """The wall for contact: continued straight beyond its top (default by half the silo's
        height), so material at the top corner always has a wall beside it."""
        ext = 0.5 * max(self.height, self.r_max) if extension is None else extension
        last = self.wall.pieces[-1]
        end = np.asarray(last.end, float)
        t = end - self.wall.point_at(self.wall.length - 1e-6 * self.wall.length)[0]
        t /= np.linalg.norm(t)
        return Wall(self.wall.pieces + [Segment(tuple(end), tuple(end + ext * t))])

    def under_outlet_edge(self, length: float) -> Segment | None:
        """A floor continued straight beyond the outlet edge by ``length``: the contact's
        support for the node at the outlet edge (WallFriction). None where the wall rises from
        the outlet edge (a hopper): the material leaves along it, past its end."""
        first = self.wall.pieces[0]
        if not (isinstance(first, Segment) and abs(first.end[1] - first.start[1]) <= 1e-12 * first.length):
            return None
        start = np.asarray(first.start, float)
        t = (start - np.asarray(first.end, float)) / first.length
        return Segment(tuple(start + length * t), tuple(start))

    def volume(self, z_top: float | None = None) -> float:
        """Exact volume of revolution of the material below ``z_top`` (default: the fill)."""
        return math.pi * self._integral_r2(self.fill_height if z_top is None else z_top)

    def meridian_area(self) -> float:
        """Area of the (r, z) domain, ∫ r_wall(z) dz over the fill."""
        return self._integral_r1(self.fill_height)

    def _integral_r2(self, ztop: float) -> float:
        return self._integrate(ztop, 2)

    def _integral_r1(self, ztop: float) -> float:
        return self._integrate(ztop, 1)

    def _integrate(self, ztop: float, power: int) -> float:
        """∫ r_wall(z)^power dz from 0 to ztop, exact per piece (Gauss on arcs' angle)."""
        total = 0.0
        xg, wg = np.polynomial.legendre.leggauss(24)
        for p in self.wall.pieces:
            za, zb = p.start[1], p.end[1]
            if zb <= za or za >= ztop:
                continue
            if isinstance(p, Segment):
                zb_c = min(zb, ztop)
                ra = p.start[0]
                rb = ra + (p.end[0] - ra) * (zb_c - za) / (zb - za)
                h = zb_c - za
                total += h * ((ra * ra + ra * rb + rb * rb) / 3.0 if power == 2 else 0.5 * (ra + rb))
            else:
                th_a = p.theta0
                th_b = p.theta0 + p.sweep
                if zb > ztop:  # clip the arc at ztop (z is monotone along it)
                    lo, hi = 0.0, 1.0
                    for _ in range(200):
                        mid = 0.5 * (lo + hi)
                        if p.point(th_a + mid * p.sweep)[1] < ztop:
                            lo = mid
                        else:
                            hi = mid
                    th_b = th_a + 0.5 * (lo + hi) * p.sweep
                th = 0.5 * (th_a + th_b) + 0.5 * (th_b - th_a) * xg
                r = p.center[0] + p.radius * np.cos(th)
                dz = p.radius * np.cos(th)  # dz/dθ
                total += 0.5 * (th_b - th_a) * float(np.sum(wg * r**power * dz))
        return total


# ---------------------------------------------------------------------------- shapes
def _hopper(g):
    H, Rt, R0 = g["height"], g["top_radius"], g["outlet_radius"]
    if R0 >= Rt:
        raise _GeometryProblem("outlet_radius", f"= {R0:g} m must be smaller than top_radius = {Rt:g} m "
                               "for a converging hopper. Fix: a smaller outlet_radius, or shape = "
                               "\"column\" with a negative half_angle for a diverging silo.")
    return [Segment((R0, 0.0), (Rt, H))], 0, np.zeros((0, 2))


def hopper_half_angle(g) -> float:
    """Apex half-angle α from the vertical (deg) of a ``shape = "hopper"`` [geometry] section."""
    return math.degrees(math.atan((g["top_radius"] - g["outlet_radius"]) / g["height"]))


def _flat_bottom(g):
    R, H, R0 = g["radius"], g["height"], g["outlet_radius"]
    if R0 >= R:
        raise _GeometryProblem("outlet_radius", f"= {R0:g} m must be smaller than radius = {R:g} m. "
                               f"Fix: outlet_radius < {R:g}.")
    return [Segment((R0, 0.0), (R, 0.0)), Segment((R, 0.0), (R, H))], 1, np.array([[R, 0.0]])


def bin_hopper_cone_height(g) -> float:
    """Height of a ``shape = "bin_hopper"``'s cone from the outlet to where its wall meets the
    bin's (the abrupt corner; a fillet rounds it off about this height) (m)."""
    return (g["radius"] - g["outlet_radius"]) / math.tan(math.radians(g["hopper_half_angle"]))


def _bin_hopper(g):
    R, Hb, alpha, R0, Rf = (g["radius"], g["bin_height"], g["hopper_half_angle"], g["outlet_radius"],
                            g["fillet_radius"])
    if R0 >= R:
        raise _GeometryProblem("outlet_radius", f"= {R0:g} m must be smaller than radius = {R:g} m. "
                               f"Fix: outlet_radius < {R:g}.")
    a = math.radians(alpha)
    hh = bin_hopper_cone_height(g)
    corner = (R, hh)
    top = (R, hh + Hb)
    if Rf == 0.0:
        return [Segment((R0, 0.0), corner), Segment(corner, top)], 0, np.array([corner])
    T = Rf * math.tan(a / 2)  # tangent length of the fillet
    L_hop = (R - R0) / math.sin(a)
    limit = min(L_hop, Hb)
    if T >= limit:
        which = "hopper wall length" if L_hop <= Hb else "bin_height"
        raise _GeometryProblem("fillet_radius", f"= {Rf:g} m does not fit: its tangent length "
                               f"fillet_radius·tan(α/2) = {T:.4g} m reaches the {which} ({limit:.4g} m). "
                               f"Fix: fillet_radius < {limit / math.tan(a / 2):.4g} m.")
    p1 = (R - T * math.sin(a), hh - T * math.cos(a))
    p2 = (R, hh + T)
    arc = Arc(center=(R - Rf, hh + T), radius=Rf, theta0=-a, sweep=a)
    mid = arc.point(-a / 2)
    return [Segment((R0, 0.0), p1), arc, Segment(p2, top)], 0, np.array([p1, mid, p2])


def _column(g):
    Rb, H, alpha = g["base_radius"], g["height"], g["half_angle"]
    Rt = Rb + H * math.tan(math.radians(alpha))
    if Rt <= 0.0:
        lim = math.degrees(math.atan(Rb / H))
        raise _GeometryProblem("half_angle", f"= {alpha:g}°: the diverging column closes below its top "
                               f"(top radius {Rt:.4g} m). Fix: half_angle > −{lim:.4g}°.")
    g["outlet_radius"] = Rb
    return [Segment((Rb, 0.0), (Rt, H))], 0, np.zeros((0, 2))


def _profile(g):
    pts = [tuple(p) for p in g["wall"]]
    R0 = g["outlet_radius"]
    for i, (r, z) in enumerate(pts):
        if r <= 0.0:
            raise _GeometryProblem("wall", f"point {i} = [{r:g}, {z:g}] has r ≤ 0: the wall must stay off "
                                   "the axis. Fix: give it a positive radius.")
    if pts[0][1] != 0.0:
        raise _GeometryProblem("wall", f"point 0 = [{pts[0][0]:g}, {pts[0][1]:g}]: the wall must start at "
                               f"the outlet level z = 0 (heights are measured from the outlet). Fix: "
                               f"subtract {pts[0][1]:g} from every z.")
    if R0 > pts[0][0]:
        raise _GeometryProblem("outlet_radius", f"= {R0:g} m is wider than the wall's first point "
                               f"r = {pts[0][0]:g} m. Fix: outlet_radius ≤ {pts[0][0]:g}.")
    for i in range(1, len(pts)):
        if pts[i][1] < pts[i - 1][1]:
            raise _GeometryProblem("wall", f"point {i} = [{pts[i][0]:g}, {pts[i][1]:g}] is lower than "
                                   f"point {i - 1} (z = {pts[i - 1][1]:g}): the wall is not monotone in z. "
                                   "Fix: list the points from the outlet upwards with z never decreasing.")
        if pts[i] == pts[i - 1]:
            raise _GeometryProblem("wall", f"points {i - 1} and {i} coincide. Fix: remove one.")
    if pts[-1][1] <= 0.0:
        raise _GeometryProblem("wall", "the wall does not rise above z = 0. Fix: add points above.")
    if R0 < pts[0][0]:
        pts = [(R0, 0.0)] + pts
    segs = [Segment(a, b) for a, b in zip(pts[:-1], pts[1:])]
    bad = _first_self_intersection(segs)
    if bad is not None:
        raise _GeometryProblem("wall", f"segments {bad[0]} and {bad[1]} intersect: the profile crosses "
                               "itself. Fix: reorder or remove points so the wall is a simple curve.")
    floor = 0
    while floor < len(segs) and segs[floor].start[1] == segs[floor].end[1] == 0.0:
        floor += 1
    wall = Wall(segs)
    return segs, floor, wall.corners()


def _first_self_intersection(segs):
    def orient(a, b, c):
        return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])

    def on_seg(a, b, c):
        return min(a[0], b[0]) - 1e-15 <= c[0] <= max(a[0], b[0]) + 1e-15 and \
            min(a[1], b[1]) - 1e-15 <= c[1] <= max(a[1], b[1]) + 1e-15

    n = len(segs)
    for i in range(n):
        for j in range(i + 1, n):
            a, b = segs[i].start, segs[i].end
            c, d = segs[j].start, segs[j].end
            o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
            if j == i + 1:  # neighbours share b == c; they cross only by folding back on a line
                if o2 == 0.0 and (d[0] - b[0]) * (a[0] - b[0]) + (d[1] - b[1]) * (a[1] - b[1]) > 0:
                    return i, j
                continue
            if (o1 * o2 < 0 and o3 * o4 < 0) or (o1 == 0 and on_seg(a, b, c)) or (o2 == 0 and on_seg(a, b, d)) \
                    or (o3 == 0 and on_seg(c, d, a)) or (o4 == 0 and on_seg(c, d, b)):
                return i, j
    return None


_BUILDERS = {"hopper": _hopper, "flat_bottom": _flat_bottom, "bin_hopper": _bin_hopper,
             "column": _column, "profile": _profile}


def outline_from_geometry(g: dict) -> Outline:
    """Build the outline of a resolved [geometry] section (raises ValueError if inconsistent)."""
    g = dict(g)
    try:
        pieces, floor, transitions = _BUILDERS[g["shape"]](g)
    except _GeometryProblem as e:
        raise ValueError(str(e.problem)) from None
    wall = Wall(pieces)
    fill = g.get("fill_height", DERIVED)
    fill = wall.end[1] if fill is DERIVED else fill
    return Outline(g["shape"], wall, g["outlet_radius"], float(fill), floor, transitions)


def resolve_geometry(g: dict) -> list[Problem]:
    """Validate shape consistency and fill derived keys of a [geometry] dict, in place."""
    try:
        pieces, floor, transitions = _BUILDERS[g["shape"]](g)
    except _GeometryProblem as e:
        return [e.problem]
    wall = Wall(pieces)
    H = wall.end[1]
    if g["fill_height"] is DERIVED:
        g["fill_height"] = float(H)
    elif g["fill_height"] > H * (1 + 1e-12):
        return [Problem("geometry", "fill_height", f"= {g['fill_height']:g} m is above the wall top "
                        f"({H:g} m): the fill would cross the wall. Fix: fill_height ≤ {H:g}.")]
    ol = Outline(g["shape"], wall, g["outlet_radius"], g["fill_height"], floor, transitions)
    rmax = ol.r_max
    if g["element_size"] is DERIVED:
        g["element_size"] = float(f"{rmax / 20:.3g}")
    if g["refinement_distance"] is DERIVED:
        g["refinement_distance"] = float(f"{rmax / 4:.3g}")
    h = g["element_size"]
    thin = min(rmax, g["fill_height"])
    if h > thin / 2:
        return [Problem("geometry", "element_size", f"= {h:g} m is too coarse: fewer than two elements "
                        f"across the silo ({thin:g} m). Fix: element_size ≤ {thin / 2:.3g}.")]
    estimate = ol.meridian_area() / h / h  # not h**2: that underflows to 0 for a typo like 1e-300
    if estimate > g["max_cells"]:
        return [Problem("geometry", "element_size", f"= {h:g} m would give about {estimate:.3g} cells, "
                        f"more than max_cells = {g['max_cells']}. Fix: a larger element_size (e.g. "
                        f"{h * math.sqrt(estimate / g['max_cells']) * 1.05:.3g}), or raise max_cells.")]
    return []
