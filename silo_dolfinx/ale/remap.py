"""Conservative, bound-preserving remap onto a moved mesh (the Eulerian phase of ALE).

The mesh moves from positions ``x0`` (after the Lagrangian steps) to ``x1`` (after smoothing).
Every edge sweeps a quadrilateral (a0, b0, b1, a1); its signed volume of revolution
δV = 2π ∫ r dA is exactly the volume that changes hands between the two cells of the edge
(the swept regions tile each cell's change of volume, for any integrand). The state follows
the swept volumes, as in the flux-form remap of Dukowicz & Baumgardner (2000) and Margolin
& Shashkov (2003), in the low-order + flux-correction arrangement of MFEM's Remhos:

**Cells (quadrature data)** — three conserved totals per cell, transported in two stages:

1. *mass*: low order (LO) is donor cell, m' = m + Σ ρ_up δV; high order (HO) reconstructs
   ρ linearly in the upwind cell (least-squares gradient about its r-weighted centroid) and
   integrates it exactly over the swept region using its moments ∫r, ∫r², ∫rz dA;
2. *every intensive variable Q* (stress components, plastic strain, ...) as ρQ with the
   final mass fluxes F of stage 1: LO F·Q_up, HO F·Q(x_f) at the swept region's centroid.

In each stage the HO − LO difference is limited by Zalesak's flux-corrected transport with
the local bounds [min, max] of the cell and its edge neighbours, so no new extremum is
created (the LO update is a convex combination under the Courant condition, which the
caller guarantees by sub-cycling the motion). Order 1 uses LO only. The new density is
m'/V' with the exact new volume; totals are conserved to round-off because every edge flux
is added to one cell and subtracted from the other (on two ranks, both compute the same
number from the same data: edges are oriented by global node index).

**Nodes (velocity)** — momentum lives on corners m_{c,a} = ρ_c ∫_c N_a 2πr dA (they sum to
the row-sum lumped mass). Mass crossing a cell edge near node a moves between two corners of
the same node (no change of nodal momentum); mass moving *inside* a cell crosses the four
dual segments (centroid to edge midpoints) between corners, carrying the upwind node's
velocity. The four intra-cell corner fluxes are fixed, up to a circulation, by requiring
each corner to end with exactly its new mass ρ'_c ∫ N_a 2πr dA on the new mesh; the
circulation is the least-squares fit to the swept volumes of the dual segments. Hence

* the new nodal mass is exactly the lumped mass of the new mesh and density (the solver's
  rebuilt mass agrees to round-off), so a uniform velocity is reproduced exactly;
* momentum Σ M v is conserved to round-off (minus what leaves through an outflow edge);
* each new velocity is a convex combination of old ones (first order, donor corner).

Outflow edges (an Eulerian outlet) let material out, never in; other boundary edges carry
nothing (a wall or free-surface node that moves along its boundary changes its cell's
volume, and the cell keeps its mass).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from mpi4py import MPI

from silo_dolfinx._mpi import reduce_scalar
from silo_dolfinx.geometry.cells import CYCLE, orientation, tensor_nodes
from silo_dolfinx.kernels import FAST

TWO_PI = 2.0 * math.pi
CLOSED = -1  # the far side of a wall / free-surface / axis edge
OUTSIDE = -2  # the far side of an outflow edge
COURANT = 0.5  # largest fraction of a cell's volume that one sub-step may move out of it


@dataclass
class RemapReport:
    """What one remap did (rank-local sums unless noted)."""

    substeps: int = 1
    courant: float = 0.0  # global max swept-out fraction of a cell before sub-cycling
    outflow_mass: float = 0.0  # kg left through outflow edges (local)
    outflow_momentum: tuple[float, float] = (0.0, 0.0)  # kg m/s (local)
    outflow_kinetic: float = 0.0  # J carried out (local)
    outflow_cells: np.ndarray | None = None  # kg out of each owned cell (local)


class Remapper:
    """Flux-form remap of cell means and nodal velocities between two node positions.

    ``outflow_facets``: local facet indices of the boundary where material may leave.
    Cell data are per owned cell; nodal data per local geometry node (owned + ghost).
    Needs ghost cells in parallel (the silo mesher distributes with shared-facet ghosts)."""

    def __init__(self, mesh, outflow_facets: np.ndarray | None = None, order: int = 2):
        from dolfinx import la

        self.mesh = mesh
        self.comm = mesh.comm
        self.order = order
        top = mesh.topology
        tdim = top.dim
        cmap = top.index_map(tdim)
        self.n_owned = cmap.size_local
        self.n_all = cmap.size_local + cmap.num_ghosts
        if self.comm.size > 1 and self.comm.allreduce(cmap.num_ghosts, op=MPI.SUM) == 0:
            raise ValueError("the ALE remap needs ghost cells: create the mesh with "
                             "dolfinx.mesh.GhostMode.shared_facet (the silo mesher does)")
        self.cell_map = cmap
        self.cn_tensor = tensor_nodes(mesh, self.n_all)
        self.cn = np.ascontiguousarray(self.cn_tensor[:, CYCLE])
        x = mesh.geometry.x
        self.orient = orientation(x, self.cn)

        # facets touching an owned cell, oriented by global node index
        top.create_connectivity(tdim - 1, tdim)
        top.create_connectivity(tdim, tdim - 1)
        f2c = top.connectivity(tdim - 1, tdim)
        nf_local = top.index_map(tdim - 1).size_local + top.index_map(tdim - 1).num_ghosts
        off, arr = f2c.offsets, f2c.array
        count = np.diff(off)
        first = arr[off[:-1]]
        second = np.where(count > 1, arr[np.minimum(off[:-1] + 1, arr.size - 1)], -1)
        touches = (first < self.n_owned) | ((second >= 0) & (second < self.n_owned))
        facets = np.nonzero(touches)[0].astype(np.int32)
        from dolfinx import mesh as dmesh

        fnodes = dmesh.entities_to_geometry(mesh, tdim - 1, facets).astype(np.int64)
        gidx = mesh.geometry.index_map().local_to_global(np.arange(x.shape[0], dtype=np.int32))
        swap = gidx[fnodes[:, 0]] > gidx[fnodes[:, 1]]
        fnodes[swap] = fnodes[swap][:, ::-1]
        self.fnodes = np.ascontiguousarray(fnodes)
        outflow = np.zeros(nf_local, bool)
        if outflow_facets is not None:
            outflow[np.asarray(outflow_facets, np.int64)] = True
        c0, c1 = first[facets].astype(np.int64), second[facets].astype(np.int64)
        far = np.where(outflow[facets], OUTSIDE, CLOSED)
        c1 = np.where(c1 < 0, far, c1)
        self.fleft, self.fright = _sides(self.cn, self.orient, self.fnodes, c0, c1)
        self.facets = facets
        nf = facets.size
        self.cell_facets, self.cell_side = _cell_facets(self.cn, self.fnodes, self.fleft, self.fright, self.n_owned)

        # work arrays (allocated once)
        self._vol0 = np.zeros(self.n_all)
        self._vol1 = np.zeros(self.n_all)
        self._cen0 = np.zeros((self.n_all, 2))
        self._swept = np.zeros((nf, 3))
        self._xf = np.zeros((nf, 2))
        self._x0 = np.zeros((x.shape[0], 2))
        self._x1 = np.zeros((x.shape[0], 2))
        nodes = mesh.geometry.index_map()
        self.n_nodes = nodes.size_local + nodes.num_ghosts
        self.n_nodes_owned = nodes.size_local
        self._nodal = la.vector(nodes, 3)
        self._vnode = la.vector(nodes, 2)

    # ------------------------------------------------------------------ ghost exchange
    def _ghosted(self, *shape: int, fill: float = 0.0) -> tuple[np.ndarray, object]:
        """A (n_all, *shape) cell array living in a DOLFINx vector on the cell index map, so
        that filling its ghost rows from their owners is one ``scatter_forward`` (no copies)."""
        from dolfinx import la

        vec = la.vector(self.cell_map, int(np.prod(shape)))
        vec.array[:] = fill
        return vec.array.reshape(self.n_all, *shape), vec

    # ------------------------------------------------------------------ queries
    def volumes(self, x: np.ndarray) -> np.ndarray:
        """Exact volumes of revolution of the local cells at node positions ``x``."""
        vol = np.zeros(self.n_all)
        cen = np.zeros((self.n_all, 2))
        _cell_geometry(np.ascontiguousarray(x[:, :2]), self.cn, self.orient, vol, cen)
        return vol

    def nodal_mass(self, x: np.ndarray, rho: np.ndarray) -> np.ndarray:
        """Row-sum lumped mass Σ_c ρ_c ∫ N_a 2πr dA of the local nodes (owned exact, ghosts
        updated) at positions ``x`` for owned-cell densities ``rho``."""
        from dolfinx import la

        acc = self._nodal.array.reshape(-1, 3)
        acc[:] = 0.0
        _lumped(np.ascontiguousarray(x[:, :2]), self.cn_tensor, np.asarray(rho, float), self.n_owned, acc)
        self._nodal.scatter_reverse(la.InsertMode.add)
        self._nodal.scatter_forward()
        return acc[:, 2].copy()

    def courant(self, x0: np.ndarray, x1: np.ndarray) -> float:
        """Largest fraction of a cell's volume swept out of it by the motion x0 -> x1 (global)."""
        self._load(x0, x1)
        _cell_geometry(self._x0, self.cn, self.orient, self._vol0, self._cen0)
        _swept(self._x0, self._x1, self.fnodes, self._swept, self._xf)
        c = _courant(self.fleft, self.fright, self._swept, self._vol0, self.n_owned)
        return reduce_scalar(self.comm, c, MPI.MAX)

    def _load(self, x0, x1):
        self._x0[:] = x0[:, :2]
        self._x1[:] = x1[:, :2]

    # ------------------------------------------------------------------ the remap
    def remap(self, x0: np.ndarray, x1: np.ndarray, rho: np.ndarray, q: np.ndarray, v: np.ndarray,
              bounds: tuple[np.ndarray, np.ndarray] | None = None) -> RemapReport:
        """Remap in place from node positions x0 to x1 (local nodes, owned + ghost).

        rho (n_owned,): cell densities; q (n_owned, k): mass-weighted cell means of the
        intensive variables; v (n_nodes, 2): nodal velocities (ghosts current). On return
        they hold the remapped values (ghost velocities updated). ``bounds`` (lo, hi) of
        shape (n_owned, k), if given, are widened to every value that entered a cell's
        local bounds (for the caller's quadrature-point redistribution)."""
        report = RemapReport()
        c = self.courant(x0, x1)  # leaves the geometry of the whole motion in the work arrays
        report.courant = c
        n = max(1, int(math.ceil(c / COURANT)))
        report.substeps = n
        k = q.shape[1]
        w = self._workspace(k)
        R = w["R"]
        R[: self.n_owned, 0] = rho
        R[: self.n_owned, 1:] = q
        out = np.zeros(4)  # mass, momentum r, z, kinetic energy out
        report.outflow_cells = np.zeros(self.n_owned)
        for j in range(n):
            if n > 1:
                self._x0[:] = x0[:, :2] + (x1[:, :2] - x0[:, :2]) * (j / n)
                self._x1[:] = x0[:, :2] + (x1[:, :2] - x0[:, :2]) * ((j + 1) / n) if j < n - 1 else x1[:, :2]
                _cell_geometry(self._x0, self.cn, self.orient, self._vol0, self._cen0)
                _swept(self._x0, self._x1, self.fnodes, self._swept, self._xf)
            self._substep(w, v, k, bounds, out, report.outflow_cells)
        rho[:] = R[: self.n_owned, 0]
        q[:] = R[: self.n_owned, 1:]
        report.outflow_mass = float(out[0])
        report.outflow_momentum = (float(out[1]), float(out[2]))
        report.outflow_kinetic = float(out[3])
        return report

    def _workspace(self, k: int) -> dict:
        """Work arrays for k intensive variables (allocated once)."""
        w = getattr(self, "_work", None)
        if w is not None and w["k"] == k:
            return w
        na, no, nf = self.n_all, self.n_owned, self.fnodes.shape[0]
        (R, vR), (grads, vgrads), (Rpm, vRpm) = (self._ghosted(1 + k), self._ghosted(1 + k, 2),
                                                 self._ghosted(2, 1 + k, fill=1.0))
        self._work = w = {
            "k": k, "R": R, "grads": grads, "Rpm": Rpm, "vec": {"R": vR, "grads": vgrads, "Rpm": vRpm},
            "cen1": np.zeros((na, 2)), "low": np.zeros((nf, 1)), "A": np.zeros((nf, 1 + k)),
            "E": np.zeros((no, 1 + k)), "mnew": np.zeros(no), "qmin": np.zeros((no, 1 + k)),
            "pp": np.zeros((no, 1 + k)), "pm": np.zeros((no, 1 + k)),
            "qmax": np.zeros((no, 1 + k)), "fmass": np.zeros(nf), "rho_old": np.zeros(no), "rho_new": np.zeros(no),
        }
        return w

    def _substep(self, w, v, k, bounds, out, out_cells):
        from dolfinx import la

        x0, x1 = self._x0, self._x1
        _cell_geometry(x1, self.cn, self.orient, self._vol1, w["cen1"])
        R, grads, vec = w["R"], w["grads"], w["vec"]
        vec["R"].scatter_forward()
        no = self.n_owned
        ho = self.order >= 2
        if ho:
            _ls_gradients(R, self._cen0, self.fleft, self.fright, no, grads)
            vec["grads"].scatter_forward()
        fl, fr = self.fleft, self.fright
        low, A, Rpm, E, qmin, qmax = w["low"], w["A"], w["Rpm"], w["E"], w["qmin"], w["qmax"]
        fmass, mnew, rho_old, rho_new = w["fmass"], w["mnew"], w["rho_old"], w["rho_new"]

        # stage 1: mass (the density transported by the volume fluxes); column 0
        pp, pm = w["pp"], w["pm"]
        _mass_stage_low(fl, fr, R, grads, self._cen0, self._swept, self._vol0, self._vol1, ho, no, E, low, A, Rpm,
                        qmin, qmax, pp, pm, rho_old)
        if ho:
            vec["Rpm"].scatter_forward()
        _fct_apply(fl, fr, low, A, Rpm, ho, no, 0, 1, E, fmass)
        mnew[:] = E[:, 0]
        _outflow(fl, fr, fmass, no, out_cells)
        if mnew.min(initial=0.0) < 0.0:
            raise FloatingPointError("remap produced a negative cell mass (Courant condition violated)")
        _divide(mnew, self._vol1, rho_old, rho_new)

        # stage 2: intensive variables, mass-weighted, with the final mass fluxes; columns 1..k
        if k:
            _value_stage_low(fl, fr, fmass, R, grads, self._cen0, self._xf, rho_old, self._vol0, mnew, ho, no, E,
                             A, Rpm, qmin, qmax, pp, pm)
            if bounds is not None:
                np.minimum(bounds[0], qmin[:, 1:], out=bounds[0])
                np.maximum(bounds[1], qmax[:, 1:], out=bounds[1])
            if ho:
                vec["Rpm"].scatter_forward()
            _fct_apply(fl, fr, low, A, Rpm, ho, no, 1, 1 + k, E, fmass)
            _values_from_totals(E, mnew, R, no)

        # nodal velocity (needs the old and new densities of every owned cell)
        acc = self._nodal.array.reshape(-1, 3)
        acc[:] = 0.0
        o = np.zeros(4)
        _nodal_remap(x0, x1, self.cn_tensor, self.cn, self.orient, rho_old, rho_new, fmass, self.cell_facets,
                     self.cell_side, fr, fl, v, no, acc, o)
        self._nodal.scatter_reverse(la.InsertMode.add)
        vv = self._vnode.array.reshape(-1, 2)
        _velocity(acc, v, self.n_nodes_owned, vv)
        self._vnode.scatter_forward()
        v[:] = vv
        out += o
        R[:no, 0] = rho_new


