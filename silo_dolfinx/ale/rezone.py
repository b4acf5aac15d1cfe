"""Conservative transfer of the state from one mesh to another of the same material (rezoning).

The remap (:mod:`.remap`) moves the state between two positions of *one* mesh: every edge
sweeps a region, and the state crosses it. A new mesh - other cells, other nodes - has no
edges in common with the old one, so the state moves by **overlaps** instead: each new cell
takes from every old cell it overlaps the share of that old cell's totals that the common
region holds, by volume of revolution 2π ∫ r dA (the cells are convex quadrilaterals, so the
common region is one convex polygon: Sutherland–Hodgman clipping, exact for straight edges).

**Cells.** An old cell o gives each new cell n the fraction w_no / W_o of its mass m_o and of
every mass-weighted total m_o Q_o, where w_no is their common volume and W_o = Σ_n w_no the
part of o that the new mesh covers. So mass and every ∫ ρ Q dV are conserved to round-off even
where the two domains differ by slivers along a curved or re-sampled boundary (an old cell's
uncovered sliver goes to the new cells it does overlap), and each new Q is a mass-weighted
mean of old ones (no new extremum). The new density is the new mass over the new cell's exact
volume. An old cell that no new cell overlaps at all loses its mass: the transfer reports it
(:attr:`Transfer.uncovered_mass`), and the caller decides whether that is acceptable.

**Nodes.** A node's velocity comes from the material around it: each cell is cut into four
corner regions (node, the two edge midpoints beside it, the mean of the four nodes - convex for
a convex cell, by Varignon's parallelogram), an old corner region carries its node's velocity
with its cell's density, and a new node's velocity is the mass-weighted mean over the old
corner regions that its own corner regions overlap: v'_a = Σ ρ_o w v_o / Σ ρ_o w. A uniform
velocity is reproduced exactly and every new velocity lies in the range of the old ones; the
momentum is conserved to the difference between the corner regions' masses and the new lumped
masses (first order, like the rest of a rezone), which the caller books with the energy.

**In parallel** the old state is gathered on every rank (:func:`gather`: one allgather of the
owned cells' corners, densities, means and corner velocities - a rezone is rare and the old
mesh small beside the run), each rank computes the overlaps of its own new cells, the covered
volumes W_o are summed over ranks, and the node sums are added across ranks through the node
index map. The search is a uniform grid of the old cells' bounding boxes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from silo_dolfinx._jit_cache import numba
from silo_dolfinx._mpi import reduce_scalar

TWO_PI = 2.0 * math.pi
MAX_VERTS = 16  # a convex quadrilateral clipped by another has at most 8 vertices


# ---------------------------------------------------------------------------- polygons
@numba.njit(cache=True)
def _clip_r_moment(px, py, qx, qy, a, b) -> float:
    """∫ r dA over the intersection of the convex quadrilaterals p and q (counter-clockwise,
    4 vertices each; r is the first coordinate). ``a``, ``b``: (MAX_VERTS, 2) work arrays."""
    n = 4
    for i in range(4):
        a[i, 0] = px[i]
        a[i, 1] = py[i]
    for e in range(4):
        ex0, ey0 = qx[e], qy[e]
        dx, dy = qx[(e + 1) % 4] - ex0, qy[(e + 1) % 4] - ey0
        m = 0
        sx, sy = a[n - 1, 0], a[n - 1, 1]
        ss = dx * (sy - ey0) - dy * (sx - ex0)  # ≥ 0: left of the edge, inside
        for i in range(n):
            cx, cy = a[i, 0], a[i, 1]
            sc = dx * (cy - ey0) - dy * (cx - ex0)
            if (sc >= 0.0) != (ss >= 0.0):  # the edge of p crosses the clipping line
                t = ss / (ss - sc)
                b[m, 0] = sx + t * (cx - sx)
                b[m, 1] = sy + t * (cy - sy)
                m += 1
            if sc >= 0.0:
                b[m, 0] = cx
                b[m, 1] = cy
                m += 1
            sx, sy, ss = cx, cy, sc
        if m < 3:
            return 0.0
        for i in range(m):
            a[i, 0] = b[i, 0]
            a[i, 1] = b[i, 1]
        n = m
    s = 0.0
    for i in range(n):
        x0, y0 = a[i, 0], a[i, 1]
        x1, y1 = a[(i + 1) % n, 0], a[(i + 1) % n, 1]
        s += (x0 * y1 - x1 * y0) * (x0 + x1)
    return max(s / 6.0, 0.0)


@numba.njit(cache=True)
def _r_moment(px, py) -> float:
    s = 0.0
    for i in range(4):
        x0, y0, x1, y1 = px[i], py[i], px[(i + 1) % 4], py[(i + 1) % 4]
        s += (x0 * y1 - x1 * y0) * (x0 + x1)
    return s / 6.0


@numba.njit(cache=True)
def _corner_region(cx, cy, k, out_x, out_y):
    """Corner region k of the quadrilateral (cx, cy) (counter-clockwise): node k, the midpoint
    of edge k→k+1, the mean of the four nodes, the midpoint of edge k-1→k (counter-clockwise)."""
    mx = 0.25 * (cx[0] + cx[1] + cx[2] + cx[3])
    my = 0.25 * (cy[0] + cy[1] + cy[2] + cy[3])
    kn, kp = (k + 1) % 4, (k + 3) % 4
    out_x[0] = cx[k]
    out_y[0] = cy[k]
    out_x[1] = 0.5 * (cx[k] + cx[kn])
    out_y[1] = 0.5 * (cy[k] + cy[kn])
    out_x[2] = mx
    out_y[2] = my
    out_x[3] = 0.5 * (cx[k] + cx[kp])
    out_y[3] = 0.5 * (cy[k] + cy[kp])


def counter_clockwise(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(n, 4, 2) corners in boundary-cycle order → (corners reordered counter-clockwise, the
    permutation of the four corners applied to each cell (n, 4))."""
    c = np.ascontiguousarray(corners, dtype=float)
    x, y = c[:, :, 0], c[:, :, 1]
    area2 = np.sum(x * np.roll(y, -1, 1) - np.roll(x, -1, 1) * y, axis=1)
    perm = np.tile(np.arange(4), (c.shape[0], 1))
    perm[area2 < 0] = perm[area2 < 0][:, ::-1]
    return np.ascontiguousarray(np.take_along_axis(c, perm[:, :, None], axis=1)), perm


