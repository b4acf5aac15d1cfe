"""Tracers: material points carried through an ALE discharge (the thesis' Fig. 6-7).

With ALE the mesh no longer shows where the material went; tracers do. Each tracer lives
in an owned cell at reference coordinates (ξ, η). Between remaps the mesh moves with the
material, so a tracer keeps its (cell, ξ, η) and its position is the cell's map of them.
At a remap its physical position on the Lagrangian mesh is located on the smoothed mesh by
walking from its cell across the edge it lies beyond (inverse bilinear map by Newton), a
few cells at most since a remap moves nodes by less than a cell. A tracer that walks into
a ghost cell moves to the rank owning it; one that crosses the outlet is discharged (its
time recorded); one pushed against a wall stays on the wall.

Seeded at the start of the discharge as ``rows`` horizontal lines of ``per_row`` points,
the classic coloured-layer picture of flow patterns; or at given points (``points``: the
material-following interior points of ``output.points``, row −1).
"""

from __future__ import annotations


import numpy as np
from mpi4py import MPI

from silo_dolfinx._jit_cache import numba
from silo_dolfinx._mpi import reduce_scalar
from silo_dolfinx.ale.remap import OUTSIDE

FOUND, GHOST, DISCHARGED = 0, 1, 2


class Tracers:
    """Material points on the owned cells of this rank."""

    CHECKPOINT = ("cell", "xi", "id", "row", "initial", "t_out", "out_pos", "_gone", "count")

    def __init__(self, ale, rows: int, per_row: int, points: np.ndarray | None = None):
        model = ale.model
        mesh = ale.mesh
        self.comm = mesh.comm
        rm = ale.remapper
        self.cn_tensor = rm.cn_tensor
        self.n_owned = rm.n_owned
        # neighbour across each tensor side: 0 ξ=0, 1 ξ=1, 2 η=0, 3 η=1 (cycle edges 3, 1, 0, 2)
        self.nbr = np.ascontiguousarray(rm.neighbours[:, [3, 1, 0, 2]], dtype=np.int64)
        cmap = mesh.topology.index_map(mesh.topology.dim)
        self.ghost_global = cmap.ghosts
        self.ghost_owner = cmap.owners
        self.offset = cmap.local_range[0]
        self.offsets = np.array(self.comm.allgather(self.offset))
        # seed: rows of points between the axis and the wall, inside the current material
        outline = model.outline
        x = np.ascontiguousarray(mesh.geometry.x[:, :2])
        pts, ids, rowid = [], [], []
        H = outline.fill_height
        for i in range(rows):
            z = H * (i + 0.5) / rows
            rw = float(outline.wall.radius_at(z)[0])
            for j in range(per_row):
                pts.append(((j + 0.5) / per_row * rw, z))
                ids.append(i * per_row + j)
                rowid.append(i)
        if points is not None:
            pts, ids, rowid = list(points), list(range(len(points))), [-1] * len(points)
        pts = np.array(pts, float).reshape(-1, 2)
        cell, xi = _locate_brute(x, self.cn_tensor, self.n_owned, pts)
        # a point on a partition boundary is found by both ranks: the lower rank keeps it
        found = cell >= 0
        owner = np.where(found, self.comm.rank, self.comm.size).astype(np.int64)
        self.comm.Allreduce(MPI.IN_PLACE, owner, op=MPI.MIN)
        keep = found & (owner == self.comm.rank)
        self.cell = cell[keep]
        self.xi = xi[keep]
        self.id = np.asarray(ids, np.int64)[keep]
        self.row = np.asarray(rowid, np.int64)[keep]
        self.initial = pts[keep]
        self.t_out = np.full(self.cell.size, np.nan)
        self.out_pos = np.zeros((0, 2))
        self._gone = {"id": [], "row": [], "t": [], "initial": []}
        self.solver = ale.solver
        self.mesh = mesh  # its own: after a rezone the solver's is another
        self.count = self.comm.allreduce(int(keep.sum()), op=MPI.SUM)
        self.carry_shift = 0.0  # (a rezone: see carried)

    def carried(self, ale) -> Tracers:
        """These tracers on the mesh of another ALE (a rezone, :mod:`.rezone`): each located
        afresh at its current position on its own (old) mesh - not the solver's, which has
        moved on - on the new mesh (collective), with its id, row, initial position and the
        record of those already discharged. A point the new
        mesh does not hold (a sliver of the old free surface that the new one, a spline through
        the surface nodes, cuts off) goes to the centre of the nearest new cell: a shift of under
        a cell, the largest of which is the new tracers' ``carry_shift`` (m, global)."""
        pos = self.positions()
        everyone = self.comm.allgather((pos, self.id, self.row, self.initial))
        pts = np.concatenate([e[0] for e in everyone]).reshape(-1, 2)
        x = np.ascontiguousarray(ale.mesh.geometry.x[:, :2])
        cn, n = ale.remapper.cn_tensor, ale.remapper.n_owned
        found = (_locate_brute(x, cn, n, pts)[0] >= 0).astype(np.int64)
        self.comm.Allreduce(MPI.IN_PLACE, found, op=MPI.MAX)
        if not found.all():
            lost = np.nonzero(found == 0)[0]
            centres = x[cn[:n]].mean(axis=1)
            dist = np.linalg.norm(pts[lost][:, None] - centres[None], axis=2) if n else np.full((lost.size, 1), np.inf)
            j = dist.argmin(axis=1)
            cands = self.comm.allgather((dist[np.arange(lost.size), j], centres[j] if n else np.zeros((lost.size, 2))))
            best = np.argmin([c[0] for c in cands], axis=0)
            moved = np.array([cands[b][1][i] for i, b in enumerate(best)]).reshape(-1, 2)
            shift = float(np.linalg.norm(moved - pts[lost], axis=1).max())
            pts[lost] = moved
        else:
            shift = 0.0
        new = Tracers(ale, 0, 0, pts)
        new.carry_shift = shift
        ids = np.concatenate([e[1] for e in everyone]).astype(np.int64)
        rows = np.concatenate([e[2] for e in everyone]).astype(np.int64)
        initial = np.concatenate([e[3] for e in everyone]).reshape(-1, 2)
        new.id, new.row, new.initial = ids[new.id], rows[new.id], initial[new.id]
        new._gone = {k: list(v) for k, v in self._gone.items()}
        new.count = self.count
        return new

    def positions(self, x: np.ndarray | None = None) -> np.ndarray:
        """Current positions of this rank's tracers."""
        x = np.ascontiguousarray(self.mesh.geometry.x[:, :2]) if x is None else x
        return map_points(x, self.cn_tensor, self.cell, self.xi)

    def relocate(self, xL: np.ndarray, xS: np.ndarray) -> None:
        """After a remap from positions xL to xS: find every tracer on the new mesh."""
        p = self.positions(xL)
        cell = self.cell.copy()
        xi = self.xi.copy()
        status = np.zeros(cell.size, np.int64)
        _walk(xS, self.cn_tensor, self.nbr, self.n_owned, p, cell, xi, status)
        out = status == DISCHARGED
        if out.any():
            self._gone["id"] += self.id[out].tolist()
            self._gone["row"] += self.row[out].tolist()
            self._gone["t"] += [self.solver.t] * int(out.sum())
            self._gone["initial"] += self.initial[out].tolist()
        stay = status == FOUND
        move = status == GHOST
        ids, rows, initial = self.id, self.row, self.initial  # indexed as ``cell`` (before filtering)
        self.cell, self.xi = cell[stay], xi[stay]
        self.id, self.row, self.initial = ids[stay], rows[stay], initial[stay]
        # tracers that walked into a ghost cell go to its owner, which walks on from there
        # (rare: one cheap count decides whether the exchange runs at all)
        if self.comm.size == 1 or reduce_scalar(self.comm, float(move.sum())) == 0.0:
            return
        outgoing = [[] for _ in range(self.comm.size)]
        for k in np.nonzero(move)[0]:
            g = cell[k] - self.n_owned
            outgoing[int(self.ghost_owner[g])].append((int(self.ghost_global[g]), p[k, 0], p[k, 1], int(ids[k]),
                                                         int(rows[k]), *initial[k]))
        incoming = [t for part in self.comm.alltoall(outgoing) for t in part]
        if incoming:
            a = np.array(incoming, float).reshape(-1, 7)
            c = a[:, 0].astype(np.int64) - self.offset
            q = np.ascontiguousarray(a[:, 1:3])
            x2 = np.zeros((c.size, 2))
            st = np.zeros(c.size, np.int64)
            _walk(xS, self.cn_tensor, self.nbr, self.n_owned, q, c, x2, st)
            ok = st == FOUND  # a second hop in one remap is not expected; such a tracer is dropped
            self.cell = np.concatenate([self.cell, c[ok]])
            self.xi = np.concatenate([self.xi, x2[ok]])
            self.id = np.concatenate([self.id, a[ok, 3].astype(np.int64)])
            self.row = np.concatenate([self.row, a[ok, 4].astype(np.int64)])
            self.initial = np.concatenate([self.initial, a[ok, 5:7]])

    def gather(self) -> dict | None:
        """All tracers on rank 0: id, row, position, initial position; discharged ones with
        the time they left."""
        pos = self.positions()
        parts = self.comm.gather((self.id, self.row, pos, self.initial, dict(self._gone)), root=0)
        if parts is None:
            return None
        gone = {k: sum((p[4][k] for p in parts), []) for k in ("id", "row", "t", "initial")}
        return {"id": np.concatenate([p[0] for p in parts]), "row": np.concatenate([p[1] for p in parts]),
                "xy": np.concatenate([p[2] for p in parts]).reshape(-1, 2),
                "initial": np.concatenate([p[3] for p in parts]).reshape(-1, 2),
                "out_id": np.asarray(gone["id"], np.int64), "out_row": np.asarray(gone["row"], np.int64),
                "out_initial": np.asarray(gone["initial"], float).reshape(-1, 2),
                "out_t": np.asarray(gone["t"], float)}