# ---------------------------------------------------------------------------- set-up kernels
@numba.njit(cache=True, fastmath=FAST, inline="always")
def _edge_moments(x0, y0, x1, y1):
    cr = x0 * y1 - x1 * y0
    return ((x0 + x1) * cr, (x0 * x0 + x0 * x1 + x1 * x1) * cr,
            (x0 * y1 + 2.0 * x0 * y0 + 2.0 * x1 * y1 + x1 * y0) * cr)


@numba.njit(cache=True, fastmath=FAST)
def _moments(r0, z0, r1, z1, r2, z2, r3, z3):
    """(∫ r dA, ∫ r² dA, ∫ r z dA) over the quadrilateral 0-1-2-3 (signed: positive if
    counter-clockwise; exact for straight edges). Scalars in and out: called per cell and
    per edge in the hot loops, where array arguments would cost reference counting."""
    a0, a1, a2 = _edge_moments(r0, z0, r1, z1)
    b0, b1, b2 = _edge_moments(r1, z1, r2, z2)
    c0, c1, c2 = _edge_moments(r2, z2, r3, z3)
    d0, d1, d2 = _edge_moments(r3, z3, r0, z0)
    return (a0 + b0 + c0 + d0) / 6.0, (a1 + b1 + c1 + d1) / 12.0, (a2 + b2 + c2 + d2) / 24.0