# ---------------------------------------------------------------------------- the search
@numba.njit(cache=True)
def _bin_range(xs, ys, origin, h, nx, ny):
    """The grid bins (i0, i1, j0, j1), clamped to the grid, that a bounding box touches."""
    return (max(int((xs.min() - origin[0]) / h), 0), min(int((xs.max() - origin[0]) / h), nx - 1),
            max(int((ys.min() - origin[1]) / h), 0), min(int((ys.max() - origin[1]) / h), ny - 1))


@numba.njit(cache=True)
def _bins(corners, origin, h, nx, ny):
    """CSR lists of the cells whose bounding box touches each grid bin."""
    n = corners.shape[0]
    offsets = np.zeros(nx * ny + 1, np.int64)
    for c in range(n):
        i0, i1, j0, j1 = _bin_range(corners[c, :, 0], corners[c, :, 1], origin, h, nx, ny)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                offsets[i * ny + j + 1] += 1
    for i in range(nx * ny):
        offsets[i + 1] += offsets[i]
    items = np.empty(offsets[nx * ny], np.int64)
    fill = offsets[:-1].copy()
    for c in range(n):
        i0, i1, j0, j1 = _bin_range(corners[c, :, 0], corners[c, :, 1], origin, h, nx, ny)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                items[fill[i * ny + j]] = c
                fill[i * ny + j] += 1
    return offsets, items