# ---------------------------------------------------------------------------- kernels
@numba.njit(cache=True)
def _bilinear(x, nodes, xi, eta):
    a, b, c, d = nodes[0], nodes[1], nodes[2], nodes[3]
    N0, N1, N2, N3 = (1 - xi) * (1 - eta), xi * (1 - eta), (1 - xi) * eta, xi * eta
    r = N0 * x[a, 0] + N1 * x[b, 0] + N2 * x[c, 0] + N3 * x[d, 0]
    z = N0 * x[a, 1] + N1 * x[b, 1] + N2 * x[c, 1] + N3 * x[d, 1]
    rx = (1 - eta) * (x[b, 0] - x[a, 0]) + eta * (x[d, 0] - x[c, 0])
    zx = (1 - eta) * (x[b, 1] - x[a, 1]) + eta * (x[d, 1] - x[c, 1])
    re = (1 - xi) * (x[c, 0] - x[a, 0]) + xi * (x[d, 0] - x[b, 0])
    ze = (1 - xi) * (x[c, 1] - x[a, 1]) + xi * (x[d, 1] - x[b, 1])
    return r, z, rx, zx, re, ze


@numba.njit(cache=True)
def _inverse(x, nodes, pr, pz):
    """Reference coordinates of (pr, pz) in a bilinear cell (Newton from the centre)."""
    xi, eta = 0.5, 0.5
    for _ in range(30):
        r, z, rx, zx, re, ze = _bilinear(x, nodes, xi, eta)
        det = rx * ze - re * zx
        if det == 0.0:
            break
        fr, fz = r - pr, z - pz
        dxi = (ze * fr - re * fz) / det
        deta = (-zx * fr + rx * fz) / det
        # damped: a far point must not throw Newton off the cell's map
        step = max(abs(dxi), abs(deta))
        if step > 2.0:
            dxi *= 2.0 / step
            deta *= 2.0 / step
        xi -= dxi
        eta -= deta
        if step < 1e-13:
            break
    return xi, eta


