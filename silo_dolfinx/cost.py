"""What a scene will cost before it runs (``silo check --cost``).

From the scene's own mesh: the stable Δt of its cells at rest (the solver's estimate, the same
kernel), the cell that sets it, the steps each stage takes at that Δt, and a wall-clock from the
step cost measured in docs/performance.md (``benchmarks/step_cost.py``, ``benchmarks/ale_cost.py``)
on a 2-core machine. The steps are a lower bound: in a discharge Δt falls as the solid at the
outlet loosens and the draining fill squeezes the top rows (on the ch. 4 scene the run took 10 %
more steps than this estimate). The wall-clock is an order of magnitude for another machine.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from silo_dolfinx import kernels

# µs per element-step per core (docs/performance.md, "Cost": the ch. 4 hopper, 1 rank, 8.4k-33.5k
# cells), the 2-rank parallel efficiency measured there, the ALE's share of the discharge step at
# smoothing frequency 10 (ibid., "What ALE costs": 24-33 %; it scales with 10/frequency) and the
# outputs' (histories at 200 Hz, "Outputs at the history rate": ~5 %)
STEP_US = {"full": 0.27, "reduced": 0.17}
EFFICIENCY = 0.9
# ms per step whatever the mesh (the Python of the step, its kernel and assembly calls; on more
# than one rank also the ghost exchanges and the Δt reduction): fitted to the README's first scene
# (480 cells, 89k steps: 19.2 s serial, 15.9 s on 2 ranks, 2026-12-06), where it is most of the step
FIXED_MS = (0.055, 0.080)
ALE_SHARE_AT_10 = 0.30
OUTPUT_SHARE = 0.05
SMALL_CELL = 0.5  # a limiting cell below this fraction of element_size is worth naming


@dataclass
class Cost:
    cells: int
    dt: float  # the stable Δt at rest, before time_step_scale (s)
    where: tuple[float, float]  # the centroid (r, z) of the cell that sets it
    length: float  # its characteristic length (m)
    steps: dict[str, int]  # per stage, at time_step_scale × dt
    active: dict[str, float]  # per stage, the mean fraction of the cells that step (a layered fill's grows)
    seconds_per_rank_step: float  # serial seconds of one step of the whole mesh, without ALE

    def wall_clock(self, ranks: int, ale_frequency: int | None) -> float:
        """Seconds on ``ranks`` ranks (ALE in the discharge at ``ale_frequency``, None = off)."""
        per_cells = self.seconds_per_rank_step / (ranks * (EFFICIENCY if ranks > 1 else 1.0))
        fixed = 1e-3 * FIXED_MS[ranks > 1]
        ale = ALE_SHARE_AT_10 * 10.0 / ale_frequency if ale_frequency else 0.0

        def step(stage: str) -> float:  # seconds of one step of a stage
            seconds = fixed + per_cells * self.active[stage]
            return seconds * (1.0 + ale) if stage == "discharge" else seconds

        return (1.0 + OUTPUT_SHARE) * sum(n * step(stage) for stage, n in self.steps.items())


def estimate(scene, sm) -> Cost:
    """The cost of ``scene`` on its mesh ``sm`` (a :class:`~silo_dolfinx.geometry.mesher.SiloMesh`,
    serial: every cell)."""
    from silo_dolfinx.geometry.cells import cycle_nodes, orientation
    from silo_dolfinx.materials import make_material
    from silo_dolfinx.simulation.stages import compose

    mesh, num = sm.mesh, scene.numerics
    x = mesh.geometry.x
    cn = cycle_nodes(mesh, mesh.topology.index_map(2).size_local)
    n = cn.shape[0]
    rho = np.full(n, scene.material.density)
    L, c = np.empty(n), np.empty(n)
    cells = (np.zeros(n), L, c, rho)  # at rest: no volumetric strain rate
    viscosity = tuple(map(float, num.bulk_viscosity))
    if kernels.stable_dt(x, cn, orientation(x, cn), cells, make_material(scene.material).wave_modulus, viscosity,
                         num.mass_scaling, kernels.HOOP) <= 0.0:
        raise ValueError("the mesh has an inverted or collapsed cell")
    dts = np.empty(n)
    kernels.cell_dts(cells, viscosity, dts)
    i = int(np.argmin(dts))
    r, z = x[cn[i], :2].mean(axis=0)
    dt = float(dts[i])
    step = num.time_step_scale * dt
    steps = {st.name: int(np.ceil(st.duration / step)) for st in compose(scene) if st.duration > 0.0}
    f = scene.fill
    layers = f.layers if f.method == "layers" else 0
    active = dict.fromkeys(steps, 1.0) | ({"fill": (layers + 1) / (2 * layers)} if layers else {})
    return Cost(n, dt, (float(r), float(z)), float(L[i]), steps, active, n * STEP_US[num.integration] * 1e-6)


def describe(scene, cost: Cost, ranks: tuple[int, ...] = (1, 2)) -> list[str]:
    """Lines for ``silo check --cost``."""
    g = scene.geometry
    ale = scene.ale.frequency if scene.ale.enabled and scene.discharge.mode != "none" else None
    r, z = cost.where
    lines = [f"cost: {cost.cells:,} cells; stable Δt {cost.dt:.3g} s at rest (× time_step_scale "
             f"{scene.numerics.time_step_scale:g}: {scene.numerics.time_step_scale * cost.dt:.3g} s), set by the cell at "
             f"r = {r:.3g} m, z = {z:.3g} m, length {1e3 * cost.length:.3g} mm ({cost.length / g.element_size:.2g} × "
             "element_size)"]
    total = sum(cost.steps.values())
    lines.append(f"≈ {total:,} steps (" + ", ".join(f"{k} {v:,}" for k, v in cost.steps.items())
                 + "): a lower bound - in a discharge Δt falls as the outlet's solid loosens")
    lines.append("≈ " + ", ".join(f"{_minutes(cost.wall_clock(k, ale))} on {k} rank{'s' if k > 1 else ''}" for k in ranks)
                 + f" ({STEP_US[scene.numerics.integration]:g} µs per element-step per core"
                 + (f", ALE +{100 * ALE_SHARE_AT_10 * 10 / ale:.0f} % in the discharge" if ale else "")
                 + "; measured on a 2-core machine, docs/performance.md: yours may differ)")
    if cost.length < SMALL_CELL * g.element_size:
        lines.append(_why_small(scene, cost))
    return lines


def _why_small(scene, cost: Cost) -> str:
    g, ol = scene.geometry, scene.outline
    head = (f"the cell that sets Δt is {cost.length / g.element_size:.2g} × element_size: every step pays for it. ")
    if g.mesh == "structured" and not ol.has_floor:
        return head + ("A structured mesh of a wall without a floor has as many cells across its outlet as across its "
                       "top; geometry.mesh = \"unstructured\" keeps element_size there (with outlet_size_factor for the "
                       "outlet's resolution): on the ch. 4 hopper 6× faster and closer to the refined answer "
                       "(docs/performance.md, `python benchmarks/accuracy_cost.py --knobs mesh_type`).")
    return head + ("It is where the mesh is refined (outlet_size_factor, transition_size_factor) or squeezed "
                   "(max_aspect_ratio, a sharp corner): refine less there if its accuracy is not needed "
                   "(docs/performance.md, the accuracy knobs).")


def _minutes(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else (f"{seconds / 60:.0f} min" if seconds < 7200 else f"{seconds / 3600:.1f} h")
