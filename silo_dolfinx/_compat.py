"""The few DOLFINx API differences between 0.10 and 0.11 that this package touches."""

from __future__ import annotations

import numpy as np


def geometry_dofmap(mesh) -> np.ndarray:
    """(num_cells, nodes_per_cell) geometry dofmap of a single-cell-type mesh."""
    g = mesh.geometry
    d = getattr(type(g), "dofmaps", None)
    if d is not None:
        d = g.dofmaps
        return d(0) if callable(d) else d[0]
    return g.dofmap  # pragma: no cover - older releases