@numba.njit(cache=True)
def _sides(cn, orient, fnodes, c0, c1):
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
def _cell_facets(cn, fnodes, fl, fr, n_owned):
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
def _cell_geometry(x, cn, orient, vol, cen):
    for c in range(cn.shape[0]):
        a, b, d, e = cn[c, 0], cn[c, 1], cn[c, 2], cn[c, 3]
        m0, mr, mz = _moments(x[a, 0], x[a, 1], x[b, 0], x[b, 1], x[d, 0], x[d, 1], x[e, 0], x[e, 1])
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
def _swept(x0, x1, fnodes, out, xf):
    """Moments of the region swept by each facet a->b, and the point to reconstruct at."""
    for f in range(fnodes.shape[0]):
        a, b = fnodes[f, 0], fnodes[f, 1]
        p0r, p0z, p1r, p1z = x0[a, 0], x0[a, 1], x0[b, 0], x0[b, 1]
        p2r, p2z, p3r, p3z = x1[b, 0], x1[b, 1], x1[a, 0], x1[a, 1]
        m0, mr, mz = _moments(p0r, p0z, p1r, p1z, p2r, p2z, p3r, p3z)
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
def _courant(fl, fr, swept, vol, n_owned):
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


@numba.njit(cache=True, fastmath=FAST, inline="always")
def _normal_terms(c, l, r, vals, w, dx, dy, axx, axy, ayy, b):
    """Add the least-squares terms of edge (l, r) (centroid offset dx, dy; weight w) to cell c."""
    axx[c] += w * dx * dx
    axy[c] += w * dx * dy
    ayy[c] += w * dy * dy
    for j in range(vals.shape[1]):
        dq = vals[r, j] - vals[l, j]
        b[c, j, 0] += w * dx * dq
        b[c, j, 1] += w * dy * dq