@numba.njit(cache=True)
def _overlaps(old, new, grid, stamp):
    """Every (new cell, old cell) pair with a common region: its ∫ r dA, and the ∫ r dA of the
    common regions of their corner regions (new corner i, old corner j)."""
    origin, h, nx, ny, offsets, items = grid
    nn = new.shape[0]
    cap = 16 * nn + 16
    pn = np.empty(cap, np.int64)
    po = np.empty(cap, np.int64)
    w = np.empty(cap)
    wsub = np.empty((cap, 4, 4))
    a = np.empty((16, 2))
    b = np.empty((16, 2))
    sx_new = np.empty((4, 4))
    sy_new = np.empty((4, 4))
    sx_old = np.empty(4)
    sy_old = np.empty(4)
    npair = 0
    for c in range(nn):
        cx, cy = new[c, :, 0], new[c, :, 1]
        for k in range(4):
            _corner_region(cx, cy, k, sx_new[k], sy_new[k])
        i0, i1, j0, j1 = _bin_range(cx, cy, origin, h, nx, ny)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                for t in range(offsets[i * ny + j], offsets[i * ny + j + 1]):
                    o = items[t]
                    if stamp[o] == c:
                        continue
                    stamp[o] = c
                    ox, oy = old[o, :, 0], old[o, :, 1]
                    if ox.max() <= cx.min() or ox.min() >= cx.max() or oy.max() <= cy.min() or oy.min() >= cy.max():
                        continue
                    v = _clip_r_moment(cx, cy, ox, oy, a, b)
                    if v <= 0.0:
                        continue
                    if npair == cap:
                        cap *= 2
                        pn2, po2, w2, ws2 = (np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty(cap),
                                             np.empty((cap, 4, 4)))
                        pn2[:npair], po2[:npair], w2[:npair], ws2[:npair] = pn, po, w, wsub
                        pn, po, w, wsub = pn2, po2, w2, ws2
                    pn[npair], po[npair], w[npair] = c, o, v
                    for jj in range(4):
                        _corner_region(ox, oy, jj, sx_old, sy_old)
                        for ii in range(4):
                            wsub[npair, ii, jj] = _clip_r_moment(sx_new[ii], sy_new[ii], sx_old, sy_old, a, b)
                    npair += 1
    return pn[:npair], po[:npair], w[:npair], wsub[:npair]


# ---------------------------------------------------------------------------- the old state
@dataclass
class OldState:
    """The old mesh's state, the same on every rank: per cell its corners (counter-clockwise,
    (N, 4, 2)), density (N,), mass-weighted means of the transferred intensive variables
    (N, k) and its corners' node velocities (N, 4, 2), in the corners' order."""

    corners: np.ndarray
    rho: np.ndarray
    means: np.ndarray
    corner_velocity: np.ndarray

    @property
    def volumes(self) -> np.ndarray:
        """Exact volumes of revolution 2π ∫ r dA of the old cells."""
        c = self.corners
        return np.array([TWO_PI * _r_moment(c[i, :, 0], c[i, :, 1]) for i in range(c.shape[0])])


def gather(comm, corners: np.ndarray, rho: np.ndarray, means: np.ndarray, corner_velocity: np.ndarray) -> OldState:
    """The old state on every rank from each rank's owned cells: ``corners`` (n, 4, 2) in
    boundary-cycle order (either orientation), ``rho`` (n,), ``means`` (n, k),
    ``corner_velocity`` (n, 4, 2) the velocity of each corner's node."""
    ccw, perm = counter_clockwise(corners)
    cv = np.take_along_axis(np.asarray(corner_velocity, float), perm[:, :, None], axis=1)
    means = np.asarray(means, float).reshape(len(rho), -1)
    parts = comm.allgather((ccw, np.asarray(rho, float), means, cv))
    return OldState(*(np.ascontiguousarray(np.concatenate([p[i] for p in parts])) for i in range(4)))