@numba.njit(cache=True)
def _map(x, cn, cell, xi, out):
    for k in range(cell.shape[0]):
        r, z, _, _, _, _ = _bilinear(x, cn[cell[k]], xi[k, 0], xi[k, 1])
        out[k, 0] = r
        out[k, 1] = z


@numba.njit(cache=True)
def _walk(x, cn, nbr, n_owned, p, cell, xi, status):
    """Walk each point p[k] from cell[k] to the cell containing it (in place)."""
    tol = 1e-10
    for k in range(p.shape[0]):
        c = cell[k]
        status[k] = FOUND
        a, b = 0.5, 0.5
        for _ in range(64):
            a, b = _inverse(x, cn[c], p[k, 0], p[k, 1])
            # the side the point lies most beyond: 0 ξ<0, 1 ξ>1, 2 η<0, 3 η>1
            beyond = (-a, a - 1.0, -b, b - 1.0)
            side = -1
            worst = tol
            for s in range(4):
                if beyond[s] > worst:
                    worst = beyond[s]
                    side = s
            if side < 0:
                break
            nb = nbr[c, side]
            if nb == OUTSIDE:
                status[k] = DISCHARGED
                break
            if nb < 0:  # a wall or the free surface: put the point on it and look again
                if side == 0:
                    a = 0.0
                elif side == 1:
                    a = 1.0
                elif side == 2:
                    b = 0.0
                else:
                    b = 1.0
                r, z, _, _, _, _ = _bilinear(x, cn[c], a, b)
                p[k, 0] = r
                p[k, 1] = z
                continue
            c = nb
            if nb >= n_owned:
                status[k] = GHOST
                break
        cell[k] = c
        xi[k, 0] = min(max(a, 0.0), 1.0)
        xi[k, 1] = min(max(b, 0.0), 1.0)


