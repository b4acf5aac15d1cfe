"""Cell geometry of the Q1 quadrilaterals in the (r, z) plane — in one place.

DOLFINx orders a quadrilateral's vertices as a tensor product, (0, 1, 2, 3) = (ξ, η) ∈
{(0,0), (1,0), (0,1), (1,1)}, so the boundary cycle is 0-1-3-2 (:data:`CYCLE`). Node lists
come in both orders: :func:`tensor_nodes` (what the isoparametric map and the remap use) and
:func:`cycle_nodes` (areas, edges, corner Jacobians, the stable Δt). Everything here works
on node positions and node lists, so it serves the solver, ALE, the monitors and the report
alike (the compiled kernels take the arrays, not the mesh).
"""

from __future__ import annotations

import math

import numpy as np

from silo_dolfinx._jit_cache import numba
from silo_dolfinx._compat import geometry_dofmap
from silo_dolfinx.kernels import FAST, uniform_strain_vectors

CYCLE = np.array([0, 1, 3, 2])
TWO_PI = 2.0 * math.pi


def tensor_nodes(mesh, n: int | None = None) -> np.ndarray:
    """(n, 4) geometry nodes of the first ``n`` local cells (default: all) in tensor order."""
    gdm = geometry_dofmap(mesh)
    return np.ascontiguousarray((gdm if n is None else gdm[:n]).astype(np.int64))


def cycle_nodes(mesh, n: int | None = None) -> np.ndarray:
    """(n, 4) geometry nodes of the first ``n`` local cells (default: all) in boundary-cycle order."""
    return np.ascontiguousarray(tensor_nodes(mesh, n)[:, CYCLE])


def cell_corners(mesh, cells: np.ndarray | None = None) -> np.ndarray:
    """(n, 4, 2) corner coordinates of local cells in boundary-cycle order."""
    dofmap = geometry_dofmap(mesh)
    if cells is None:
        cells = np.arange(mesh.topology.index_map(2).size_local, dtype=np.int32)
    return mesh.geometry.x[dofmap[cells][:, CYCLE], :2]


@numba.njit(cache=True)
def corner_jacobians(xy: np.ndarray) -> np.ndarray:
    """Twice the signed area of the corner triangles, (n, 4): all > 0 for a valid CCW cell."""
    n = xy.shape[0]
    out = np.empty((n, 4))
    for c in range(n):
        for k in range(4):
            a = xy[c, (k + 3) % 4]
            b = xy[c, k]
            d = xy[c, (k + 1) % 4]
            out[c, k] = (d[0] - b[0]) * (a[1] - b[1]) - (d[1] - b[1]) * (a[0] - b[0])
    return out


@numba.njit(cache=True)
def aspect_ratios(xy: np.ndarray) -> np.ndarray:
    """Longest over shortest edge of each cell."""
    n = xy.shape[0]
    out = np.empty(n)
    for c in range(n):
        lo = 1e300
        hi = 0.0
        for k in range(4):
            a = xy[c, k]
            b = xy[c, (k + 1) % 4]
            L = np.sqrt((b[0] - a[0]) ** 2 + (b[1] - a[1]) ** 2)
            lo = min(lo, L)
            hi = max(hi, L)
        out[c] = hi / lo if lo > 0 else np.inf
    return out


