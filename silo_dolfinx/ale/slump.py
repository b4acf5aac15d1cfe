"""Free-surface slump: a granular surface steeper than its angle of repose avalanches.

A cohesionless continuum at its free surface sits at the apex of its yield cone: no pressure,
no strength - and no force either that would make a steep lip or a pit slump. Real grains
roll down such slopes; the continuum keeps them (a pit on the axis where the flow channel
reaches the surface, a lip at a rough wall), and a mesh whose free surface follows the
material degenerates there (docs/validation/ch6.md, ch7.md). With ``ale.max_surface_slope``
= θ > 0, each smoothing moves the surface's nodes vertically so that no segment of the top
polyline is steeper than tan θ, and the remap moves the material with them, along the top
row of cells:

1. **the surface** (:func:`slump_heights`, at smoothing): Gauss-Seidel sweeps over the
   segments; a segment steeper than tan θ has its two nodes moved towards each other by
   dz_hi = −d W_lo/(W_hi + W_lo), dz_lo = d W_hi/(W_hi + W_lo) (d the excess drop, W the
   nodes' r-weighted tributary lengths ∫ N_i r dr), which keeps the volume of revolution
   under the polyline exactly; each node moves at most ``cap`` (a twentieth of its segments'
   length) per smoothing, so that a top cell gives or takes at most a few per cent of its
   volume per remap. A node that cannot move (a top corner on an inclined wall: it would
   leave the wall) leaves its segment as it is.
2. **the material** (:func:`top_row_transfer`, after the remap): the remap keeps each cell's
   mass when a boundary node moves, so the cell under a lowered segment is compressed and
   the one under a raised segment dilated, by the volumes δV_e its top edge swept between the
   material surface and the placed one (:func:`swept_volumes`). The volume −δV moves along
   the top row from cell to cell (a 1-D flux F_{e+½} = −Σ_{i≤e} δV_i, zero past the last cell
   as the placed surface keeps the material's volume), carrying the donor cell's density as
   it was before the smoothing changed its volume and its intensive variables (stress,
   state): mass is conserved exactly (every flux leaves one cell and enters the next), each
   cell is returned to about its density, and the mixing is a convex combination (no new
   extrema; the bounds of the quadrature redistribution are widened by the donors' values).
   This runs at every remap, slump or not: the top rule's own placement (nodes slid along a
   kinked surface, heights corrected to keep the volume under it, :mod:`.smoothing`) moves
   the top edges too, by less - without the transfer its remainder compressed a top cell in
   the ch. 4 scene's crater to 1,180 kg/m³ and crushed it at 63 s.

:class:`TopRow` finds the top row's cells in the order of the segments and gathers what the
transfer reads on every rank (a few dozen cells: one Allgatherv per remap).

The potential energy the slump releases is an avalanche's dissipation (not tracked: nothing
the energy balance sums changes with it); the kinetic and elastic energy the moved mass
carries are booked with the remap's.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from silo_dolfinx._jit_cache import numba

CAP = 0.05  # largest vertical move of a surface node per smoothing, as a fraction of its segments' length
SWEEPS = 8  # Gauss-Seidel sweeps over the segments per smoothing


@numba.njit(cache=True)
def _segment_weights(a, b):
    """(∫ N_a r dr, ∫ N_b r dr) over a segment from radius a to b (linear N)."""
    h = abs(b - a)
    return h * (2.0 * a + b) / 6.0, h * (a + 2.0 * b) / 6.0


@numba.njit(cache=True)
def tributary(r, out):
    """∫ N_i r dr of each node of a polyline with radii r (the volume of revolution under it
    changes by 2π Σ W_i dz_i when its nodes move by dz_i vertically)."""
    out[:] = 0.0
    for e in range(r.size - 1):
        wa, wb = _segment_weights(r[e], r[e + 1])
        out[e] += wa
        out[e + 1] += wb


@numba.njit(cache=True)
def slump_heights(r, z, movable, tan_max, dz):
    """Vertical moves dz of the polyline nodes (r, z) (axis first) that bring its segments to
    slopes ≤ tan_max, keeping the volume under it (module doc); returns the largest excess
    slope left (0 when none)."""
    n = r.size
    W = np.empty(n)
    tributary(r, W)
    zz = z.copy()
    cap = np.empty(n)
    for i in range(n):
        left = abs(r[i] - r[i - 1]) if i > 0 else np.inf
        right = abs(r[i + 1] - r[i]) if i < n - 1 else np.inf
        cap[i] = CAP * min(left, right)
    dz[:] = 0.0
    for _ in range(SWEEPS):
        moved = False
        for e in range(n - 1):
            a, b = e, e + 1
            if not (movable[a] and movable[b]):
                continue
            d = abs(zz[a] - zz[b]) - tan_max * abs(r[b] - r[a])
            if d <= 0.0:
                continue
            hi, lo = (a, b) if zz[a] > zz[b] else (b, a)
            s = W[hi] + W[lo]
            if s <= 0.0:
                continue
            # the excess that both nodes can still take within their caps
            room_hi = cap[hi] + dz[hi]  # how far it may still go down: |dz| ≤ cap
            room_lo = cap[lo] - dz[lo]  # and up
            d = min(d, room_hi * s / max(W[lo], 1e-300), room_lo * s / max(W[hi], 1e-300))
            if d <= 0.0:
                continue
            down, up = d * W[lo] / s, d * W[hi] / s
            dz[hi] -= down
            dz[lo] += up
            zz[hi] -= down
            zz[lo] += up
            moved = True
        if not moved:
            break
    excess = 0.0
    for e in range(n - 1):
        excess = max(excess, abs(zz[e] - zz[e + 1]) / max(abs(r[e + 1] - r[e]), 1e-300) - tan_max)
    return excess


@numba.njit(cache=True)
def swept_volumes(old, new, out):
    """δV_e: the volume of revolution swept by segment e of a polyline moving from ``old`` to
    ``new`` (nodes (r, z), axis first), positive where it rose - how much the smoothing changed
    the volume of the top cell under it while the remap kept that cell's mass: 2π ∫∫ r dA over
    the quadrilateral (old_e, old_e+1, new_e+1, new_e). For vertical moves dz at fixed r it is
    2π ∫ dz(r) r dr; the segments' sum is the change of the volume under the polyline (the
    shared sides cancel), zero when the ends stay."""
    for e in range(old.shape[0] - 1):
        q = ((old[e, 0], old[e, 1]), (old[e + 1, 0], old[e + 1, 1]), (new[e + 1, 0], new[e + 1, 1]),
             (new[e, 0], new[e, 1]))
        m = 0.0
        for k in range(4):
            r0, z0 = q[k]
            r1, z1 = q[(k + 1) % 4]
            m += (r0 + r1) * (r0 * z1 - r1 * z0)
        out[e] = 2.0 * np.pi * m / 6.0


@numba.njit(cache=True)
def top_row_transfer(dV, V, mass, Q, dm, dQ):
    """Mass and intensive-variable changes (dm, and dQ (n, k) of the mass-weighted totals
    m Q) of the top-row cells (in segment order) that move the slumped volume along the row:
    ``V`` their volumes and ``mass`` their masses after the remap, ``Q`` their intensive
    means. A flux leaves its donor at the density it had before the slump changed its volume,
    m / (V − δV); at most half of a donor's mass per remap."""
    n = dV.size
    dm[:] = 0.0
    dQ[:] = 0.0
    F = 0.0
    for e in range(n - 1):
        F -= dV[e]  # volume moving from cell e to e + 1 (negative: from e + 1 to e)
        donor = e if F > 0.0 else e + 1
        M = F * mass[donor] / max(V[donor] - dV[donor], 1e-300)
        M = max(-0.5 * mass[donor], min(0.5 * mass[donor], M))
        dm[e] -= M
        dm[e + 1] += M
        for j in range(Q.shape[1]):
            dQ[e, j] -= M * Q[donor, j]
            dQ[e + 1, j] += M * Q[donor, j]


