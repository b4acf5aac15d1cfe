"""Quadrilateral quality in the (r, z) plane: corner Jacobians, aspect ratio, inverted cells.

Used to accept a freshly built mesh and, later, by the ALE smoother to refuse a move that
would invert a cell. DOLFINx orders a quadrilateral's vertices as a tensor product,
(0, 1, 2, 3) = (ξ, η) ∈ {(0,0), (1,0), (0,1), (1,1)}, so the boundary cycle is 0-1-3-2.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from silo_dolfinx._compat import geometry_dofmap

CYCLE = np.array([0, 1, 3, 2])


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


def quality_report(mesh) -> dict:
    """Global mesh-quality numbers: inverted cells, min scaled Jacobian, aspect ratios, angles."""
    from mpi4py import MPI

    xy = cell_corners(mesh)
    J = corner_jacobians(np.ascontiguousarray(xy))
    # A mesh may be consistently clockwise (gmsh surface orientation); what matters is that
    # all corners of all cells share one sign.
    sign = np.sign(J.sum()) if J.size else 1.0
    sign = mesh.comm.allreduce(float(sign), op=MPI.SUM)
    sign = 1.0 if sign >= 0 else -1.0
    Js = sign * J
    e_prev = np.linalg.norm(xy - np.roll(xy, 1, axis=1), axis=2)
    e_next = np.linalg.norm(np.roll(xy, -1, axis=1) - xy, axis=2)
    scaled = Js / np.maximum(e_prev * e_next, 1e-300)  # = sin(corner angle)
    ar = aspect_ratios(np.ascontiguousarray(xy))
    comm = mesh.comm
    return {
        "cells": comm.allreduce(xy.shape[0], op=MPI.SUM),
        "inverted": comm.allreduce(int(np.sum(np.any(Js <= 0.0, axis=1))), op=MPI.SUM),
        "min_scaled_jacobian": comm.allreduce(float(scaled.min(initial=1.0)), op=MPI.MIN),
        "max_aspect_ratio": comm.allreduce(float(ar.max(initial=1.0)), op=MPI.MAX),
        "min_angle_deg": float(np.degrees(np.arcsin(np.clip(
            comm.allreduce(float(scaled.min(initial=1.0)), op=MPI.MIN), -1, 1)))),
        "orientation": "counter-clockwise" if sign > 0 else "clockwise",
    }


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
