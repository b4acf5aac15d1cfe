"""The silo wall as exact geometry: straight segments and circular arcs in the (r, z) plane.

The wall is an open curve traversed from the outlet edge up to the top of the silo. The
granular material lies on the *left* of the direction of travel (towards the axis), so the
outward unit normal of the material, which points into the wall, is the right-hand normal
of the tangent: ``n = (t_z, -t_r)``.

:meth:`Wall.project` is the closest-point projection used by contact, smoothing and the
wall-pressure output. For each point it returns

* ``distance`` -- signed distance to the wall: positive on the material side (a gap),
  negative beyond the wall (a penetration);
* ``closest`` -- the closest point on the wall;
* ``normal`` -- the unit normal pointing into the wall (outward for the material);
* ``tangent`` -- the unit tangent in the direction of increasing arclength;
* ``s`` -- the arclength of the closest point, measured from the outlet edge.

Where the closest point is a vertex (a corner, or an end of the wall) the normal is the
direction between the point and the vertex, oriented with the vertex pseudo-normal (the
mean of the adjacent normals), which makes the sign of the distance correct on both sides
of an abrupt corner (Baerentzen & Aanaes, IEEE TVCG 11, 2005).

The kernel is compiled with numba and vectorised over points; the primitives are a few
arrays, so a wall of a hundred pieces costs nothing next to a time step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from silo_dolfinx._jit_cache import numba

SEGMENT = 0
ARC = 1


@dataclass(frozen=True)
class Segment:
    """Straight wall piece from ``start`` to ``end`` (points (r, z), metres)."""

    start: tuple[float, float]
    end: tuple[float, float]

    @property
    def length(self) -> float:
        return math.dist(self.start, self.end)


@dataclass(frozen=True)
class Arc:
    """Circular wall piece: centre, radius, start angle and signed sweep (radians).

    A positive sweep is counter-clockwise in the (r, z) plane. With the material on the
    left of the direction of travel, a counter-clockwise arc has its centre on the material
    side (a fillet that rounds a corner which is convex for the material).
    """

    center: tuple[float, float]
    radius: float
    theta0: float
    sweep: float

    def point(self, theta: float) -> tuple[float, float]:
        return (
            self.center[0] + self.radius * math.cos(theta),
            self.center[1] + self.radius * math.sin(theta),
        )

    @property
    def start(self) -> tuple[float, float]:
        return self.point(self.theta0)

    @property
    def end(self) -> tuple[float, float]:
        return self.point(self.theta0 + self.sweep)

    @property
    def length(self) -> float:
        return self.radius * abs(self.sweep)


@dataclass(frozen=True)
class Projection:
    distance: np.ndarray  # (n,)
    closest: np.ndarray  # (n, 2)
    normal: np.ndarray  # (n, 2)
    tangent: np.ndarray  # (n, 2)
    s: np.ndarray  # (n,)
    piece: np.ndarray  # (n,) index of the wall piece holding the closest point


class Wall:
    """An open chain of :class:`Segment` and :class:`Arc` pieces, outlet edge first."""

    def __init__(self, pieces: list[Segment | Arc], *, tol: float = 1e-9):
        if not pieces:
            raise ValueError("a wall needs at least one piece")
        for a, b in zip(pieces[:-1], pieces[1:]):
            if math.dist(a.end, b.start) > tol * max(1.0, abs(a.end[0]) + abs(a.end[1])):
                raise ValueError(f"wall pieces do not join: {a.end} != {b.start}")
        self.pieces = list(pieces)
        n = len(pieces)
        self._kind = np.array([SEGMENT if isinstance(p, Segment) else ARC for p in pieces], np.int64)
        self._geo = np.zeros((n, 6))  # segment: r0 z0 r1 z1 . . ; arc: rc zc R theta0 sweep .
        self._s0 = np.zeros(n)
        s = 0.0
        for i, p in enumerate(pieces):
            if isinstance(p, Segment):
                self._geo[i, :4] = (*p.start, *p.end)
            else:
                self._geo[i, :5] = (*p.center, p.radius, p.theta0, p.sweep)
            self._s0[i] = s
            s += p.length
        self.length = s
        # Outward normals at the ends of every piece, for vertex pseudo-normals.
        self._n_end = np.zeros((n, 2, 2))
        for i, p in enumerate(pieces):
            for k, where in enumerate(("start", "end")):
                t = _unit_tangent(p, where)
                self._n_end[i, k] = (t[1], -t[0])

    # ----------------------------------------------------------------- queries
    @property
    def start(self) -> tuple[float, float]:
        return self.pieces[0].start

    @property
    def end(self) -> tuple[float, float]:
        return self.pieces[-1].end

    @property
    def vertices(self) -> np.ndarray:
        """Piece end points, outlet edge first, shape (n_pieces + 1, 2)."""
        return np.array([self.pieces[0].start] + [p.end for p in self.pieces])

    def _corner_pieces(self, angle_tol_deg: float) -> list[int]:
        """Indices i where the tangent turns abruptly between piece i and piece i + 1."""
        out = []
        for i in range(len(self.pieces) - 1):
            t0 = _unit_tangent(self.pieces[i], "end")
            t1 = _unit_tangent(self.pieces[i + 1], "start")
            turn = math.degrees(math.atan2(t0[0] * t1[1] - t0[1] * t1[0], t0[0] * t1[0] + t0[1] * t1[1]))
            if abs(turn) > angle_tol_deg:
                out.append(i)
        return out

    def corners(self, angle_tol_deg: float = 1.0) -> np.ndarray:
        """Interior vertices where the tangent turns abruptly (more than ``angle_tol_deg``)."""
        return np.array([self.pieces[i].end for i in self._corner_pieces(angle_tol_deg)]).reshape(-1, 2)

    def corner_s(self, angle_tol_deg: float = 1.0) -> np.ndarray:
        """Arclengths of the corners (see :meth:`corners`)."""
        return np.array([self._s0[i + 1] for i in self._corner_pieces(angle_tol_deg)], float)

    def project(self, points: np.ndarray) -> Projection:
        """Closest-point projection of ``points`` (shape (n, 2) or (n, 3); r, z first)."""
        p = np.ascontiguousarray(np.asarray(points, dtype=np.float64)[:, :2])
        d, q, nrm, s, piece = _projected(p, self._kind, self._geo, self._s0, self._n_end)
        tan = np.column_stack((-nrm[:, 1], nrm[:, 0]))
        return Projection(d, q, nrm, tan, s, piece)

    def project_into(self, points: np.ndarray, out: tuple) -> None:
        """:meth:`project` without allocating (the contact of every step): ``points`` (n, 2)
        contiguous, out = (distance (n,), closest (n, 2), normal (n, 2), s (n,), piece (n,) int64)."""
        _project(points, self._kind, self._geo, self._s0, self._n_end, *out)

    @property
    def arrays(self) -> tuple:
        """(kind, geo, s0, n_end, length): the wall for numba kernels such as :func:`slide`."""
        return self._kind, self._geo, self._s0, self._n_end, self.length

    def point_at(self, s: np.ndarray | float) -> np.ndarray:
        """Wall point(s) at arclength ``s`` from the outlet edge (clipped to the wall)."""
        return self.point_normal_at(s)[0]

    def point_normal_at(self, s: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Wall points and unit normals (into the wall) at arclengths ``s`` (clipped)."""
        s = np.ascontiguousarray(np.atleast_1d(np.asarray(s, dtype=float)))
        pts = np.empty((s.size, 2))
        nrm = np.empty((s.size, 2))
        _point_at(np.clip(s, 0.0, self.length), self._kind, self._geo, self._s0, pts, nrm)
        return pts, nrm

    def s_at_height(self, z: np.ndarray | float) -> np.ndarray:
        """Arclength of the wall point at height ``z``.

        Defined on the rising part of the wall (a wall whose height never decreases, as the
        scene validation guarantees); horizontal floor pieces are skipped. Heights outside
        the wall are clipped to its ends. Exact for segments, bisection to round-off on arcs.
        """
        z = np.atleast_1d(np.asarray(z, dtype=float))
        out = np.empty(z.size)
        for j, zj in enumerate(z):
            out[j] = self._s_at_height_scalar(float(zj))
        return out

    def _s_at_height_scalar(self, z: float) -> float:
        if z <= self.start[1]:
            return 0.0
        for i, p in enumerate(self.pieces):
            za, zb = p.start[1], p.end[1]
            if zb <= za or not (za <= z <= zb):
                continue
            if isinstance(p, Segment):
                return self._s0[i] + p.length * (z - za) / (zb - za)
            lo, hi = 0.0, p.length  # z is monotone along a piece of a rising wall
            for _ in range(200):
                mid = 0.5 * (lo + hi)
                if self.point_at(self._s0[i] + mid)[0, 1] < z:
                    lo = mid
                else:
                    hi = mid
                if hi - lo <= 4e-16 * max(p.length, 1.0):
                    break
            return self._s0[i] + 0.5 * (lo + hi)
        return self.length

    def radius_at(self, z: np.ndarray | float) -> np.ndarray:
        """Wall radius at height ``z`` (above any floor; the wall is single-valued there)."""
        return self.point_at(self.s_at_height(z))[:, 0]


