"""The silo model: a scene's mesh and solid on the explicit solver, with its effects.

:class:`SiloModel` owns what every silo has — the mesh, the material, the solver, the axis
(v_r = 0), the wall and outlet node sets, the filling layers — and the effects the scene asks
for (:func:`silo_dolfinx.simulation.effects.compose`), the stages
(:func:`silo_dolfinx.simulation.stages.compose`), the post-step hooks (ALE, when it runs)
and the output streams (set by :func:`silo_dolfinx.simulation.run`).
"""

from __future__ import annotations

import numpy as np

from silo_dolfinx.ale.rezone import Rezoner
from silo_dolfinx.geometry.mesher import FACET_TAGS, SiloMesh
from silo_dolfinx.invariants import stress_free_pressure
from silo_dolfinx.materials import make_material
from silo_dolfinx.simulation import effects as fx
from silo_dolfinx.simulation import stages
from silo_dolfinx.simulation.effects import SmoothRamp
from silo_dolfinx.solver import ExplicitSolver, Numerics, VelocityConstraint


class SiloModel:
    """A scene's silo on the explicit solver: walls, gate, axis, loads, layers, stages."""

    def __init__(self, scene, sm: SiloMesh):
        self.scene = scene
        self.material = make_material(scene.material)
        self.solver = ExplicitSolver(sm.mesh, self.material, Numerics.from_scene(scene), gravity=scene.loads.gravity)
        self._attach(sm)
        self.hooks: list = []  # post-step hooks (before_step / after_step): the point history, ALE
        self.ale = None  # the discharge's ALE, once it runs
        self.outputs = None  # output streams (simulation.run sets them)
        self.effects = fx.compose(self)
        self.stages = stages.compose(scene)
        # the discharge's rezoning, if the scene asks for it (silo_dolfinx.ale.rezone)
        self.rezoner = Rezoner(self) if Rezoner.wanted(scene) else None
        # below it a cell is stress-free and its q/p undefined (output)
        self.p_stress_free = stress_free_pressure(scene.material.density, scene.loads.gravity, self.outline.fill_height)

    def _attach(self, sm: SiloMesh) -> None:
        """What the model takes from its mesh: node sets, the axis constraint, the wall."""
        s = self.solver
        self.sm, self.outline = sm, sm.outline
        owned = lambda nodes: nodes[s.node_dof[nodes] < s.n_owned]  # noqa: E731
        self.wall_nodes = owned(sm.nodes_on("wall"))
        self.outlet_nodes = owned(sm.nodes_on("outlet"))
        self.axis_dofs = s.node_dof[sm.nodes_on("axis")]
        self.outlet_dofs_all = s.node_dof[sm.nodes_on("outlet")]
        s.constraints.append(VelocityConstraint(self.axis_dofs, 0))
        self.contact_wall_open = self.outline.contact_wall()
        self.__dict__.pop("_area_form", None)  # wall_state's, on the old mesh

    def move_to(self, sm: SiloMesh) -> None:
        """Go on discharging on another mesh of the material (a rezone: the caller carries the
        state over, :mod:`silo_dolfinx.ale.rezone`): the solver and every effect are built
        again on ``sm`` and put where the discharge has them - full gravity (and surcharge) on
        every cell, the gate open, the outlet driven from its opening time. ALE, outputs and
        state are the caller's."""
        drive = self.effects.get("outlet_drive")
        self.solver.move_to(sm.mesh)
        self._attach(sm)
        self.effects = fx.compose(self)
        s = self.solver
        self.effects["gravity"].load(s.active_cells, None, SmoothRamp(s.t, 0.0))
        if "surcharge" in self.effects:
            self.effects["surcharge"].load(SmoothRamp(s.t, 0.0))
        self.effects["gate"].remove()
        if drive is not None and drive.t0 is not None:
            self.effects["outlet_drive"].drive(drive.t0)

    # ------------------------------------------------------------------ effects
    @property
    def contact(self):
        """The wall's contact set (its forces and slip are the wall output)."""
        return self.wall.contact

    @property
    def damping_alpha(self) -> float:
        """α (1/s) of the fill damping in the stages that declare ``damped`` (0: no damping)."""
        d = self.effects.get("damping")
        return d.alpha if d is not None else 0.0

    fill_damping = damping_alpha

    def open_outlet(self) -> None:
        """Remove the gate (free discharge) or start driving the outlet (controlled): what the
        discharge stage's begin does to the outlet, for tests that step the solver themselves."""
        opening = stages.Stage("discharge", 0.0)
        for name in ("gate", "outlet_drive"):
            if name in self.effects:
                self.effects[name].begin(opening)

    def remove_gate(self) -> None:
        """Remove the gate (an open outlet) and take nodes with a prescribed velocity out of
        contact (tests and benchmarks that drive the outlet themselves)."""
        self.effects["gate"].remove()
        for c in self.solver.constraints:
            if c.value is not None:
                for contact in self.solver.contacts:
                    contact.exclude(c.dofs)

    def after_remap(self) -> None:
        """The mesh and the mass changed (ALE remap): every effect that depends on them."""
        for effect in self.effects.values():
            effect.after_remap()

    # ------------------------------------------------------------------ layers and initial state
    def layers(self) -> list[np.ndarray]:
        """Owned cells of each filling layer, bottom first (by initial centroid height; the
        mesher makes the layer tops mesh lines, so each layer is a full horizontal slab)."""
        from silo_dolfinx.geometry.quality import cell_corners

        n = self.scene.fill.layers if self.scene.fill.method == "layers" else 1
        zc = cell_corners(self.sm.mesh)[:, :, 1].mean(axis=1)
        k = np.minimum((zc / self.outline.fill_height * n).astype(int), n - 1)
        return [np.nonzero(k == i)[0].astype(np.int32) for i in range(n)]

    def activate(self, cells: np.ndarray, new_cells: np.ndarray | None, t0: float, ramp_time: float,
                 last: bool) -> None:
        """Integrate over ``cells``; ramp the gravity of ``new_cells`` from t0 (others: full);
        with the ``last`` layer, the surcharge (if any) ramps in too."""
        s = self.solver
        s.set_active_cells(cells)
        s.loads.clear()
        amp = SmoothRamp(t0, ramp_time)
        self.effects["gravity"].load(cells, new_cells, amp)
        if last and "surcharge" in self.effects:
            self.effects["surcharge"].load(amp)

    def set_geostatic_stress(self, k0: float) -> None:
        """σ_zz = −(ρ g (H − z) + q), σ_rr = σ_θθ = k0 σ_zz at every quadrature point."""
        s = self.solver
        xq = s.quadrature_points()
        rho, g, H = self.material.density, s.gravity, self.outline.fill_height
        szz = -(rho * g * (H - xq[:, 1]) + self.scene.loads.top_surcharge)
        s.sig[:, 0] = k0 * szz
        s.sig[:, 1] = szz
        s.sig[:, 2] = k0 * szz
        s.sig[:, 3] = 0.0
        m = s.material
        if m.plastic:  # a K0 state outside the yield surface is first returned onto it (no dissipation booked)
            out = np.empty_like(s.sig)
            state = {k: a.copy() for k, a in s.state.items()}
            m.rate_independent.update(s.sig.copy(), np.zeros_like(s.sig), s.state, out, state, s.dV)
            s.sig[:] = out
        s.refresh_force()
        # stored without any work done on it: the energy balance starts from it
        s.energy.initial = s.material.elastic_energy(s.sig, s.dV)  # this rank's share (summed globally)

    # ------------------------------------------------------------------ wall output
    def wall_state(self, interval_mean: bool = False) -> dict[str, np.ndarray] | None:
        """Per wall node (gathered on rank 0, sorted by arclength): s, r, z, p_n, p_s, slip —
        of the last step, or (``interval_mean``) their means since the last such call
        (:meth:`~silo_dolfinx.contact.WallContact.interval_means`, which starts the next)."""
        from dolfinx import fem, la

        s, c = self.solver, self.contact
        if not hasattr(self, "_area_form"):
            self._area_form = s.forms.tributary_area_form(self.sm.facet_tags, FACET_TAGS["wall"])
            self._area = la.vector(s.V.dofmap.index_map, 2)
        self._area.array[:] = 0.0
        fem.assemble_vector(self._area.array, self._area_form)
        self._area.scatter_reverse(la.InsertMode.add)
        area = self._area.array.reshape(-1, 2)[c.dofs, 0]
        on_wall = area > 0
        x = self.sm.mesh.geometry.x[c.nodes]
        a = np.where(on_wall, area, 1.0)
        N, T, slip = c.interval_means() if interval_mean else (c.normal_force, c.shear_force, c.slip_velocity)
        cols = np.column_stack([c.s, x[:, 0], x[:, 1], N / a, T / a, slip, c.in_contact.astype(float)])[on_wall]
        parts = self.sm.comm.gather(cols, root=0)
        if parts is None:
            return None
        allc = np.concatenate(parts)
        allc = allc[np.argsort(allc[:, 0])]
        return dict(zip(("s", "r", "z", "p_n", "p_s", "slip_velocity", "in_contact"), allc.T))