@numba.njit(cache=True, fastmath=FAST)
def _ls_gradients(vals, cen, fl, fr, n_owned, grads):
    """Least-squares gradients (weights 1/|Δx|²) of every column of ``vals`` in owned cells."""
    k = vals.shape[1]
    axx = np.zeros(n_owned)
    axy = np.zeros(n_owned)
    ayy = np.zeros(n_owned)
    b = np.zeros((n_owned, k, 2))
    for f in range(fl.shape[0]):
        l, r = fl[f], fr[f]
        if l < 0 or r < 0:
            continue
        dx = cen[r, 0] - cen[l, 0]
        dy = cen[r, 1] - cen[l, 1]
        w = 1.0 / (dx * dx + dy * dy + 1e-300)
        # both cells of the edge get the same normal-equation terms (the signs of Δx and Δq cancel)
        if l < n_owned:
            _normal_terms(l, l, r, vals, w, dx, dy, axx, axy, ayy, b)
        if r < n_owned:
            _normal_terms(r, l, r, vals, w, dx, dy, axx, axy, ayy, b)
    for c in range(n_owned):
        det = axx[c] * ayy[c] - axy[c] * axy[c]
        if det <= 1e-10 * (axx[c] + ayy[c]) ** 2:
            for j in range(k):
                grads[c, j, 0] = 0.0
                grads[c, j, 1] = 0.0
            continue
        for j in range(k):
            grads[c, j, 0] = (ayy[c] * b[c, j, 0] - axy[c] * b[c, j, 1]) / det
            grads[c, j, 1] = (axx[c] * b[c, j, 1] - axy[c] * b[c, j, 0]) / det


