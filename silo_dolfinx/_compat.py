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


def facet_ghost_partitioner():
    """A cell partitioner that adds one layer of ghost cells across partition facets (the
    ALE remap reads its neighbours' state there). DOLFINx 0.11 takes the maximum facet-to-
    cell links as a second argument; 0.10 does not."""
    from dolfinx import mesh as dmesh

    try:
        return dmesh.create_cell_partitioner(dmesh.GhostMode.shared_facet, 2)
    except TypeError:  # pragma: no cover - DOLFINx 0.10
        return dmesh.create_cell_partitioner(dmesh.GhostMode.shared_facet)
