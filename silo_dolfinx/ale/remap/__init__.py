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

Outflow edges (an Eulerian outlet) let material out, never in, with the donor cell's mass flux
(a high-order one, extrapolating an emptied outlet cell's gradient, could point inwards, and
nothing outside would bound it); other boundary edges carry nothing (a wall or free-surface node that moves along its boundary changes its cell's
volume, and the cell keeps its mass).

The closed edges at an outflow's ends (the wall edge beside the outlet's edge node) are outflow
edges too. The outlet's edge node moves with the material in the Lagrangian steps and is put
back by the smoothing, so the wall edge it shares is dragged off its wall and back: where the
material flows past the outlet's edge, the edge swings out of the silo, and what it swept out
has crossed the outlet plane - it leaves. Kept in its cell instead (the edge carrying nothing),
it was a mass pump: the cell beside a flat bottom's outlet, sheared as the flow runs down its
side, lost the material under its dragged floor edge to nothing while its top edge, swept back,
brought the same volume in from above - its mass grew each remap at a constant volume (ch. 6,
h 0.02 m: 1,210 to 6,400 kg/m³ in 0.17 s, ~1 % per remap; at the thesis' mesh 28,000 kg/m³, and
the mass leaving through it doubled the flow rate). Swung inwards the edge leaves a gap between
the material and the wall, which carries nothing, as before.

The stages, each in its module and chosen once at set-up (order 1: low order only):

* :mod:`.geometry` — moments, swept regions, edge sides, Courant numbers, corner integrals;
* :mod:`.lo` — donor-cell fluxes (and the local bounds);
* :mod:`.ho` — least-squares gradients, high-order corrections A = HO − LO;
* :mod:`.fct` — Zalesak's sums, limiters, and the limited corrections;
* :mod:`.nodal` — the corner-mass remap of the velocity;
* :mod:`.quadrature` — cell means and bounds of the quadrature data, and back.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from silo_dolfinx._mpi import reduce_scalar
from silo_dolfinx.ale.remap import fct, ho, lo
from silo_dolfinx.ale.remap.geometry import (CLOSED, OUTSIDE, cell_facets, cell_geometry, corner_integrals,
                                             courant, lumped, sides, swept)
from silo_dolfinx.ale.remap.nodal import nodal_remap, velocity
from silo_dolfinx.ale.remap.quadrature import cell_state, cell_volume_density, redistribute
from silo_dolfinx.geometry.cells import CYCLE, orientation, tensor_nodes

COURANT = 0.5  # largest fraction of a cell's volume that one sub-step may move out of it
MAX_SUBSTEPS = 64  # a motion that needs more sub-steps is refused (SweptTooFar), never sub-cycled for ever


class RemapError(RuntimeError):
    """The remap cannot carry the state to the smoothed mesh (raised on every rank alike)."""


class SweptTooFar(RemapError):
    """The mesh motion sweeps a cell's volume MAX_SUBSTEPS × COURANT times over in one remap."""