@numba.njit(cache=True, fastmath=FAST, inline="always")
def _face_bounds(l, r, vals, j0, j1, n_owned, qmin, qmax):
    """Widen the [min, max] of columns j0..j1 of the owned cells of an interior edge by the
    value across it (called in the flux loops: the cell and edge-neighbour bounds in the
    same pass over the edges)."""
    if l < 0 or r < 0:
        return
    for j in range(j0, j1):
        if l < n_owned:
            qmin[l, j] = min(qmin[l, j], vals[r, j])
            qmax[l, j] = max(qmax[l, j], vals[r, j])
        if r < n_owned:
            qmin[r, j] = min(qmin[r, j], vals[l, j])
            qmax[r, j] = max(qmax[r, j], vals[l, j])


@numba.njit(cache=True, fastmath=FAST)
def _limiters(E, mnew, qmin, qmax, pp, pm, j0, j1, n_owned, Rpm):
    for c in range(n_owned):
        for j in range(j0, j1):
            qp = max(0.0, mnew[c] * qmax[c, j] - E[c, j])
            qm = min(0.0, mnew[c] * qmin[c, j] - E[c, j])
            Rpm[c, 0, j] = min(1.0, qp / pp[c, j]) if pp[c, j] > 0.0 else 1.0
            Rpm[c, 1, j] = min(1.0, qm / pm[c, j]) if pm[c, j] < 0.0 else 1.0


