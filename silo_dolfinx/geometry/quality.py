"""Quadrilateral quality in the (r, z) plane: corner Jacobians, aspect ratio, inverted cells.

Used to accept a freshly built mesh and, later, by the ALE smoother to refuse a move that
would invert a cell. The cell geometry itself (corners,
Jacobians, aspect ratios) lives in :mod:`silo_dolfinx.geometry.cells`.
"""

from __future__ import annotations

import numpy as np

from silo_dolfinx.geometry.cells import CYCLE, aspect_ratios, cell_corners, corner_jacobians, worst_cells

__all__ = ["CYCLE", "aspect_ratios", "cell_corners", "corner_jacobians", "quality_report", "worst_cells"]


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