# ---------------------------------------------------------------------------- the transfer
class Transfer:
    """The overlaps of this rank's new cells with the old cells (collective: every rank of
    ``comm`` constructs it), and the state carried over them.

    ``new_corners`` (n, 4, 2): this rank's new cells in boundary-cycle order (owned cells;
    each is counted once over the ranks)."""

    def __init__(self, comm, old: OldState, new_corners: np.ndarray):
        self.comm = comm
        self.old = old
        self.new, self._perm = counter_clockwise(new_corners)
        lo = old.corners.reshape(-1, 2).min(axis=0)
        hi = old.corners.reshape(-1, 2).max(axis=0)
        n_old = old.corners.shape[0]
        span = np.maximum(hi - lo, 1e-300)
        h = math.sqrt(span[0] * span[1] / max(n_old, 1))  # about one old cell per bin
        nx, ny = int(span[0] / h) + 1, int(span[1] / h) + 1
        offsets, items = _bins(old.corners, lo, h, nx, ny)
        grid = (lo, h, nx, ny, offsets, items)
        stamp = np.full(n_old, -1, np.int64)
        self.pair_new, self.pair_old, w, wsub = _overlaps(old.corners, self.new, grid, stamp)
        self.w, self.wsub = TWO_PI * w, TWO_PI * wsub  # volumes of revolution
        local = np.bincount(self.pair_old, weights=self.w, minlength=n_old)
        self.covered = np.empty_like(local)
        comm.Allreduce(local, self.covered, op=MPI.SUM)  # W_o over every rank's new cells
        self.new_volumes = np.array([TWO_PI * _r_moment(c[:, 0], c[:, 1]) for c in self.new])
        self.old_volumes = old.volumes

    # ------------------------------------------------------------------ cells
    @property
    def gap_volume(self) -> float:
        """Volume of the new cells that no old cell covers (global, m³): where the old material
        had come away from the wall, or the new surface passes above the old; the mass around
        it spreads into it."""
        covered = np.bincount(self.pair_new, weights=self.w, minlength=self.new.shape[0])
        return self.comm.allreduce(float(np.sum(np.maximum(self.new_volumes - covered, 0.0))))

    @property
    def uncovered_mass(self) -> float:
        """Mass of the old cells no new cell overlaps (lost by the transfer; global)."""
        o = self.old
        return float(np.sum(o.rho * self.old_volumes * (self.covered <= 0.0)))

    def cells(self) -> tuple[np.ndarray, np.ndarray]:
        """(density (n,), mass-weighted means (n, k)) of this rank's new cells."""
        o = self.old
        share = self.w / np.where(self.covered > 0.0, self.covered, 1.0)[self.pair_old]  # w_no / W_o
        mass_o = o.rho * self.old_volumes
        dm = mass_o[self.pair_old] * share
        n = self.new.shape[0]
        mass = np.bincount(self.pair_new, weights=dm, minlength=n)
        k = o.means.shape[1]
        means = np.zeros((n, k))
        for j in range(k):
            means[:, j] = np.bincount(self.pair_new, weights=dm * o.means[self.pair_old, j], minlength=n)
        means /= np.where(mass > 0.0, mass, 1.0)[:, None]
        empty = self.comm.allreduce(int(np.sum(mass <= 0.0)))  # (raised on every rank alike)
        if empty:
            raise ValueError(f"{empty} new cell(s) overlap no old cell: the new mesh covers ground the material does not")
        return mass / self.new_volumes, means

    # ------------------------------------------------------------------ nodes
    def corner_velocities(self) -> tuple[np.ndarray, np.ndarray]:
        """(mass (n, 4), momentum (n, 4, 2)) that each corner region of this rank's new cells
        takes from the old corner regions it overlaps, in boundary-cycle order of the new
        cells (sum them per node over every rank; the velocity is their ratio)."""
        o = self.old
        rho = o.rho[self.pair_old]
        dm = self.wsub * rho[:, None, None]  # (P, 4 new, 4 old)
        n = self.new.shape[0]
        mass = np.zeros((n, 4))
        mom = np.zeros((n, 4, 2))
        for i in range(4):
            mass[:, i] = np.bincount(self.pair_new, weights=dm[:, i, :].sum(axis=1), minlength=n)
            for d in range(2):
                p = np.einsum("pj,pj->p", dm[:, i, :], o.corner_velocity[self.pair_old, :, d])
                mom[:, i, d] = np.bincount(self.pair_new, weights=p, minlength=n)
        inv = np.argsort(self._perm, axis=1)  # back to the caller's corner order
        return np.take_along_axis(mass, inv, axis=1), np.take_along_axis(mom, inv[:, :, None], axis=1)


def node_velocities(index_map, cell_nodes: np.ndarray, corner_mass: np.ndarray,
                    corner_momentum: np.ndarray) -> np.ndarray:
    """Velocities (n_local, 2) of the local nodes (owned and ghost) of ``index_map`` from the
    corner sums of :meth:`Transfer.corner_velocities`: ``cell_nodes`` (n, 4) the new cells'
    nodes in boundary-cycle order. The sums are added across ranks (collective).

    A node whose corner regions overlap no old material - a wall corner in the gap the
    material had opened from the wall, a spline top a millimetre above the old polyline -
    takes the mass-weighted velocity of its cells instead (every new cell overlaps some: see
    :meth:`Transfer.cells`); only a node with no material in any of its cells is an error."""
    from dolfinx import la

    vec = la.vector(index_map, 6)
    acc = vec.array.reshape(-1, 6)
    acc[:] = 0.0
    nodes = np.asarray(cell_nodes).ravel()
    cell_mass = np.repeat(corner_mass.sum(axis=1), 4)
    cell_momentum = np.repeat(corner_momentum.sum(axis=1), 4, axis=0)
    for k, w in enumerate((corner_mass.ravel(), corner_momentum[:, :, 0].ravel(), corner_momentum[:, :, 1].ravel(),
                           cell_mass, cell_momentum[:, 0], cell_momentum[:, 1])):
        np.add.at(acc[:, k], nodes, w)
    vec.scatter_reverse(la.InsertMode.add)
    vec.scatter_forward()
    own = acc[:, 0] > 0.0
    m = np.where(own, acc[:, 0], acc[:, 3])
    empty = index_map.comm.allreduce(int(np.sum(m <= 0.0)))  # (raised on every rank alike)
    if empty:
        raise ValueError(f"{empty} new node(s) have no old material in any of their cells")
    return np.where(own[:, None], acc[:, 1:3], acc[:, 4:6]) / m[:, None]


