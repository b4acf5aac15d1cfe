"""Pictures of the fields from the snapshots a run writes (``fields/snapshot_NNNN.npz``).

The whole silo is drawn: the axisymmetric section and its mirror image about the axis (a
user looks at a silo, not at half of one), axes in metres with equal scales, the simulated
time in the title, a labelled colour bar beside the plot. Fields: the speed (cell mean of its
corner nodes' |v|, with the tracers on top when the run has them) and the stress ratio q/p
(grey where a cell is stress-free and q/p is undefined: :func:`silo_dolfinx.invariants.stress_ratio`).
:func:`movie` animates the discharge (GIF) with fixed colour scales across the frames.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silo_dolfinx.analysis import cell_speed

FIELDS = {  # name: (colour-bar label, colour map)
    "speed": ("speed |v| (m/s, log scale)", "viridis"),
    "q_over_p": ("stress ratio q/p (grey: stress-free)", "viridis"),
}
SPEED_DECADES = 3  # the speed's colour scale spans this many decades below its top: the slow
# flow far from the outlet (mass or funnel flow) shows beside the fast flow at it


def field_values(snap: dict, field: str) -> np.ndarray:
    """The per-cell values of ``field`` in a snapshot."""
    if field == "speed":
        return cell_speed(snap)
    return np.asarray(snap[f"cell_{field}"], float)


def colour_limits(snaps: list[dict], field: str) -> tuple[float, float]:
    """One colour scale for all the snapshots: the speed's top is its largest value, and the
    scale goes SPEED_DECADES decades below it (log); q/p from 0 to 1.05 × its 99th percentile
    (the cone's slope, where the solid yields; a cell just above the stress-free pressure can
    read more - c/p - and would otherwise set the scale)."""
    return _limits([field_values(s, field) for s in snaps], field)


def _limits(values: list[np.ndarray], field: str) -> tuple[float, float]:
    """:func:`colour_limits` of per-cell values already computed."""
    top_of = np.nanmax if field == "speed" else (lambda v: np.nanpercentile(v, 99))  # noqa: E731
    tops = [top_of(v) for v in values if np.isfinite(v).any()]
    top = max(max(tops, default=1.0), 1e-12)
    return (top * 10.0**-SPEED_DECADES, top) if field == "speed" else (0.0, 1.05 * top)


def draw(ax, snap: dict, field: str, clim: tuple[float, float] | None = None):
    """The whole silo's ``field`` on ``ax`` (the section and its mirror); returns the collection
    (for a colour bar). Tracers, if the snapshot has them, are drawn on the speed."""
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    from matplotlib.colors import LogNorm, Normalize

    c = np.asarray(snap["corners"], float)
    v = field_values(snap, field)
    lo, hi = clim if clim is not None else _limits([v], field)  # (the values computed once)
    norm = LogNorm(lo, hi, clip=True) if field == "speed" else Normalize(lo, hi)
    mirror = c * np.array([-1.0, 1.0])
    cmap = plt.get_cmap(FIELDS[field][1]).with_extremes(bad="lightgrey")
    poly = PolyCollection(np.concatenate([c, mirror]), array=np.concatenate([v, v]), cmap=cmap, norm=norm,
                          edgecolors="face", linewidths=0.2)  # face-coloured edges: no seams between cells
    ax.add_collection(poly)
    if field == "speed" and "tracer_xy" in snap and len(snap["tracer_xy"]):
        xy = np.asarray(snap["tracer_xy"], float)
        ax.plot(np.concatenate([xy[:, 0], -xy[:, 0]]), np.concatenate([xy[:, 1], xy[:, 1]]), "o", ms=1.5, color="w",
                mec="k", mew=0.2)
    ax.axvline(0.0, color="k", lw=0.4, ls=":")  # the axis of symmetry
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("r (m)")
    ax.set_ylabel("z (m)")
    ax.set_title(f"t = {float(snap['t']):.3g} s")
    return poly


def picture(snap: dict, field: str, path: Path) -> None:
    """One field of one snapshot, the colour bar labelled beside it."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 7), layout="constrained")
    poly = draw(ax, snap, field)
    fig.colorbar(poly, ax=ax, shrink=0.8, label=FIELDS[field][0])
    fig.savefig(path, dpi=120)
    plt.close(fig)


def movie(snapshots: list[Path], path: Path, fields: tuple[str, ...] = ("speed", "q_over_p"), fps: int = 5) -> int:
    """An animated GIF of ``fields`` side by side through the ``snapshots`` (one frame each, the
    colour scales fixed over all of them); returns the number of frames."""
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    snaps = [dict(np.load(p)) for p in snapshots]
    if not snaps:
        return 0
    limits = {f: colour_limits(snaps, f) for f in fields}
    fig, axes = plt.subplots(1, len(fields), figsize=(5 * len(fields), 6.5), layout="constrained", squeeze=False)
    axes = axes[0]
    for ax, f in zip(axes, fields):
        poly = draw(ax, snaps[0], f, limits[f])
        fig.colorbar(poly, ax=ax, shrink=0.8, label=FIELDS[f][0])

    def frame(k):
        for ax, f in zip(axes, fields):
            for artist in list(ax.collections) + list(ax.lines):
                artist.remove()
            draw(ax, snaps[k], f, limits[f])
        return []

    FuncAnimation(fig, frame, frames=len(snaps), blit=False).save(path, writer=PillowWriter(fps=fps))
    plt.close(fig)
    return len(snaps)
