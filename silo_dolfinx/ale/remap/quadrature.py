"""Quadrature data ↔ cell means: what the remap moves is a cell's mass-weighted mean; the
points of a cell keep their internal variation as far as the local bounds allow."""

from __future__ import annotations

import numpy as np

from silo_dolfinx._jit_cache import numba
from silo_dolfinx.kernels import FAST


def redistribute(values: np.ndarray, nq: int, dV: np.ndarray, mean_new: np.ndarray, lo: np.ndarray,
                 hi: np.ndarray, j0: int = 0) -> None:
    """Quadrature-point values from remapped cell means, keeping each cell's internal
    variation as far as the local bounds allow: Q_q = Q̄' + θ (Q_q − Q̄_q), with Q̄_q the
    mean under the new point volumes (so the cell mean is exactly Q̄') and θ ∈ [0, 1] the
    largest factor keeping every point inside [lo, hi] (old values of the cell and its
    neighbours). In place on ``values`` (n·nq, c), whose means and bounds are columns
    j0..j0+c of ``mean_new``, ``lo`` and ``hi`` (n, k)."""
    _redistribute(values, nq, dV, mean_new, lo, hi, j0)


@numba.njit(cache=True, fastmath=FAST)
def _redistribute(values, nq, dV, mean_new, lo, hi, j0):
    nc = mean_new.shape[0]
    k = values.shape[1]
    for c in range(nc):
        b = c * nq
        vol = 0.0
        for q in range(nq):
            vol += dV[b + q]
        inv = 1.0 / vol
        for j in range(k):
            mean = 0.0
            for q in range(nq):
                mean += values[b + q, j] * dV[b + q]
            mean *= inv
            dmax = 0.0  # the cell's largest deviations above and below its mean
            dmin = 0.0
            for q in range(nq):
                d = values[b + q, j] - mean
                dmax = max(dmax, d)
                dmin = min(dmin, d)
            # the largest θ ≤ 1 with target + θ dmax ≤ hi and target + θ dmin ≥ lo (branch-free
            # selects: ~5x faster than testing every point)
            target = mean_new[c, j0 + j]
            room_hi = max(hi[c, j0 + j] - target, 0.0)
            room_lo = min(lo[c, j0 + j] - target, 0.0)
            theta = min(1.0, room_hi / dmax if dmax > 0.0 else 1.0, room_lo / dmin if dmin < 0.0 else 1.0)
            for q in range(nq):
                values[b + q, j] = target + theta * (values[b + q, j] - mean)


@numba.njit(cache=True, fastmath=FAST)
def cell_volume_density(rho_q, nq, dV, vol, rho):
    """Cell volumes and mean densities from the quadrature-point volumes and densities."""
    for c in range(vol.shape[0]):
        v = 0.0
        m = 0.0
        for q in range(nq):
            v += dV[c * nq + q]
            m += rho_q[c * nq + q] * dV[c * nq + q]
        vol[c] = v
        rho[c] = m / v


@numba.njit(cache=True, fastmath=FAST)
def cell_state(values, nq, dV, vol, j0, means, lo, hi):
    """One pass over the quadrature points of each cell: volume-weighted means of the
    values (n·nq, c) and their per-cell point range, into columns j0..j0+c of means, lo and
    hi (n, k); ``vol`` the cell volumes (:func:`cell_volume_density`)."""
    nc = vol.shape[0]
    k = values.shape[1]
    for c in range(nc):
        v = vol[c]
        for j in range(k):
            s = 0.0
            a = values[c * nq, j]
            b = a
            for q in range(nq):
                x = values[c * nq + q, j]
                s += x * dV[c * nq + q]
                a = min(a, x)
                b = max(b, x)
            means[c, j0 + j] = s / v
            lo[c, j0 + j] = a
            hi[c, j0 + j] = b