@numba.njit(cache=True, fastmath=FAST)
def _mass_stage_low(fl, fr, R, grads, cen, mom, vol0, vol1, ho, n_owned, E, low, A, Rpm, qmin, qmax, pp, pm,
                    rho_old):
    """Stage 1, low order: donor-cell mass fluxes ρ_up δV into ``low[:, 0]``, the masses they
    leave in ``E[:, 0]``; high order: the upwind linear reconstruction integrated exactly over
    the swept region (from its moments), the difference in ``A[:, 0]``; Zalesak's limiters for
    ρ ∈ [min, max] of the neighbourhood on the new volume. Column 0 of the work arrays.

    The same pass over the edges gathers the bounds [qmin, qmax] (cell and edge neighbours)
    of every column, at any order: stage 2 and the quadrature redistribution use them too."""
    k1 = R.shape[1]
    for c in range(n_owned):
        rho_old[c] = R[c, 0]
        E[c, 0] = R[c, 0] * vol0[c]
        for j in range(k1):
            qmin[c, j] = qmax[c, j] = R[c, j]
        pp[c, 0] = pm[c, 0] = 0.0
    for f in range(fl.shape[0]):
        l, r = fl[f], fr[f]
        _face_bounds(l, r, R, 0, k1, n_owned, qmin, qmax)
        m0 = mom[f, 0]
        d = l if m0 > 0.0 else r
        if d < 0 or m0 == 0.0 or l == CLOSED or r == CLOSED:
            low[f, 0] = 0.0
            A[f, 0] = 0.0
            continue
        lo = TWO_PI * m0 * R[d, 0]
        a = 0.0
        if ho:
            hi = TWO_PI * (R[d, 0] * m0 + grads[d, 0, 0] * (mom[f, 1] - cen[d, 0] * m0)
                           + grads[d, 0, 1] * (mom[f, 2] - cen[d, 1] * m0))
            a = hi - lo
        low[f, 0] = lo
        A[f, 0] = a
        if 0 <= l < n_owned:  # Zalesak's sums, as in _value_stage_low
            E[l, 0] -= lo
            pm[l, 0] -= max(a, 0.0)
            pp[l, 0] -= min(a, 0.0)
        if 0 <= r < n_owned:
            E[r, 0] += lo
            pp[r, 0] += max(a, 0.0)
            pm[r, 0] += min(a, 0.0)
    if ho:
        _limiters(E, vol1, qmin, qmax, pp, pm, 0, 1, n_owned, Rpm)


