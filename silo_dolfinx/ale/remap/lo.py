"""Low order: donor-cell fluxes (Remhos' LO stage). Each edge moves what its upwind cell
holds: mass ρ_up δV (stage 1), then every intensive variable as F·Q_up with the final mass
fluxes F (stage 2). A convex update under the Courant condition: monotone, first order.
Stage 1 also gathers the local bounds [min, max] over each cell and its edge neighbours that
the flux correction and the quadrature redistribution keep."""

from __future__ import annotations

from silo_dolfinx._jit_cache import numba
from silo_dolfinx.ale.remap.geometry import CLOSED, OUTSIDE, TWO_PI
from silo_dolfinx.kernels import FAST


@numba.njit(cache=True, fastmath=FAST)
def mass_fluxes(faces, nbr, R, mom, vol0, out):
    """Stage 1: donor-cell mass fluxes ρ_up δV of each edge into ``low[:, 0]``, the masses
    they leave in ``E[:, 0]``, the old densities, and the bounds of every column.

    faces = (left cell, right cell, n_owned); nbr (n_owned, 4): each owned cell's neighbour
    across each edge, itself across the boundary; R (n_all, 1 + k): density then the
    intensive variables; mom (n_faces, 3): moments of the swept regions; out = (E, low,
    qmin, qmax, rho_old)."""
    fl, fr, n_owned = faces
    E, low, qmin, qmax, rho_old = out
    k1 = R.shape[1]
    for c in range(n_owned):
        rho_old[c] = R[c, 0]
        E[c, 0] = R[c, 0] * vol0[c]
        # the bounds gathered per cell (2.7× faster than widening both cells of each edge)
        n0, n1, n2, n3 = nbr[c, 0], nbr[c, 1], nbr[c, 2], nbr[c, 3]
        for j in range(k1):
            a, b0, b1, b2, b3 = R[c, j], R[n0, j], R[n1, j], R[n2, j], R[n3, j]
            qmin[c, j] = min(a, min(min(b0, b1), min(b2, b3)))
            qmax[c, j] = max(a, max(max(b0, b1), max(b2, b3)))
    for f in range(fl.shape[0]):
        l, r = fl[f], fr[f]
        m0 = mom[f, 0]
        d = l if m0 > 0.0 else r
        if d < 0 or m0 == 0.0 or l == CLOSED or r == CLOSED:
            low[f, 0] = 0.0
            continue
        lo = TWO_PI * m0 * R[d, 0]
        low[f, 0] = lo
        if 0 <= l < n_owned:
            E[l, 0] -= lo
        if 0 <= r < n_owned:
            E[r, 0] += lo


@numba.njit(cache=True, fastmath=FAST - {"contract"})
def value_fluxes(faces, fmass, R, rho_old, vol0, E):
    """Stage 2: the totals m Q of columns 1..k of ``E`` after the donor-cell fluxes F·Q_up
    with the final mass fluxes ``fmass``. (No fused multiply-add here: E − F·Q rounds as the
    product, then the sum, exactly as when LO and HO shared one loop.)"""
    fl, fr, n_owned = faces
    k1 = R.shape[1]
    for c in range(n_owned):
        m = rho_old[c] * vol0[c]
        for j in range(1, k1):
            E[c, j] = m * R[c, j]
    for f in range(fl.shape[0]):
        l, r = fl[f], fr[f]
        F = fmass[f]
        d = l if F > 0.0 else r
        if d < 0 or F == 0.0:
            continue
        lown = 0 <= l < n_owned
        rown = 0 <= r < n_owned
        for j in range(1, k1):
            lo = F * R[d, j]
            if lown:
                E[l, j] -= lo
            if rown:
                E[r, j] += lo


@numba.njit(cache=True)
def outflow(faces, flux, out):
    """Mass leaving each owned cell through outflow edges."""
    fl, fr, n_owned = faces
    for f in range(fl.shape[0]):
        l, r = fl[f], fr[f]
        if r == OUTSIDE and 0 <= l < n_owned and flux[f] > 0.0:
            out[l] += flux[f]
        elif l == OUTSIDE and 0 <= r < n_owned and flux[f] < 0.0:
            out[r] -= flux[f]


@numba.njit(cache=True)
def divide(m, vol, fallback, out):
    """New densities m/V (the old one where a cell has no volume)."""
    for c in range(m.shape[0]):
        out[c] = m[c] / vol[c] if vol[c] > 0.0 else fallback[c]


@numba.njit(cache=True)
def values_from_totals(E, mnew, R, n_owned):
    """Intensive variables Q = (m Q)/m of columns 1..k."""
    for c in range(n_owned):
        if mnew[c] > 0.0:
            for j in range(1, R.shape[1]):
                R[c, j] = E[c, j] / mnew[c]