class TopRow:
    """The top row of cells in the order of the surface's segments, gathered on every rank for
    the transfer along it (module doc): each segment is the top edge of one owned
    cell somewhere."""

    def __init__(self, sm, smoother, n_owned: int):
        from dolfinx import mesh as dmesh

        m = sm.mesh
        facets = sm.facets("top")
        m.topology.create_connectivity(1, 2)
        f2c = m.topology.connectivity(1, 2)
        cells = np.array([f2c.links(f)[0] for f in facets], np.int64)
        nodes = dmesh.entities_to_geometry(m, 1, facets)
        pos = smoother.top_position[nodes]
        own = cells < n_owned
        self.cells = cells[own]
        self.segment = pos[own].min(axis=1)  # segment e joins polyline nodes e and e + 1
        self.comm = m.comm
        counts = np.array(self.comm.allgather(self.cells.size))
        self.n = int(counts.sum())
        segs = np.concatenate(self.comm.allgather(self.segment))
        if not np.array_equal(np.sort(segs), np.arange(self.n)):
            raise ValueError("the top surface's segments are not the top edges of one cell each: not a silo mesh")
        self._order = np.argsort(segs)
        self._counts = counts
        self._displs = np.concatenate([[0], np.cumsum(counts)[:-1]])

    def transfer(self, dV, volumes, rho, means, bounds) -> None:
        """Move the volumes ``dV`` the smoothing swept with the top edges (:func:`swept_volumes`,
        by segment) along the top row as material (in place on the owned cells' densities
        ``rho`` and mass-weighted means ``means``; ``bounds`` (lo, hi) widened)."""
        k = means.shape[1]
        c = self.cells
        local = np.column_stack([rho[c] * volumes[c], volumes[c], means[c]])
        rows = np.empty((self.n, 2 + k))
        self.comm.Allgatherv(np.ascontiguousarray(local), [rows, self._counts * (2 + k), self._displs * (2 + k), MPI.DOUBLE])
        rows = rows[self._order]  # by segment
        mass, V, Q = rows[:, 0].copy(), rows[:, 1].copy(), np.ascontiguousarray(rows[:, 2:])
        dm, dQ = np.zeros(self.n), np.zeros((self.n, k))
        top_row_transfer(dV, V, mass, Q, dm, dQ)
        e = self.segment
        m_new = mass[e] + dm[e]
        means[c] = (mass[e, None] * Q[e] + dQ[e]) / m_new[:, None]
        rho[c] = m_new / volumes[c]
        lo, hi = bounds
        lo[c] = np.minimum(lo[c], means[c])
        hi[c] = np.maximum(hi[c], means[c])