@numba.njit(cache=True, fastmath=FAST)
def _value_stage_low(fl, fr, fmass, R, grads, cen, xf, rho_old, vol0, mnew, ho, n_owned, E, A, Rpm, qmin, qmax,
                     pp, pm):
    """Stage 2, low order: F·Q_up with the final mass fluxes F (columns 1..k of E hold the
    totals m Q); high order: F·Q at the swept region's centroid; limiters for Q in the
    bounds [qmin, qmax] that stage 1 gathered."""
    k1 = R.shape[1]
    for c in range(n_owned):
        m = rho_old[c] * vol0[c]
        for j in range(1, k1):
            E[c, j] = m * R[c, j]
            pp[c, j] = pm[c, j] = 0.0
    for f in range(fl.shape[0]):
        l, r = fl[f], fr[f]
        F = fmass[f]
        d = l if F > 0.0 else r
        if d < 0 or F == 0.0:
            for j in range(1, k1):
                A[f, j] = 0.0
            continue
        lown = 0 <= l < n_owned
        rown = 0 <= r < n_owned
        dr = xf[f, 0] - cen[d, 0]
        dz = xf[f, 1] - cen[d, 1]
        for j in range(1, k1):
            lo = F * R[d, j]  # the low-order flux goes straight into the totals
            a = F * (grads[d, j, 0] * dr + grads[d, j, 1] * dz) if ho else 0.0
            A[f, j] = a
            # Zalesak's sums of the antidiffusive fluxes into (pp) and out of (pm) each cell
            # (branch-free: the sign of a is data, not a pattern the CPU can predict)
            ap = max(a, 0.0)
            am = min(a, 0.0)
            if lown:
                E[l, j] -= lo
                pm[l, j] -= ap
                pp[l, j] -= am
            if rown:
                E[r, j] += lo
                pp[r, j] += ap
                pm[r, j] += am
    if ho:
        _limiters(E, mnew, qmin, qmax, pp, pm, 1, k1, n_owned, Rpm)


@numba.njit(cache=True, fastmath=FAST)
def _fct_apply(fl, fr, low, A, Rpm, ho, n_owned, j0, j1, E, fmass):
    """Add the limited antidiffusive fluxes α A to the owned totals E (columns j0..j1); for
    column 0 (mass) store the final facet fluxes low + α A in ``fmass``."""
    for f in range(fl.shape[0]):
        l, r = fl[f], fr[f]
        if not ho:
            if j0 == 0:
                fmass[f] = low[f, 0]
            continue
        for j in range(j0, j1):
            a = A[f, j]
            # extra going left -> right (a > 0) is limited by the right cell's inflow and the
            # left cell's outflow factor, and the other way round (selects, not branches)
            up = 0 if a > 0.0 else 1
            ar = Rpm[r, up, j] if r >= 0 else 1.0
            al = Rpm[l, 1 - up, j] if l >= 0 else 1.0
            fa = min(ar, al) * a
            if 0 <= l < n_owned:
                E[l, j] -= fa
            if 0 <= r < n_owned:
                E[r, j] += fa
            if j == 0:
                fmass[f] = low[f, 0] + fa


@numba.njit(cache=True)
def _divide(m, vol, fallback, out):
    for c in range(m.shape[0]):
        out[c] = m[c] / vol[c] if vol[c] > 0.0 else fallback[c]


@numba.njit(cache=True)
def _values_from_totals(E, mnew, R, n_owned):
    for c in range(n_owned):
        if mnew[c] > 0.0:
            for j in range(1, R.shape[1]):
                R[c, j] = E[c, j] / mnew[c]


@numba.njit(cache=True)
def _velocity(acc, v, nn, out):
    for i in range(nn):
        M = acc[i, 2]
        if M > 0.0:
            out[i, 0] = acc[i, 0] / M
            out[i, 1] = acc[i, 1] / M
        else:
            out[i, 0] = v[i, 0]
            out[i, 1] = v[i, 1]


@numba.njit(cache=True)
def _outflow(fl, fr, flux, n_owned, out):
    """Mass leaving each owned cell through outflow facets."""
    for f in range(fl.shape[0]):
        l, r = fl[f], fr[f]
        if r == OUTSIDE and 0 <= l < n_owned and flux[f] > 0.0:
            out[l] += flux[f]
        elif l == OUTSIDE and 0 <= r < n_owned and flux[f] < 0.0:
            out[r] -= flux[f]


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
def _lumped(x, cn_tensor, rho, n_owned, acc):
    for c in range(n_owned):
        a, b, cc, d = cn_tensor[c, 0], cn_tensor[c, 1], cn_tensor[c, 2], cn_tensor[c, 3]
        I = corner_integrals(x, a, b, cc, d)
        acc[a, 2] += rho[c] * I[0]
        acc[b, 2] += rho[c] * I[1]
        acc[cc, 2] += rho[c] * I[2]
        acc[d, 2] += rho[c] * I[3]