@numba.njit(cache=True)
def _locate_brute(x, cn, n_cells, pts):
    """Cell and reference coordinates of each point among the first n_cells (-1: none)."""
    n = pts.shape[0]
    cell = -np.ones(n, np.int64)
    xi = np.zeros((n, 2))
    for k in range(n):
        for c in range(n_cells):
            rmin, rmax, zmin, zmax = 1e300, -1e300, 1e300, -1e300
            for j in range(4):
                rmin = min(rmin, x[cn[c, j], 0])
                rmax = max(rmax, x[cn[c, j], 0])
                zmin = min(zmin, x[cn[c, j], 1])
                zmax = max(zmax, x[cn[c, j], 1])
            if not (rmin - 1e-12 <= pts[k, 0] <= rmax + 1e-12 and zmin - 1e-12 <= pts[k, 1] <= zmax + 1e-12):
                continue
            a, b = _inverse(x, cn[c], pts[k, 0], pts[k, 1])
            if -1e-10 <= a <= 1 + 1e-10 and -1e-10 <= b <= 1 + 1e-10:
                cell[k] = c
                xi[k, 0] = min(max(a, 0.0), 1.0)
                xi[k, 1] = min(max(b, 0.0), 1.0)
                break
    return cell, xi


locate_points = _locate_brute  # public name: cell and (ξ, η) of points among the first n cells


def map_points(x, cn, cell, xi) -> np.ndarray:
    """Positions of the points at reference coordinates xi of the cells ``cell``."""
    out = np.empty((cell.size, 2))
    _map(x, cn, cell, xi, out)
    return out
