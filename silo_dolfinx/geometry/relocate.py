"""Node relocation of a fresh unstructured mesh for the explicit time step.

An explicit run steps at the stable Δt of its *worst* cell (:func:`kernels.stable_dt`:
the smallest altitude a/e_max over the wave speed), so a few small cells cost every step.
Frontal-Delaunay quadrilaterals recombined by Blossom leave such cells where the front
closes: on the ch. 4 hopper (h 15.5 mm, 7,814 cells) the smallest altitude is 5.7 mm against
a median of 14.6 mm, and that one cell sets Δt for the whole run (9.2 mm after relocation).

Relocation moves nodes - never the topology - to raise the smallest altitude. Each sweep
takes the cells below the ``fraction`` quantile of L and, at each of their movable nodes, a
pattern search (16 directions, steps from 1/5 to 1/50 of the local cell size) for the
position that maximises the smallest L of the cells around the node - the plain altitude,
without the hoop term (a measure of the distance from the axis, which relocation should not
buy by pushing the cells there outwards) - accepting a move only
if no corner of those cells falls below a scaled Jacobian of ``min_scaled_jacobian`` (or its
value before the move, if already lower). Moves never lower the local minimum of L, so the
mesh's smallest L rises monotonically.

Nodes inside the surface move freely; nodes on a horizontal internal line (a filling
layer's top, which must stay a mesh line) move along it; nodes on the boundary and on other
lines stay where gmsh put them. The mesh keeps its cells, its node count and its boundary:
only the cell sizes even out where they were smallest.
"""

from __future__ import annotations

import numpy as np

from silo_dolfinx._jit_cache import numba
from silo_dolfinx.geometry.cells import orientation
from silo_dolfinx.kernels import dt_length

FIXED, FREE, HORIZONTAL = 0, 1, 2


def relocate_gmsh_model(*, sweeps: int = 100, fraction: float = 0.02, min_scaled_jacobian: float = 0.7) -> dict:
    """Relocate the nodes of the current gmsh model's quadrilateral mesh in place (rank-local,
    before it is distributed). Returns {"before": L_min, "after": L_min} in metres."""
    import gmsh

    tags, x, cn, kind = gmsh_mesh()
    x0 = x.copy()
    before, after = relocate(x, cn, kind, sweeps=sweeps, fraction=fraction, min_scaled_jacobian=min_scaled_jacobian)
    for i in np.flatnonzero(np.any(x != x0, axis=1)):
        gmsh.model.mesh.setNode(int(tags[i]), [float(x[i, 0]), float(x[i, 1]), 0.0], [])
    return {"before": before, "after": after}