@numba.njit(cache=True)
def worst_cells(x: np.ndarray, cycle_nodes: np.ndarray, orient: np.ndarray, n: int) -> tuple[float, float]:
    """(min scaled Jacobian, max aspect ratio) over the first ``n`` cells, straight from node
    positions ``x`` and boundary-cycle nodes (no arrays allocated: the ALE smoother calls
    this at every smoothing). ``orient`` is each cell's sign of area (±1), so a cell that
    turns inside out has a negative scaled Jacobian."""
    smin = 1e300
    amax = 0.0
    for c in range(n):
        n0, n1, n2, n3 = cycle_nodes[c, 0], cycle_nodes[c, 1], cycle_nodes[c, 2], cycle_nodes[c, 3]
        # the four edges k -> k+1 and their lengths, each once
        e0r, e0z = x[n1, 0] - x[n0, 0], x[n1, 1] - x[n0, 1]
        e1r, e1z = x[n2, 0] - x[n1, 0], x[n2, 1] - x[n1, 1]
        e2r, e2z = x[n3, 0] - x[n2, 0], x[n3, 1] - x[n2, 1]
        e3r, e3z = x[n0, 0] - x[n3, 0], x[n0, 1] - x[n3, 1]
        l0 = math.sqrt(e0r * e0r + e0z * e0z)
        l1 = math.sqrt(e1r * e1r + e1z * e1z)
        l2 = math.sqrt(e2r * e2r + e2z * e2z)
        l3 = math.sqrt(e3r * e3r + e3z * e3z)
        # corner k lies between edge k-1 (in) and edge k (out): J_k = (e_{k-1} x e_k) orient
        o = orient[c]
        smin = min(smin, o * (e3r * e0z - e3z * e0r) / max(l3 * l0, 1e-300),
                   o * (e0r * e1z - e0z * e1r) / max(l0 * l1, 1e-300),
                   o * (e1r * e2z - e1z * e2r) / max(l1 * l2, 1e-300),
                   o * (e2r * e3z - e2z * e3r) / max(l2 * l3, 1e-300))
        lo = min(l0, l1, l2, l3)
        amax = max(amax, max(l0, l1, l2, l3) / lo if lo > 0.0 else np.inf)
    return smin, amax


@numba.njit(cache=True)
def orientation(x, cn):
    """Sign (±1) of each cell's area, nodes in boundary-cycle order."""
    out = np.empty(cn.shape[0])
    for c in range(cn.shape[0]):
        a = 0.0
        for k in range(4):
            p, q = cn[c, k], cn[c, (k + 1) % 4]
            a += x[p, 0] * x[q, 1] - x[q, 0] * x[p, 1]
        out[c] = 1.0 if a > 0.0 else -1.0
    return out


@numba.njit(cache=True, fastmath=FAST)
def qp_volumes(x, cn_tensor, points, weights, n_cells, out):
    """Quadrature volumes 2π r |det J| w_q of the first ``n_cells`` Q1 cells at positions
    ``x`` (the solver's dV layout: cell-major, basix point order). One point is the uniform-
    strain cell (:func:`silo_dolfinx.kernels.mean_gradients_q1`): its volume is the cell's exact
    volume of revolution, in the same closed form (:func:`silo_dolfinx.kernels.uniform_strain_vectors`),
    not 2π r_c |det J_c|."""
    nq = points.shape[0]
    for c in range(n_cells):
        a, b, cc, d = cn_tensor[c, 0], cn_tensor[c, 1], cn_tensor[c, 2], cn_tensor[c, 3]
        if nq == 1:
            _, _, _, v = uniform_strain_vectors((x[a, 0], x[b, 0], x[cc, 0], x[d, 0]),
                                                (x[a, 1], x[b, 1], x[cc, 1], x[d, 1]))
            out[c] = TWO_PI * abs(v)
            continue
        for q in range(nq):
            xi, eta = points[q, 0], points[q, 1]
            r = ((1.0 - xi) * (1.0 - eta) * x[a, 0] + xi * (1.0 - eta) * x[b, 0] + (1.0 - xi) * eta * x[cc, 0]
                 + xi * eta * x[d, 0])
            dr_dxi = (1.0 - eta) * (x[b, 0] - x[a, 0]) + eta * (x[d, 0] - x[cc, 0])
            dz_dxi = (1.0 - eta) * (x[b, 1] - x[a, 1]) + eta * (x[d, 1] - x[cc, 1])
            dr_deta = (1.0 - xi) * (x[cc, 0] - x[a, 0]) + xi * (x[d, 0] - x[b, 0])
            dz_deta = (1.0 - xi) * (x[cc, 1] - x[a, 1]) + xi * (x[d, 1] - x[b, 1])
            out[c * nq + q] = TWO_PI * r * abs(dr_dxi * dz_deta - dr_deta * dz_dxi) * weights[q]


# ---------------------------------------------------------------------------- sections of a snapshot
def cell_areas(corners) -> np.ndarray:
    """Areas of quadrilaterals (n, 4, 2) given in boundary-cycle order."""
    c = np.asarray(corners, float)
    x, y = c[:, :, 0], c[:, :, 1]
    return 0.5 * np.abs(np.sum(x * np.roll(y, -1, 1) - np.roll(x, -1, 1) * y, axis=1))