__all__ = ["CLOSED", "COURANT", "MAX_SUBSTEPS", "OUTSIDE", "RemapError", "RemapReport", "Remapper", "SweptTooFar", "cell_state", "cell_volume_density",
           "corner_integrals", "redistribute"]


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
        self.high_order = order >= 2  # the HO + FCT stages, or LO alone (chosen once)
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
        # the closed boundary edges at the outflow's ends are outflow edges too (module docstring)
        ends = self._outflow_nodes(mesh, outflow_facets)[self.fnodes].any(axis=1) & (count[facets] == 1)
        c0, c1 = first[facets].astype(np.int64), second[facets].astype(np.int64)
        far = np.where(outflow[facets] | ends, OUTSIDE, CLOSED)
        c1 = np.where(c1 < 0, far, c1)
        self.fleft, self.fright = sides(self.cn, self.orient, self.fnodes, c0, c1)
        self.facets = facets
        nf = facets.size
        self.cell_facets, self.cell_side = cell_facets(self.cn, self.fnodes, self.fleft, self.fright, self.n_owned)
        # each owned cell's neighbour across each cycle edge (CLOSED / OUTSIDE across the
        # boundary), and the same with the cell itself there (for the gathers: the bounds)
        own = np.arange(self.n_owned)[:, None]
        cf = np.maximum(self.cell_facets, 0)
        other = np.where(self.fleft[cf] == own, self.fright[cf], self.fleft[cf])
        self.neighbours = np.where(self.cell_facets >= 0, other, CLOSED)
        self.nbr = np.ascontiguousarray(np.where(self.neighbours >= 0, self.neighbours, own))

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

    @staticmethod
    def _outflow_nodes(mesh, outflow_facets) -> np.ndarray:
        """Whether each local geometry node lies on an outflow facet of any rank (a node at
        a partition boundary may border an outflow facet this rank does not hold)."""
        from dolfinx import la
        from dolfinx import mesh as dmesh

        flags = la.vector(mesh.geometry.index_map(), 1)
        flags.array[:] = 0.0
        if outflow_facets is not None and len(outflow_facets):
            nodes = dmesh.entities_to_geometry(mesh, mesh.topology.dim - 1, np.asarray(outflow_facets, np.int32))
            flags.array[nodes.ravel()] = 1.0
        flags.scatter_reverse(la.InsertMode.add)
        flags.scatter_forward()
        return flags.array > 0.0

    # ------------------------------------------------------------------ ghost exchange
    def _ghosted(self, *shape: int, fill: float = 0.0) -> tuple[np.ndarray, object]:
        """A (n_all, *shape) cell array living in a DOLFINx vector on the cell index map, so
        that filling its ghost rows from their owners is one ``scatter_forward`` (no copies)."""
        from dolfinx import la

        vec = la.vector(self.cell_map, int(np.prod(shape)))
        vec.array[:] = fill
        return vec.array.reshape(self.n_all, *shape), vec

    # ------------------------------------------------------------------ queries
    def volumes(self, x: np.ndarray, out: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """Exact volumes of revolution of the local cells at node positions ``x`` (into
        ``out`` = (volumes (n_all,), centroids (n_all, 2)) if given: no allocation)."""
        vol, cen = out if out is not None else (np.zeros(self.n_all), np.zeros((self.n_all, 2)))
        cell_geometry(np.ascontiguousarray(x[:, :2]), self.cn, self.orient, vol, cen)
        return vol

    def nodal_mass(self, x: np.ndarray, rho: np.ndarray) -> np.ndarray:
        """Row-sum lumped mass Σ_c ρ_c ∫ N_a 2πr dA of the local nodes (owned exact, ghosts
        updated) at positions ``x`` for owned-cell densities ``rho``."""
        from dolfinx import la

        acc = self._nodal.array.reshape(-1, 3)
        acc[:] = 0.0
        lumped(np.ascontiguousarray(x[:, :2]), self.cn_tensor, np.asarray(rho, float), self.n_owned, acc)
        self._nodal.scatter_reverse(la.InsertMode.add)
        self._nodal.scatter_forward()
        return acc[:, 2].copy()

    @property
    def last_volumes(self) -> np.ndarray:
        """Exact volumes of the local cells at the end positions of the last remap."""
        return self._vol1

    def courant(self, x0: np.ndarray, x1: np.ndarray) -> float:
        """Largest fraction of a cell's volume swept out of it by the motion x0 -> x1 (global)."""
        self._load(x0, x1)
        cell_geometry(self._x0, self.cn, self.orient, self._vol0, self._cen0)
        swept(self._x0, self._x1, self.fnodes, self._swept, self._xf)
        c = courant(self.fleft, self.fright, self._swept, self._vol0, self.n_owned)
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
        if not c <= MAX_SUBSTEPS * COURANT:  # also NaN
            raise SweptTooFar(f"the smoothed mesh moved {c:.3g} cell volumes out of a cell in one remap (more than "
                              f"{MAX_SUBSTEPS} sub-steps at Courant {COURANT})")
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
                cell_geometry(self._x0, self.cn, self.orient, self._vol0, self._cen0)
                swept(self._x0, self._x1, self.fnodes, self._swept, self._xf)
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
            "ls": (np.zeros((no, 3)), np.zeros((no, 1 + k, 2))),  # the gradients' normal equations
            "E": np.zeros((no, 1 + k)), "mnew": np.zeros(no), "qmin": np.zeros((no, 1 + k)),
            "qmax": np.zeros((no, 1 + k)), "fmass": np.zeros(nf), "rho_old": np.zeros(no), "rho_new": np.zeros(no),
        }
        return w

    def _substep(self, w, v, k, bounds, out, out_cells):
        from dolfinx import la

        cell_geometry(self._x1, self.cn, self.orient, self._vol1, w["cen1"])
        R, grads, vec = w["R"], w["grads"], w["vec"]
        vec["R"].scatter_forward()
        no = self.n_owned
        faces = (self.fleft, self.fright, no)
        if self.high_order:
            ho.ls_gradients(R, self._cen0, faces, w["ls"], grads)
            vec["grads"].scatter_forward()
        low, A, E, qmin, qmax = w["low"], w["A"], w["E"], w["qmin"], w["qmax"]
        fmass, mnew, rho_old, rho_new = w["fmass"], w["mnew"], w["rho_old"], w["rho_new"]

        # stage 1: mass (the density transported by the volume fluxes); column 0
        lo.mass_fluxes(faces, self.nbr, R, self._swept, self._vol0, (E, low, qmin, qmax, rho_old))
        if self.high_order:
            ho.mass_corrections(faces, R, grads, self._cen0, self._swept, low, A)
            self._correct(w, faces, self._vol1, (0, 1))
        else:
            fmass[:] = low[:, 0]
        mnew[:] = E[:, 0]
        lo.outflow(faces, fmass, out_cells)
        if reduce_scalar(self.comm, float(mnew.min(initial=0.0)), MPI.MIN) < 0.0:  # every rank stops alike
            raise RemapError("the remap produced a negative cell mass (a cell swept out faster than its own volume)")
        lo.divide(mnew, self._vol1, rho_old, rho_new)

        # stage 2: intensive variables, mass-weighted, with the final mass fluxes; columns 1..k
        if k:
            lo.value_fluxes(faces, fmass, R, rho_old, self._vol0, E)
            if bounds is not None:
                np.minimum(bounds[0], qmin[:, 1:], out=bounds[0])
                np.maximum(bounds[1], qmax[:, 1:], out=bounds[1])
            if self.high_order:
                ho.value_corrections(faces, fmass, grads, self._cen0, self._xf, A)
                self._correct(w, faces, mnew, (1, 1 + k))
            lo.values_from_totals(E, mnew, R, no)

        # nodal velocity (needs the old and new densities of every owned cell)
        acc = self._nodal.array.reshape(-1, 3)
        acc[:] = 0.0
        o = np.zeros(4)
        nodal_remap((self._x0, self._x1), (self.cn_tensor, self.cn, self.orient, no), (rho_old, rho_new), fmass,
                    (self.cell_facets, self.cell_side, self.fright, self.fleft), v, (acc, o))
        self._nodal.scatter_reverse(la.InsertMode.add)
        vv = self._vnode.array.reshape(-1, 2)
        velocity(acc, v, self.n_nodes_owned, vv)
        self._vnode.scatter_forward()
        v[:] = vv
        out += o
        R[:no, 0] = rho_new

    def _correct(self, w, faces, mnew, cols):
        """Flux correction of columns cols = (j0, j1): Zalesak's sums and limiters, the
        limiters' ghost values, the limited corrections into the totals (and, for the mass,
        the final edge fluxes)."""
        fct.limiters((self.cell_facets, self.cell_side), w["A"], w["E"], mnew, (w["qmin"], w["qmax"]), cols,
                     self.n_owned, w["Rpm"])
        w["vec"]["Rpm"].scatter_forward()
        fct.apply(faces, w["A"], w["Rpm"], cols, w["E"], w["low"], w["fmass"])
