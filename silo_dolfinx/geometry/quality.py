"""Quadrilateral quality in the (r, z) plane: corner Jacobians, aspect ratio, inverted cells.

Used to accept a freshly built mesh and, later, by the ALE smoother to refuse a move that
would invert a cell. The cell geometry itself (corners,
Jacobians, aspect ratios) lives in :mod:`silo_dolfinx.geometry.cells`.
"""

from __future__ import annotations

import numpy as np

from silo_dolfinx.geometry.cells import CYCLE, aspect_ratios, cell_corners, corner_jacobians, worst_cells

__all__ = ["CYCLE", "aspect_ratios", "cell_corners", "corner_jacobians", "corner_measures", "quality_report",
           "worst_cells"]


def corner_measures(xy: np.ndarray, sign: float | None = None,
                    J: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(scaled Jacobian, interior angle in degrees) of every corner of cells ``xy`` (n, 4, 2):
    the sine and the angle between a corner's two edges, both negative where the corner is
    inverted. ``sign``: the mesh's orientation (+1 counter-clockwise); default, the sign of the
    cells' summed Jacobians (a mesh may be consistently clockwise: gmsh's surface orientation).
    ``J``: the cells' corner_jacobians, if already computed."""
    J = corner_jacobians(np.ascontiguousarray(xy)) if J is None else J
    if sign is None:
        sign = 1.0 if J.sum() >= 0 else -1.0
    J = sign * J
    e_prev = xy - np.roll(xy, 1, axis=1)
    e_next = np.roll(xy, -1, axis=1) - xy
    scaled = J / np.maximum(np.linalg.norm(e_prev, axis=2) * np.linalg.norm(e_next, axis=2), 1e-300)
    angle = np.degrees(np.arctan2(J, -np.einsum("cki,cki->ck", e_prev, e_next)))
    return scaled, angle


def quality_report(mesh) -> dict:
    """Global mesh-quality numbers: inverted cells, min scaled Jacobian (the sine of the corner
    angle farthest from 90°), aspect ratios, the smallest and largest corner angles."""
    from mpi4py import MPI

    comm = mesh.comm
    xy = cell_corners(mesh)
    J = corner_jacobians(np.ascontiguousarray(xy))
    sign = comm.allreduce(float(np.sign(J.sum()) if J.size else 1.0), op=MPI.SUM)
    scaled, angle = corner_measures(xy, 1.0 if sign >= 0 else -1.0, J)
    ar = aspect_ratios(np.ascontiguousarray(xy))
    return {
        "cells": comm.allreduce(xy.shape[0], op=MPI.SUM),
        "inverted": comm.allreduce(int(np.sum(np.any(scaled <= 0.0, axis=1))), op=MPI.SUM),
        "min_scaled_jacobian": comm.allreduce(float(scaled.min(initial=1.0)), op=MPI.MIN),
        "max_aspect_ratio": comm.allreduce(float(ar.max(initial=1.0)), op=MPI.MAX),
        "min_angle_deg": comm.allreduce(float(angle.min(initial=90.0)), op=MPI.MIN),
        "max_angle_deg": comm.allreduce(float(angle.max(initial=90.0)), op=MPI.MAX),
        "orientation": "counter-clockwise" if sign >= 0 else "clockwise",
    }