def _unit_tangent(p: Segment | Arc, where: str) -> tuple[float, float]:
    if isinstance(p, Segment):
        dr, dz = p.end[0] - p.start[0], p.end[1] - p.start[1]
        L = math.hypot(dr, dz)
        return (dr / L, dz / L)
    th = p.theta0 if where == "start" else p.theta0 + p.sweep
    sgn = 1.0 if p.sweep > 0 else -1.0
    return (-sgn * math.sin(th), sgn * math.cos(th))


@numba.njit(cache=True)
def _point_at(s, kind, geo, s0, pts, nrm):
    n = kind.shape[0]
    for j in range(s.shape[0]):
        i = n - 1
        while i > 0 and s0[i] > s[j]:
            i -= 1
        g = geo[i]
        u = s[j] - s0[i]
        if kind[i] == SEGMENT:
            dr, dz = g[2] - g[0], g[3] - g[1]
            L = math.sqrt(dr * dr + dz * dz)
            f = u / L if L > 0.0 else 0.0
            pts[j, 0] = g[0] + f * dr
            pts[j, 1] = g[1] + f * dz
            tr, tz = (dr / L, dz / L) if L > 0.0 else (0.0, 1.0)
        else:
            sg = 1.0 if g[4] > 0.0 else -1.0
            th = g[3] + sg * u / g[2]
            pts[j, 0] = g[0] + g[2] * math.cos(th)
            pts[j, 1] = g[1] + g[2] * math.sin(th)
            tr, tz = -sg * math.sin(th), sg * math.cos(th)
        nrm[j, 0] = tz
        nrm[j, 1] = -tr