# ---------------------------------------------------------------------------- the rezone of a discharge
class Rezoner:
    """Re-meshes a discharge when its mesh has fallen behind the material: once the stable Δt
    has fallen by ``ale.rezone_dt_fall`` below its value after the opening (or the last rezone)
    and the cell that sets it is shorter by as much than the shortest cell then - or once the
    worst cell's scaled Jacobian (the discharge monitor's last sample) has fallen below
    ``ale.rezone_min_quality`` - right after a remap (the outlet's nodes are then on the outlet plane and the surface on
    the material), the material domain - axis, outlet, wall up to the top corner, the free
    surface through its nodes - is meshed again by the scene's mesher at the scene's element
    size (unstructured, relocated), the model moves to it (:meth:`SiloModel.move_to`), the
    state comes over by :class:`Transfer`, ALE starts again on the new mesh with the old one's
    tracers and counters, and the outputs go on (VTX fields in new files, ``_rezone<k>``).
    What the transfer changes in kinetic and elastic energy is booked with the remap's.

    The rows a draining fill squeezes under its falling surface are where Δt falls (the ch. 4
    hopper: docs/performance.md); a fresh mesh of the smaller domain has the scene's cells
    again, and fewer of them. Checkpoints stop at the first rezone (the one before it resumes
    the run, which then rezones again where it did)."""

    CHECKPOINT = ("dt_ref", "length_ref", "fresh_quality")  # (a checkpoint comes before the first rezone: see above)

    def __init__(self, model):
        self.model = model
        self.fall = model.scene.ale.rezone_dt_fall
        self.min_quality = model.scene.ale.rezone_min_quality
        self.dt_ref = self.length_ref = None  # the stable Δt and smallest cell length after the opening or the last rezone
        self.fresh_quality = np.inf  # the worst cell of the last fresh mesh (a nearly empty silo's: below the trigger)
        self.records: list[dict] = []

    @staticmethod
    def wanted(scene) -> bool:
        a = scene.ale
        return a.enabled and scene.discharge.mode != "none" and (a.rezone_dt_fall > 0.0 or a.rezone_min_quality > 0.0)

    def due(self) -> bool:
        """After a step: whether to rezone now (the same answer on every rank: Δt is global)."""
        ale = self.model.ale
        if ale is None or not ale.due():
            return False
        s = self.model.solver
        if self.dt_ref is None:
            self._reference()
        monitor = self.model.outputs.monitor if self.model.outputs is not None else None
        if monitor is not None and monitor.min_quality < self.min_quality <= self.fresh_quality:
            return True  # (the last sample's worst cell, global; not again if a fresh mesh is no better)
        if self.fall <= 0.0 or s.dt_crit >= (1.0 - self.fall) * self.dt_ref:
            return False
        # a cell dilated at the outlet sets a smaller Δt that no mesh cures: only a cell shrunk as
        # much as Δt fell is the mesh's doing (its length, not its density)
        return s.limiting_cell(refresh=False)["length"] < (1.0 - self.fall) * self.length_ref

    def _reference(self) -> None:
        """Δt and the smallest cell length now: what the next rezone waits for them to fall from."""
        s = self.model.solver
        self.dt_ref = s.dt_crit
        self.length_ref = reduce_scalar(s.comm, float(s.q.cells.L.min(initial=np.inf)), MPI.MIN)

    def rezone(self) -> dict:
        """Mesh the material again and carry the state over (collective); returns its record."""
        import time

        from silo_dolfinx.ale import ALE
        from silo_dolfinx.geometry.cells import cell_corners

        started = time.perf_counter()
        model, s, ale = self.model, self.model.solver, self.model.ale
        comm = s.comm
        old = self._old_state()
        before = s.mechanical_energy_local()
        record = {"t": s.t, "step": s.steps, "cells_before": model.sm.num_cells_global(), "dt_before": s.dt_crit,
                  "kinetic_before": comm.allreduce(s.kinetic_energy_local()),
                  "mass_before": float(np.sum(old.rho * old.volumes))}

        sm = remesh(model.scene, ale.smoother.surface(s.x), comm)
        model.move_to(sm)
        tr = Transfer(comm, old, cell_corners(sm.mesh))
        elastic = self._carry(tr)
        model.after_remap()  # gravity (and surcharge) on the new mass
        after = s.kinetic_energy_local() + elastic
        s.energy.remap += before - after  # booked as the remap's upwinding is

        new_ale = ALE(model, model.scene.ale)
        carried = new_ale.take_over(ale)
        model.hooks[model.hooks.index(ale)] = new_ale
        model.ale = model.effects["ale"].ale = new_ale
        if model.outputs is not None:
            model.outputs.after_rezone(model, carried, len(self.records) + 1)
        self._reference()
        if model.outputs is not None and model.outputs.monitor is not None:
            self.fresh_quality = model.outputs.monitor.min_quality  # (refreshed on the new mesh)
        record.update(cells_after=sm.num_cells_global(), dt_after=s.dt_crit,
                      mass_after=comm.allreduce(float(np.dot(s.rho, s.dV))),
                      uncovered_mass=tr.uncovered_mass, gap_volume=tr.gap_volume,
                      kinetic_after=comm.allreduce(s.kinetic_energy_local()), energy_removed=comm.allreduce(before - after),
                      tracer_shift=max([t.carry_shift for t in (new_ale.tracers, *new_ale.followers) if t is not None],
                                       default=0.0),
                      seconds=round(comm.allreduce(time.perf_counter() - started, op=MPI.MAX), 3))
        self.records.append(record)
        return record

    def _old_state(self) -> OldState:
        """The solver's state as cells (density of the exact volume, mass-weighted means of the
        stress and the law's state) and corner velocities, gathered on every rank."""
        from silo_dolfinx.ale.remap import cell_state, cell_volume_density
        from silo_dolfinx.geometry.cells import cell_corners

        s, ale = self.model.solver, self.model.ale
        nq, no = s.nq, s.n_cells_owned
        vol, rho = np.zeros(no), np.zeros(no)
        cell_volume_density(s.rho, nq, s.dV, vol, rho)
        means, lo, hi = (np.zeros((no, ale.k)) for _ in range(3))
        for j0, a in ale._field_arrays():
            cell_state(a, nq, s.dV, vol, j0, means, lo, hi)
        corners = cell_corners(self.model.sm.mesh)
        return gather(s.comm, corners, rho, means, s.v[s.node_dof[s.cell_nodes[:no]]])

    def _carry(self, tr: Transfer) -> float:
        """The transferred state into the solver on its new mesh, and its rebuild; returns this
        rank's elastic energy (as :meth:`ExplicitSolver.after_remap`)."""
        from silo_dolfinx.geometry.cells import cycle_nodes, qp_volumes

        s, mesh = self.model.solver, self.model.sm.mesh
        nq, no = s.nq, s.n_cells_owned
        rho, means = tr.cells()
        dV = np.zeros(no * nq)
        qp_volumes(np.ascontiguousarray(s.x[:, :2]), s.cell_tensor[:no], s.forms.points, s.forms.weights, no, dV)
        s.rho.reshape(-1, nq)[:] = rho[:, None]  # the quadrature volumes are exact: Σ dV = tr.new_volumes
        j0 = 0
        for name, c in [("sig", 4)] + list(s.point_fields.items()):
            a = (s.sig if name == "sig" else s.state[name]).reshape(no, nq, c)
            a[:] = 0.0 if name == "hourglass" else means[:, None, j0:j0 + c]  # a stored force is the old mesh's
            j0 += c
        s.v[s.node_dof] = node_velocities(mesh.geometry.index_map(), cycle_nodes(mesh, no), *tr.corner_velocities())
        return s.after_remap(dV, None)[1]


def remesh(scene, surface: np.ndarray, comm):
    """A mesh of the scene's silo holding material up to ``surface`` (points from the axis to
    the wall), at the scene's element size: the surface is resampled at that size (the mesher
    puts a spline through the points) and meshed unstructured without layers (collective)."""
    from dataclasses import replace

    from silo_dolfinx.geometry.mesher import MeshOptions, create_mesh

    opts = replace(MeshOptions.from_scene(scene), structured=False, layer_heights=())
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(surface, axis=0), axis=1))])
    m = max(2, int(round(arc[-1] / opts.element_size)))
    at = np.linspace(0.0, arc[-1], m + 1)
    pts = np.column_stack([np.interp(at, arc, surface[:, 0]), np.interp(at, arc, surface[:, 1])])
    return create_mesh(scene.outline.with_surface(pts), opts, comm)
