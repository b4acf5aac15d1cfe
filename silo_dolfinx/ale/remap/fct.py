"""Flux correction (Remhos' FCT stage): Zalesak's limiter on the high-order corrections A.

Each cell sums the corrections that would flow into it (P+) and out of it (P−); the room
Q± = m' [max, min] − (low-order total) in its local bounds gives its factors R± = min(1,
Q±/P±); each edge's correction is scaled by the smaller factor of its receiving and its
giving cell. The result stays within the bounds the low-order update respects: no new
extremum, conservation untouched (each limited flux leaves one cell and enters the other)."""

from __future__ import annotations

import numba

from silo_dolfinx.kernels import FAST


@numba.njit(cache=True, fastmath=FAST)
def sums(faces, A, cols, pp, pm):
    """Zalesak's sums of the corrections into (pp) and out of (pm) each owned cell, columns
    cols = (j0, j1)."""
    fl, fr, n_owned = faces
    j0, j1 = cols
    for c in range(n_owned):
        for j in range(j0, j1):
            pp[c, j] = pm[c, j] = 0.0
    for f in range(fl.shape[0]):
        l, r = fl[f], fr[f]
        lown = 0 <= l < n_owned
        rown = 0 <= r < n_owned
        for j in range(j0, j1):
            # branch-free: the sign of a is data, not a pattern the CPU can predict
            a = A[f, j]
            ap = max(a, 0.0)
            am = min(a, 0.0)
            if lown:
                pm[l, j] -= ap
                pp[l, j] -= am
            if rown:
                pp[r, j] += ap
                pm[r, j] += am


@numba.njit(cache=True, fastmath=FAST)
def limiters(E, mnew, bounds, sums, cols, n_owned, Rpm):
    """R± of each owned cell: E the low-order totals, mnew the new masses (or volumes, for
    the density), bounds = (qmin, qmax), sums = (pp, pm), cols = (j0, j1)."""
    qmin, qmax = bounds
    pp, pm = sums
    j0, j1 = cols
    for c in range(n_owned):
        for j in range(j0, j1):
            qp = max(0.0, mnew[c] * qmax[c, j] - E[c, j])
            qm = min(0.0, mnew[c] * qmin[c, j] - E[c, j])
            Rpm[c, 0, j] = min(1.0, qp / pp[c, j]) if pp[c, j] > 0.0 else 1.0
            Rpm[c, 1, j] = min(1.0, qm / pm[c, j]) if pm[c, j] < 0.0 else 1.0


@numba.njit(cache=True, fastmath=FAST)
def apply(faces, A, Rpm, cols, E, low, fmass):
    """Add the limited corrections α A to the owned totals E (columns j0..j1); for column 0
    (mass) also store the final edge mass fluxes low + α A in ``fmass``."""
    fl, fr, n_owned = faces
    j0, j1 = cols
    for f in range(fl.shape[0]):
        l, r = fl[f], fr[f]
        for j in range(j0, j1):
            a = A[f, j]
            # extra going left -> right (a > 0) is limited by the right cell's inflow and the
            # left cell's outflow factor, and the other way round. A missing side does not
            # limit: its factor (read from row 0; R± lie in [0, 1]) is lifted above 1 by
            # arithmetic - a select on the value compiled to a branch on the sign of a, which
            # the CPU mispredicts (this pass ran 2.3× slower with it)
            up = 0 if a > 0.0 else 1
            ar = Rpm[max(r, 0), up, j] + 2.0 * (r < 0)
            al = Rpm[max(l, 0), 1 - up, j] + 2.0 * (l < 0)
            fa = min(ar, al) * a
            if 0 <= l < n_owned:
                E[l, j] -= fa
            if 0 <= r < n_owned:
                E[r, j] += fa
            if j == 0:
                fmass[f] = low[f, 0] + fa