@numba.njit(cache=True)
def slide(points, s_new, kind, geo, s0, n_end, length, out):
    """Each point carried along the wall to arclength ``s_new`` (clipped to the wall), at its
    present normal gap (0 for a point in or beyond the wall): ``out`` = wall(s) − gap·n(s).
    The wall is given by :attr:`Wall.arrays`."""
    d, q, nrm, _, _ = _projected(points, kind, geo, s0, n_end)
    _point_at(np.minimum(np.maximum(s_new, 0.0), length), kind, geo, s0, q, nrm)
    for j in range(points.shape[0]):
        gap = max(d[j], 0.0)
        out[j, 0] = q[j, 0] - gap * nrm[j, 0]
        out[j, 1] = q[j, 1] - gap * nrm[j, 1]


@numba.njit(cache=True)
def arclength_of(point, kind, geo, s0, n_end):
    """Arclength of the closest wall point to one point (r, z)."""
    p = np.empty((1, 2))
    p[0, 0], p[0, 1] = point[0], point[1]
    return _projected(p, kind, geo, s0, n_end)[3][0]


@numba.njit(cache=True)
def _projected(p, kind, geo, s0, n_end):
    """:func:`_project` into new arrays: (distance, closest, normal, s, piece)."""
    n = p.shape[0]
    d = np.empty(n)
    q = np.empty((n, 2))
    nrm = np.empty((n, 2))
    s = np.empty(n)
    piece = np.empty(n, np.int64)
    _project(p, kind, geo, s0, n_end, d, q, nrm, s, piece)
    return d, q, nrm, s, piece