@numba.njit(cache=True, fastmath=FAST)
def _nodal_remap(x0, x1, cn_tensor, cn, orient, rho_old, rho_new, fmass, cell_facets, cell_side, fr, fl, v,
                 n_owned, acc, out):
    """Corner-mass/momentum remap of the nodal velocity; accumulates (P_r, P_z, M) per node.

    ``out`` += (outflow mass, outflow momentum r, z, outflow kinetic energy)."""
    m = np.empty(4)  # corner masses in cycle order
    mt = np.empty(4)  # targets
    phi = np.empty(4)
    sw = np.empty(4)
    for c in range(n_owned):
        a0, a1, a2, a3 = cn_tensor[c, 0], cn_tensor[c, 1], cn_tensor[c, 2], cn_tensor[c, 3]
        I0 = corner_integrals(x0, a0, a1, a2, a3)
        I1 = corner_integrals(x1, a0, a1, a2, a3)
        # cycle order 0-1-3-2 of the tensor nodes
        m[0], m[1], m[2], m[3] = rho_old[c] * I0[0], rho_old[c] * I0[1], rho_old[c] * I0[3], rho_old[c] * I0[2]
        mt[0], mt[1], mt[2], mt[3] = rho_new[c] * I1[0], rho_new[c] * I1[1], rho_new[c] * I1[3], rho_new[c] * I1[2]
        # edge fluxes: into this cell (+) are credited half to each end corner
        for k in range(4):
            f = cell_facets[c, k]
            if f < 0:
                continue
            inflow = cell_side[c, k] * fmass[f]
            if inflow == 0.0:
                continue
            far = fr[f] if cell_side[c, k] < 0.0 else fl[f]
            for kk in (k, (k + 1) % 4):
                node = cn[c, kk]
                m[kk] += 0.5 * inflow
                if far == OUTSIDE and inflow < 0.0:
                    out[0] -= 0.5 * inflow
                    out[1] -= 0.5 * inflow * v[node, 0]
                    out[2] -= 0.5 * inflow * v[node, 1]
                    out[3] -= 0.25 * inflow * (v[node, 0] ** 2 + v[node, 1] ** 2)
        # intra-cell corner-to-corner fluxes phi[k]: corner k -> k+1, net into k = phi[k-1] - phi[k]
        phi[0] = 0.0
        for k in range(1, 4):
            phi[k] = phi[k - 1] - (mt[k] - m[k])
        # dual segments centre -> midpoint of edge (k, k+1): swept volume moves k+1 -> k (CCW)
        gr0 = 0.0
        gz0 = 0.0
        gr1 = 0.0
        gz1 = 0.0
        for k in range(4):
            gr0 += 0.25 * x0[cn[c, k], 0]
            gz0 += 0.25 * x0[cn[c, k], 1]
            gr1 += 0.25 * x1[cn[c, k], 0]
            gz1 += 0.25 * x1[cn[c, k], 1]
        kappa = 0.0
        for k in range(4):
            a, b = cn[c, k], cn[c, (k + 1) % 4]
            m0, _, _ = _moments(gr0, gz0, 0.5 * (x0[a, 0] + x0[b, 0]), 0.5 * (x0[a, 1] + x0[b, 1]),
                                0.5 * (x1[a, 0] + x1[b, 0]), 0.5 * (x1[a, 1] + x1[b, 1]), gr1, gz1)
            sw[k] = -orient[c] * rho_old[c] * TWO_PI * m0
            kappa += 0.25 * (sw[k] - phi[k])
        for k in range(4):
            phi[k] += kappa
        # momentum: own corner mass with own velocity, then the intra-cell transfers (upwind)
        for k in range(4):
            node = cn[c, k]
            acc[node, 0] += m[k] * v[node, 0]
            acc[node, 1] += m[k] * v[node, 1]
            acc[node, 2] += mt[k]
        for k in range(4):
            a, b = cn[c, k], cn[c, (k + 1) % 4]
            f = phi[k]
            up = a if f > 0.0 else b
            acc[b, 0] += f * v[up, 0]
            acc[b, 1] += f * v[up, 1]
            acc[a, 0] -= f * v[up, 0]
            acc[a, 1] -= f * v[up, 1]


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


