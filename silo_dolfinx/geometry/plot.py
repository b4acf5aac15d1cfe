"""PNG pictures of silo meshes (matplotlib; gathered on rank 0, drawn there)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silo_dolfinx.geometry.quality import cell_corners

COLOURS = {"wall": "tab:red", "outlet": "tab:green", "top": "tab:blue", "axis": "tab:gray"}


def gather_cells(sm) -> np.ndarray | None:
    """All cells' corner coordinates (n, 4, 2) on rank 0, None elsewhere."""
    parts = sm.comm.gather(cell_corners(sm.mesh), root=0)
    return np.concatenate(parts) if parts is not None else None


def gather_facets(sm, name: str) -> np.ndarray | None:
    """Segments (n, 2, 2) of the facets tagged ``name`` on rank 0."""
    from dolfinx import mesh as dmesh

    m = sm.mesh
    f = sm.facets(name)
    f = f[f < m.topology.index_map(1).size_local]
    nodes = dmesh.entities_to_geometry(m, 1, f)
    seg = m.geometry.x[nodes][:, :, :2] if f.size else np.zeros((0, 2, 2))
    parts = sm.comm.gather(seg, root=0)
    return np.concatenate(parts) if parts is not None else None


def plot_mesh(sm, path: str | Path, title: str = "") -> None:
    """Draw the mesh, its tagged boundaries and the analytic wall to ``path`` (rank 0 writes)."""
    cells = gather_cells(sm)
    facets = {n: gather_facets(sm, n) for n in COLOURS}
    if sm.comm.rank != 0:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PolyCollection

    ol = sm.outline
    H = ol.fill_height
    R = ol.r_max
    fig_h = 8.0
    fig_w = max(3.0, min(12.0, fig_h * (R * 1.15) / (H * 1.05) + 1.0)) + 1.6
    fig, ax = plt.subplots(figsize=(fig_w, fig_h), dpi=150)
    ax.add_collection(PolyCollection(cells, facecolor="#f4efe1", edgecolor="#555555", linewidth=0.2))
    for name, segs in facets.items():
        ax.add_collection(LineCollection(segs, colors=COLOURS[name], linewidths=1.6, label=name))
    s = np.linspace(0.0, ol.wall.length, 400)
    w = ol.wall.point_at(s)
    ax.plot(w[:, 0], w[:, 1], "k--", lw=0.6, label="analytic wall")
    ax.set_aspect("equal")
    ax.set_xlim(-0.03 * R, 1.12 * R)
    ax.set_ylim(-0.03 * H, 1.03 * max(H, ol.height if ol.height < 1.2 * H else H))
    ax.set_xlabel("r (m)")
    ax.set_ylabel("z (m)")
    ax.set_title(title or f"{ol.shape}: {len(cells)} cells")
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=7, framealpha=0.9)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
