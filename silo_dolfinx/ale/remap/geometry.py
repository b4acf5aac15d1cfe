"""Geometry and topology of the remap: moments of quadrilaterals of revolution, the swept
regions of the edges, left/right cells of oriented edges, Courant numbers, corner integrals."""

from __future__ import annotations

import math

import numpy as np

from silo_dolfinx._jit_cache import numba
from silo_dolfinx.kernels import FAST

TWO_PI = 2.0 * math.pi
CLOSED = -1  # the far side of a wall / free-surface / axis edge
OUTSIDE = -2  # the far side of an outflow edge


# ---------------------------------------------------------------------------- set-up kernels
@numba.njit(cache=True, fastmath=FAST, inline="always")
def edge_moments(x0, y0, x1, y1):
    cr = x0 * y1 - x1 * y0
    return ((x0 + x1) * cr, (x0 * x0 + x0 * x1 + x1 * x1) * cr,
            (x0 * y1 + 2.0 * x0 * y0 + 2.0 * x1 * y1 + x1 * y0) * cr)


@numba.njit(cache=True, fastmath=FAST)
def moments(r0, z0, r1, z1, r2, z2, r3, z3):
    """(∫ r dA, ∫ r² dA, ∫ r z dA) over the quadrilateral 0-1-2-3 (signed: positive if
    counter-clockwise; exact for straight edges). Scalars in and out: called per cell and
    per edge in the hot loops, where array arguments would cost reference counting."""
    a0, a1, a2 = edge_moments(r0, z0, r1, z1)
    b0, b1, b2 = edge_moments(r1, z1, r2, z2)
    c0, c1, c2 = edge_moments(r2, z2, r3, z3)
    d0, d1, d2 = edge_moments(r3, z3, r0, z0)
    return (a0 + b0 + c0 + d0) / 6.0, (a1 + b1 + c1 + d1) / 12.0, (a2 + b2 + c2 + d2) / 24.0


@numba.njit(cache=True)
def sides(cn, orient, fnodes, c0, c1):
    """Left and right cell of each oriented facet a->b (CLOSED / OUTSIDE for none)."""
    nf = fnodes.shape[0]
    left = np.empty(nf, np.int64)
    right = np.empty(nf, np.int64)
    for f in range(nf):
        a, b = fnodes[f, 0], fnodes[f, 1]
        cells = (c0[f], c1[f])
        left[f] = CLOSED
        right[f] = CLOSED
        other = CLOSED
        for c in cells:
            if c < 0:
                other = c
                continue
            forward = False
            for k in range(4):
                if cn[c, k] == a and cn[c, (k + 1) % 4] == b:
                    forward = True
            on_left = forward == (orient[c] > 0.0)
            if on_left:
                left[f] = c
            else:
                right[f] = c
        if left[f] == CLOSED and other == OUTSIDE:
            left[f] = OUTSIDE
        if right[f] == CLOSED and other == OUTSIDE:
            right[f] = OUTSIDE
    return left, right


@numba.njit(cache=True)
def cell_facets(cn, fnodes, fl, fr, n_owned):
    """Facet of each cycle edge (k, k+1) of the owned cells, and the cell's side (+1 right)."""
    cf = -np.ones((n_owned, 4), np.int64)
    side = np.zeros((n_owned, 4))
    for f in range(fnodes.shape[0]):
        for c, s in ((fl[f], -1.0), (fr[f], 1.0)):
            if c < 0 or c >= n_owned:
                continue
            a, b = fnodes[f, 0], fnodes[f, 1]
            for k in range(4):
                p, q = cn[c, k], cn[c, (k + 1) % 4]
                if (p == a and q == b) or (p == b and q == a):
                    cf[c, k] = f
                    side[c, k] = s
    return cf, side


# ---------------------------------------------------------------------------- remap kernels
@numba.njit(cache=True, fastmath=FAST)
def cell_geometry(x, cn, orient, vol, cen):
    for c in range(cn.shape[0]):
        a, b, d, e = cn[c, 0], cn[c, 1], cn[c, 2], cn[c, 3]
        m0, mr, mz = moments(x[a, 0], x[a, 1], x[b, 0], x[b, 1], x[d, 0], x[d, 1], x[e, 0], x[e, 1])
        m0 *= orient[c]
        mr *= orient[c]
        mz *= orient[c]
        vol[c] = TWO_PI * m0
        if m0 != 0.0:
            cen[c, 0] = mr / m0
            cen[c, 1] = mz / m0
        else:
            cen[c, 0] = 0.25 * (x[a, 0] + x[b, 0] + x[d, 0] + x[e, 0])
            cen[c, 1] = 0.25 * (x[a, 1] + x[b, 1] + x[d, 1] + x[e, 1])