@numba.njit(cache=True)
def _closest_on_piece(pr, pz, kind, g):
    """Closest point on one piece: (qr, qz, where, theta) with where -1 start, 0 inside, 1 end."""
    if kind == SEGMENT:
        r0, z0, r1, z1 = g[0], g[1], g[2], g[3]
        dr, dz = r1 - r0, z1 - z0
        L2 = dr * dr + dz * dz
        t = ((pr - r0) * dr + (pz - z0) * dz) / L2
        if t <= 0.0:
            return r0, z0, -1, 0.0
        if t >= 1.0:
            return r1, z1, 1, 1.0
        return r0 + t * dr, z0 + t * dz, 0, t
    rc, zc, R, th0, sw = g[0], g[1], g[2], g[3], g[4]
    phi = math.atan2(pz - zc, pr - rc)
    two_pi = 2.0 * math.pi
    if sw > 0.0:
        u = (phi - th0) % two_pi
    else:
        u = (th0 - phi) % two_pi
    if u <= abs(sw) and (pr != rc or pz != zc):
        th = th0 + u if sw > 0.0 else th0 - u
        return rc + R * math.cos(th), zc + R * math.sin(th), 0, th
    # Outside the angular range: the nearer end point.
    ra, za = rc + R * math.cos(th0), zc + R * math.sin(th0)
    rb, zb = rc + R * math.cos(th0 + sw), zc + R * math.sin(th0 + sw)
    if (pr - ra) ** 2 + (pz - za) ** 2 <= (pr - rb) ** 2 + (pz - zb) ** 2:
        return ra, za, -1, th0
    return rb, zb, 1, th0 + sw


@numba.njit(cache=True)
def _project(p, kind, geo, s0, n_end, d_out, q_out, n_out, s_out, piece_out):
    npieces = kind.shape[0]
    for j in range(p.shape[0]):
        pr, pz = p[j, 0], p[j, 1]
        best = 1e300
        bi = -1
        bwhere = 0
        bpar = 0.0
        bqr = 0.0
        bqz = 0.0
        for i in range(npieces):
            qr, qz, where, par = _closest_on_piece(pr, pz, kind[i], geo[i])
            dist2 = (pr - qr) ** 2 + (pz - qz) ** 2
            # Strictly nearer wins; on a tie an interior projection beats a vertex.
            if dist2 < best * (1.0 - 1e-14) or (dist2 <= best * (1.0 + 1e-14) and where == 0 and bwhere != 0):
                best = dist2
                bi = i
                bwhere = where
                bpar = par
                bqr = qr
                bqz = qz
        q_out[j, 0] = bqr
        q_out[j, 1] = bqz
        piece_out[j] = bi
        g = geo[bi]
        if bwhere == 0:
            if kind[bi] == SEGMENT:
                dr, dz = g[2] - g[0], g[3] - g[1]
                L = math.sqrt(dr * dr + dz * dz)
                tr, tz = dr / L, dz / L
                s_out[j] = s0[bi] + bpar * L
            else:
                sg = 1.0 if g[4] > 0.0 else -1.0
                tr, tz = -sg * math.sin(bpar), sg * math.cos(bpar)
                s_out[j] = s0[bi] + g[2] * abs(bpar - g[3])
            nr, nz = tz, -tr
            n_out[j, 0] = nr
            n_out[j, 1] = nz
            d_out[j] = (bqr - pr) * nr + (bqz - pz) * nz
        else:
            # Vertex: pseudo-normal from the pieces meeting there.
            k = 0 if bwhere < 0 else 1
            pnr, pnz = n_end[bi, k, 0], n_end[bi, k, 1]
            if bwhere < 0 and bi > 0:
                pnr += n_end[bi - 1, 1, 0]
                pnz += n_end[bi - 1, 1, 1]
            elif bwhere > 0 and bi < npieces - 1:
                pnr += n_end[bi + 1, 0, 0]
                pnz += n_end[bi + 1, 0, 1]
            pl = math.sqrt(pnr * pnr + pnz * pnz)
            pnr /= pl
            pnz /= pl
            dist = math.sqrt(best)
            # a point at the vertex to round-off takes the pseudo-normal (its direction to
            # the vertex would be noise)
            if dist > 1e-12 * (abs(bqr) + abs(bqz) + 1e-300):
                wr, wz = (bqr - pr) / dist, (bqz - pz) / dist
                sign = 1.0 if wr * pnr + wz * pnz >= 0.0 else -1.0
                n_out[j, 0] = sign * wr
                n_out[j, 1] = sign * wz
                d_out[j] = sign * dist
            else:
                n_out[j, 0] = pnr
                n_out[j, 1] = pnz
                d_out[j] = 0.0
            if kind[bi] == SEGMENT:
                Lseg = math.sqrt((g[2] - g[0]) ** 2 + (g[3] - g[1]) ** 2)
            else:
                Lseg = g[2] * abs(g[4])
            s_out[j] = s0[bi] + (0.0 if bwhere < 0 else Lseg)