def gmsh_mesh() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(node tags, positions (n, 2), quadrilaterals (nc, 4) as rows of the positions in
    boundary-cycle order, each node's kind) of the current gmsh model."""
    import gmsh

    tags, xyz, _ = gmsh.model.mesh.getNodes()
    index = np.full(int(tags.max()) + 1, -1, np.int64)
    index[tags.astype(np.int64)] = np.arange(tags.size)
    x = np.ascontiguousarray(xyz.reshape(-1, 3)[:, :2])
    cells = []
    for _, tag in gmsh.model.getEntities(2):
        types, _, nodes = gmsh.model.mesh.getElements(2, tag)
        cells += [index[n.astype(np.int64)].reshape(-1, 4) for t, n in zip(types, nodes) if t == 3]
    cn = np.ascontiguousarray(np.concatenate(cells))  # gmsh orders a quadrilateral's nodes around it
    kind = np.full(x.shape[0], FIXED, np.int8)
    for _, tag in gmsh.model.getEntities(2):
        kind[index[gmsh.model.mesh.getNodes(2, tag)[0].astype(np.int64)]] = FREE
    outer = {abs(t) for _, t in gmsh.model.getBoundary(gmsh.model.getEntities(2), combined=True, oriented=False)}
    span = float(np.ptp(x[:, 1])) or 1.0
    for _, tag in gmsh.model.getEntities(1):
        zmin, zmax = gmsh.model.getBoundingBox(1, tag)[1::3]
        if tag not in outer and zmax - zmin < 1e-6 * span:  # (OCC pads boxes by ~1e-7)
            kind[index[gmsh.model.mesh.getNodes(1, tag)[0].astype(np.int64)]] = HORIZONTAL
    return tags, x, cn, kind


def relocate(x: np.ndarray, cn: np.ndarray, kind: np.ndarray, *, sweeps: int = 100, fraction: float = 0.02,
             min_scaled_jacobian: float = 0.7) -> tuple[float, float]:
    """Relocate nodes ``x`` (n, 2) in place; ``cn`` (nc, 4) cells in boundary-cycle order,
    ``kind`` per node (FIXED, FREE, HORIZONTAL). Returns (smallest L before, after)."""
    orient = orientation(x, cn)
    counts = np.bincount(cn.ravel(), minlength=x.shape[0])
    ptr = np.concatenate(([0], np.cumsum(counts))).astype(np.int64)
    adj = np.argsort(cn.ravel(), kind="stable").astype(np.int64) // 4  # cells around each node
    kind = np.where(counts > 0, kind, FIXED).astype(np.int8)  # nodes of no cell (stray line nodes) stay
    L = np.empty(cn.shape[0])
    _lengths(x, cn, orient, L)
    before = float(L.min())
    _sweeps(x, (cn, orient, ptr, adj), kind, L, (sweeps, fraction, min_scaled_jacobian))
    _lengths(x, cn, orient, L)
    return before, float(L.min())


@numba.njit(cache=True)
def _lengths(x, cn, orient, L):
    for c in range(cn.shape[0]):
        L[c] = dt_length(x, cn, c, orient[c], 0.0)


@numba.njit(cache=True)
def _min_sj(x, cn, c, o):
    """Smallest scaled Jacobian (sine of a corner angle) of cell c."""
    s = 1.0
    for k in range(4):
        a, b, d = cn[c, (k + 3) % 4], cn[c, k], cn[c, (k + 1) % 4]
        e1r, e1z = x[b, 0] - x[a, 0], x[b, 1] - x[a, 1]
        e2r, e2z = x[d, 0] - x[b, 0], x[d, 1] - x[b, 1]
        den = np.sqrt((e1r * e1r + e1z * e1z) * (e2r * e2r + e2z * e2z))
        s = min(s, o * (e1r * e2z - e1z * e2r) / max(den, 1e-300))
    return s


@numba.njit(cache=True)
def _around(x, cn, orient, ptr, adj, n):
    """(smallest L, smallest scaled Jacobian, mean area) of the cells around node n."""
    lo, sj, area = 1e300, 1.0, 0.0
    for j in range(ptr[n], ptr[n + 1]):
        c = adj[j]
        lo = min(lo, dt_length(x, cn, c, orient[c], 0.0))
        sj = min(sj, _min_sj(x, cn, c, orient[c]))
        a = 0.0
        for k in range(4):
            p, q = cn[c, k], cn[c, (k + 1) % 4]
            a += x[p, 0] * x[q, 1] - x[q, 0] * x[p, 1]
        area += 0.5 * abs(a)
    return lo, sj, area / (ptr[n + 1] - ptr[n])


@numba.njit(cache=True)
def _sweeps(x, mesh, kind, L, options):
    """The pattern search (module docstring); mesh = (cells, orientation, node → cells CSR
    pointers and cells), options = (sweeps, fraction, min_scaled_jacobian)."""
    cn, orient, ptr, adj = mesh
    sweeps, fraction, sj_floor = options
    nc = cn.shape[0]
    angles = 2.0 * np.pi * np.arange(16) / 16.0
    steps = np.array([0.2, 0.1, 0.05, 0.02])
    seen = np.zeros(x.shape[0], np.int64)
    for sweep in range(1, sweeps + 1):
        for c in range(nc):
            L[c] = dt_length(x, cn, c, orient[c], 0.0)
        threshold = np.sort(L)[min(nc - 1, int(fraction * nc))]
        moved = 0
        for c in range(nc):
            if L[c] > threshold:
                continue
            for k in range(4):
                n = cn[c, k]
                if kind[n] == FIXED or seen[n] == sweep:
                    continue
                seen[n] = sweep
                best, sj0, area = _around(x, cn, orient, ptr, adj, n)
                floor = min(sj_floor, sj0)
                h = np.sqrt(area)
                br, bz = x[n, 0], x[n, 1]
                for s in steps:
                    for t in angles:
                        dr, dz = s * h * np.cos(t), s * h * np.sin(t)
                        if kind[n] == HORIZONTAL:
                            if abs(dz) > 1e-12 * h:
                                continue
                            dz = 0.0
                        x[n, 0], x[n, 1] = br + dr, bz + dz
                        lo, sj, _ = _around(x, cn, orient, ptr, adj, n)
                        if lo > best * (1.0 + 1e-4) and sj >= floor:
                            best, br, bz = lo, br + dr, bz + dz
                            moved += 1
                        x[n, 0], x[n, 1] = br, bz
        if moved == 0:
            break