@numba.njit(cache=True, fastmath=FAST)
def swept(x0, x1, fnodes, out, xf):
    """Moments of the region swept by each facet a->b, and the point to reconstruct at."""
    for f in range(fnodes.shape[0]):
        a, b = fnodes[f, 0], fnodes[f, 1]
        p0r, p0z, p1r, p1z = x0[a, 0], x0[a, 1], x0[b, 0], x0[b, 1]
        p2r, p2z, p3r, p3z = x1[b, 0], x1[b, 1], x1[a, 0], x1[a, 1]
        m0, mr, mz = moments(p0r, p0z, p1r, p1z, p2r, p2z, p3r, p3z)
        out[f, 0] = m0
        out[f, 1] = mr
        out[f, 2] = mz
        # the r-weighted centroid of the swept region; its 4-point mean where the region is
        # degenerate (no motion, or a bow-tie whose halves cancel)
        L2 = (p1r - p0r) ** 2 + (p1z - p0z) ** 2
        D2 = max((p3r - p0r) ** 2 + (p3z - p0z) ** 2, (p2r - p1r) ** 2 + (p2z - p1z) ** 2)
        ravg = 0.25 * (abs(p0r) + abs(p1r) + abs(p2r) + abs(p3r)) + math.sqrt(L2)
        if m0 * m0 > 1e-16 * ravg * ravg * L2 * D2:  # |m0| > 1e-8 r̄ L D, squared
            xf[f, 0] = mr / m0
            xf[f, 1] = mz / m0
        else:
            xf[f, 0] = 0.25 * (p0r + p1r + p2r + p3r)
            xf[f, 1] = 0.25 * (p0z + p1z + p2z + p3z)


@numba.njit(cache=True)
def courant(fl, fr, swept, vol, n_owned):
    out = np.zeros(n_owned)
    for f in range(fl.shape[0]):
        dv = TWO_PI * swept[f, 0]
        # dv > 0: volume leaves the left cell
        c = fl[f] if dv > 0.0 else fr[f]
        if 0 <= c < n_owned:
            out[c] += abs(dv)
    worst = 0.0
    for c in range(n_owned):
        if vol[c] > 0.0:
            worst = max(worst, out[c] / vol[c])
    return worst


@numba.njit(cache=True, fastmath=FAST)
def corner_integrals(x, a, b, c, d):
    """(∫ N_k 2π r dA for k = 0..3) over one Q1 cell with tensor-ordered nodes a, b, c, d
    (2 × 2 Gauss: exact, the integrand being at most quadratic in each direction)."""
    I0 = 0.0
    I1 = 0.0
    I2 = 0.0
    I3 = 0.0
    g0 = 0.5 - 0.5 / math.sqrt(3.0)
    g1 = 0.5 + 0.5 / math.sqrt(3.0)
    for i in range(4):
        xi = g0 if i % 2 == 0 else g1
        eta = g0 if i < 2 else g1
        N0 = (1.0 - xi) * (1.0 - eta)
        N1 = xi * (1.0 - eta)
        N2 = (1.0 - xi) * eta
        N3 = xi * eta
        r = N0 * x[a, 0] + N1 * x[b, 0] + N2 * x[c, 0] + N3 * x[d, 0]
        dr_dxi = (1.0 - eta) * (x[b, 0] - x[a, 0]) + eta * (x[d, 0] - x[c, 0])
        dz_dxi = (1.0 - eta) * (x[b, 1] - x[a, 1]) + eta * (x[d, 1] - x[c, 1])
        dr_deta = (1.0 - xi) * (x[c, 0] - x[a, 0]) + xi * (x[d, 0] - x[b, 0])
        dz_deta = (1.0 - xi) * (x[c, 1] - x[a, 1]) + xi * (x[d, 1] - x[b, 1])
        w = 0.25 * TWO_PI * r * abs(dr_dxi * dz_deta - dr_deta * dz_dxi)
        I0 += w * N0
        I1 += w * N1
        I2 += w * N2
        I3 += w * N3
    return I0, I1, I2, I3


@numba.njit(cache=True, fastmath=FAST)
def lumped(x, cn_tensor, rho, n_owned, acc):
    for c in range(n_owned):
        a, b, cc, d = cn_tensor[c, 0], cn_tensor[c, 1], cn_tensor[c, 2], cn_tensor[c, 3]
        I = corner_integrals(x, a, b, cc, d)
        acc[a, 2] += rho[c] * I[0]
        acc[b, 2] += rho[c] * I[1]
        acc[cc, 2] += rho[c] * I[2]
        acc[d, 2] += rho[c] * I[3]
