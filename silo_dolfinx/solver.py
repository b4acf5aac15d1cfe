"""The explicit Lagrangian step: central differences on a lumped mass (thesis ch. 3.3).

One step from t_n to t_{n+1} = t_n + Δt (eqs. 3-7 to 3-9), as in the thesis' Fig. 3-3:

1. **predict**: a^n = M⁻¹ (f_ext^n − f_int^n − C v^{n−½}); v^{n+½} = v^{n−½} + Δt̄ a^n with
   Δt̄ = ½(Δt_{n−½} + Δt_{n+½});
2. **contact**: fixed velocity components by index (axis, rollers); kinematic wall contact
   corrects v^{n+½} of the wall nodes; prescribed velocities are imposed last (they win);
3. **update**: x^{n+1} = x^n + Δt v^{n+½} (the mesh moves with the material); strain rate and
   spin at the mid-step configuration; Jaumann rotation; material update; density;
4. **internal force** f_int^{n+1} = ∫ σ̃ : ε_axi(w) 2π r dx on x^{n+1} (one compiled form,
   coefficients pre-packed by the stress kernel);
5. **stable Δt** from x^{n+1}: Δt_{n+3/2} = scale × min_e Δt_e. If the step just taken was
   longer than the new configuration allows (by more than 5 %), it is **rejected** and
   repeated with the new Δt (Laghos' policy), never silently kept.

The smoothing and remap of ALE (every N steps) act on the accepted state between steps
(:mod:`silo_dolfinx.ale`). A blow-up guard (non-finite values, kinetic energy or energy
balance out of bounds) stops the run with a clear message before anything non-finite is
written.

Energy bookkeeping (J, full 360°), all centred at t_{n+½}: kinetic ½ Σ M |v^{n+½}|²;
elastic energy from the stress (mean of t_n and t_{n+1}); plastic dissipation from the
return map; bulk-viscous and damping dissipation; external work (gravity, surcharge,
prescribed velocities, contact) as W += F^n · ½(Δx^{n−½} + Δx^{n+½}). The balance
B = KE + E_el + D_p + D_visc + D_damp − W_ext should stay near its initial value. An ALE
remap moves energy out of the mesh (what the discharged material carries: ``outflow``) and
dissipates some (upwinding: ``remap``); both are booked so that B stays meaningful.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from silo_dolfinx._jit_cache import numba
from silo_dolfinx import kernels
from silo_dolfinx._mpi import reduce_scalar
from silo_dolfinx.forms import AxisymmetricForms
from silo_dolfinx.geometry.cells import CYCLE, orientation, tensor_nodes
from silo_dolfinx.materials.base import Material
from silo_dolfinx.state import Energy, NodalData, QuadratureData

REJECT_TOLERANCE = 0.05
EMPTIED = 0.25  # a cell below this fraction of the solid's density has emptied (Δt diagnosis)


class InstabilityError(RuntimeError):
    """The explicit integration has become unstable (the message says why and what to change)."""


@dataclass
class Numerics:
    time_step_scale: float = 0.8
    bulk_viscosity: tuple[float, float] = (0.06, 1.2)
    mass_scaling: float = 1.0
    bbar: bool = True
    damping: float = 0.0  # initial mass-proportional damping α (1/s), f = −α M v; stages declare theirs
    min_time_step_fraction: float = 0.0  # stop when the stable Δt falls below this × its reference (0: never)
    integration: str = "full"  # "full": 2 × 2 points; "reduced": one point + hourglass control
    hourglass: tuple[float, float] = (0.0, 0.1)  # (κ_s, κ_v) of the hourglass control (reduced only)

    @classmethod
    def from_scene(cls, scene) -> Numerics:
        n = scene.numerics
        return cls(n.time_step_scale, tuple(n.bulk_viscosity), n.mass_scaling,
                   min_time_step_fraction=n.min_time_step_fraction, integration=n.integration,
                   hourglass=(n.hourglass_stiffness, n.hourglass_viscosity))

    @property
    def hourglass_control(self) -> bool:
        return self.integration == "reduced" and any(k > 0.0 for k in self.hourglass)


@dataclass
class VelocityConstraint:
    """Velocity component ``comp`` of the nodes ``dofs`` is ``value(t)`` (0 if None)."""

    dofs: np.ndarray
    comp: int
    value: Callable[[float], float] | None = None


def full(t: float) -> float:
    """The amplitude of a load that is on in full (a module function: loads are checkpointed)."""
    return 1.0


@dataclass
class LoadGroup:
    """A nodal force (block array) times an amplitude a(t) (data or a module function, not a
    closure, for a run that writes checkpoints: :class:`silo_dolfinx.simulation.effects.SmoothRamp`)."""

    force: np.ndarray
    amplitude: Callable[[float], float]
    kind: str = "gravity"


class ExplicitSolver:
    """Central-difference dynamics of an axisymmetric solid on a moving mesh.

    State lives in three structs (:mod:`silo_dolfinx.state`): ``q`` (quadrature data,
    double-buffered), ``nodes`` (lumped mass and nodal vectors) and ``energy`` (the ledger).
    The scene's effects attach themselves as ``loads``, ``constraints`` and ``contacts``; a
    post-step ``hook`` (ALE) may ask the step to skip its internal force (``defer_force``)."""

    # what a checkpoint keeps (silo_dolfinx.checkpoint): every number the next step reads
    CHECKPOINT = ("t", "steps", "rejected", "dt_prev", "dt", "dt_crit", "_dt_crit0", "dt_reference", "_increment",
                  "energy_scale", "damping", "defer_force", "_force_stale", "energy", "nodes", "q", "f_int", "loads")

    def __init__(self, mesh, material: Material, numerics: Numerics | None = None, *, gravity: float = 0.0):
        from dolfinx import la

        self.mesh, self.comm, self.material = mesh, mesh.comm, material
        self.numerics = numerics or Numerics()
        self.gravity = gravity
        self.damping = self.numerics.damping  # α (1/s): the current stage's declared value
        self.forms = AxisymmetricForms(mesh, self.numerics.integration)
        self.V = self.forms.V
        imap = self.V.dofmap.index_map
        self.n_owned, self.n_nodes = imap.size_local, imap.size_local + imap.num_ghosts
        self.nq = self.forms.nq
        self._strain_path = (kernels.mean_gradients_q1 if self.nq == 1 else kernels.gradients_q1,
                             self.forms.points)  # chosen once
        # the quadrature fields: the law's declared state, and the stored hourglass force
        self._hourglass_law = (material.wave_modulus, *map(float, self.numerics.hourglass), *material.strength)
        self._hourglass_on = self.numerics.hourglass_control  # (asked every step: kept, not re-derived)
        self.point_fields = dict(material.state_fields)
        if self._hourglass_on and self.numerics.hourglass[0] > 0.0:
            self.point_fields["hourglass"] = 2
        self.n_cells_owned = mesh.topology.index_map(mesh.topology.dim).size_local
        self._number_nodes(mesh)
        self.nodes = NodalData.allocate(self.forms.velocity.x.array.reshape(-1, 2))
        self._vvec = self.forms.velocity.x
        # internal force f_int^n and f_int^{n+1} in two la.Vectors (ghosts accumulate), swapped on commit
        self._fvec, self._fvec_new = la.vector(imap, 2), la.vector(imap, 2)
        self._mass_vec = la.vector(imap, 1)  # the lumped mass, assembled in place
        self.x = mesh.geometry.x  # the node positions: a view of DOLFINx's own array (moved in place)
        self.x0 = mesh.geometry.x.copy()
        self._x_old = mesh.geometry.x.copy()
        self.defer_force = False  # skip this step's internal force (a remap rebuilds it)
        self._force_stale = False  # a deferred force not yet rebuilt: assembled before use
        self.constraints: list[VelocityConstraint] = []
        self.contacts = []
        self.loads: list[LoadGroup] = []
        self.energy = Energy()
        self.energy_scale = 0.0
        self.t, self.steps, self.rejected = 0.0, 0, 0
        self.dt_prev, self.dt, self.dt_crit = 0.0, 0.0, math.inf
        self._dt_crit0 = math.inf  # the stable Δt at the last rebuild (collapse guard)
        self.dt_reference = 0.0  # the stable Δt at the last activation ([numerics] min_time_step_fraction)
        self._increment = (0.0, 0.0, 0.0, 0.0)  # (plastic, viscous, internal work, hourglass) of the last step
        self._active = None
        self.timings: dict[str, float] = {}
        self._clock = _no_clock
        self.set_active_cells(np.arange(self.n_cells_owned, dtype=np.int32))

    #: what carries over when the solver moves to another mesh (:meth:`move_to`): clocks, Δt
    #: history, the energy ledger, the stage's damping
    CARRIED = ("t", "steps", "rejected", "dt_prev", "dt", "dt_reference", "_increment", "energy", "energy_scale",
               "damping", "timings", "_clock")

    def move_to(self, mesh) -> None:
        """Continue on another mesh of the same material (a rezone, :mod:`silo_dolfinx.ale.rezone`):
        everything built on the mesh is built again on ``mesh`` - forms, node numbering, nodal and
        quadrature arrays, all cells active - and what :attr:`CARRIED` names is kept. Loads,
        constraints and contacts start empty (the model adds its own again); the caller then
        fills ``sig``, ``state``, ``rho`` and ``v`` and calls :meth:`after_remap`. The
        displacement output starts again from the new mesh."""
        kept = {k: getattr(self, k) for k in self.CARRIED}
        self.__init__(mesh, self.material, self.numerics, gravity=self.gravity)
        for k, v in kept.items():
            setattr(self, k, v)

    def _number_nodes(self, mesh) -> None:
        """node <-> dof maps (Q1 geometry: one geometry node per vertex, same local order)."""
        gdm = tensor_nodes(mesh)
        self.cell_tensor = gdm
        self.cell_nodes = np.ascontiguousarray(gdm[:, CYCLE])  # boundary cycle
        self.cell_orientation = orientation(mesh.geometry.x, self.cell_nodes)  # of the valid initial mesh
        self.node_dof = np.empty(mesh.geometry.x.shape[0], np.int64)
        self.node_dof[gdm.ravel()] = self.V.dofmap.list.ravel()
        self.dof_node = np.empty(self.n_nodes, np.int64)
        self.dof_node[self.node_dof] = np.arange(self.node_dof.size)

    def profile(self, on: bool = True) -> None:
        """Accumulate wall-clock seconds per phase of the step in ``timings`` (benchmarks)."""
        self.timings = {k: 0.0 for k in ("update", "strain", "constitutive", "dt", "assembly")}
        self._clock = _Clock(self.timings) if on else _no_clock

    # ------------------------------------------------------------------ views on the structs
    v = property(lambda self: self.nodes.v)
    mass = property(lambda self: self.nodes.mass)
    m_inertial = property(lambda self: self.nodes.m_inertial)
    minv = property(lambda self: self.nodes.minv)
    sig = property(lambda self: self.q.now.sig)
    state = property(lambda self: self.q.now.state)
    rho = property(lambda self: self.q.now.rho)
    dV = property(lambda self: self.q.dV)
    rho_cell = property(lambda self: self.q.cells.rho)
    f_int = property(lambda self: self._fvec.array.reshape(-1, 2))
    active_cells = property(lambda self: self._active)
    active_cell_nodes = property(lambda self: self._active_nodes)

    # ------------------------------------------------------------------ active cells (layers)
    def set_active_cells(self, cells: np.ndarray, *, keep_state: bool = True) -> None:
        """Integrate over ``cells`` only (owned, sorted); state of cells already active is kept."""
        cells = np.asarray(np.sort(cells), np.int32)
        old, old_q = self._active, getattr(self, "q", None)
        self.q = QuadratureData.allocate(cells.size, self.nq, self.point_fields, self.material.density)
        if old is not None and keep_state:
            kept = np.isin(old, cells)  # cells that stay active keep their state
            pos = np.searchsorted(cells, old[kept])
            fields = self.point_fields
            for (_, a_new), (_, a_old) in zip(self.q.now.arrays(self.nq, fields), old_q.now.arrays(self.nq, fields)):
                a_new[pos] = a_old[kept]
        self._active = cells
        self.force_form, key = self.forms.internal_force(cells)
        self._mass_form = self.forms.mass_form(cells)
        self._coeffs = {key: self.q.packed}
        self._active_nodes = np.ascontiguousarray(self.cell_nodes[cells])
        self._active_tensor = np.ascontiguousarray(self.cell_tensor[cells])
        self._no_hourglass = np.zeros((cells.size, 2))
        self._active_orientation = np.ascontiguousarray(self.cell_orientation[cells])
        self._update_stable_dt()
        self.dt_reference = self.dt_crit  # what Δt may fall from: a remap does not reset it
        self.rebuild_mass()
        self.refresh_force()

    def rebuild_mass(self) -> None:
        """Lumped mass from the current densities (after activation or a remap)."""
        n = self.nodes
        m = self.forms.lumped_mass(self.rho.reshape(-1, self.nq), self._active, self._mass_form, out=self._mass_vec)
        n.mass[:] = m
        np.multiply(m, self.numerics.mass_scaling, out=n.m_inertial)
        n.minv[:] = 0.0
        np.divide(1.0, n.m_inertial, out=n.minv, where=m > 0.0)
        np.greater(m, 0.0, out=n.active)

    def nodal_mass_of(self, cells: np.ndarray) -> np.ndarray:
        """Lumped mass of a subset of the active cells (e.g. one layer), per node."""
        pos = np.searchsorted(self._active, cells)
        return self.forms.lumped_mass(self.rho.reshape(-1, self.nq)[pos], cells)

    # ------------------------------------------------------------------ loads
    def add_gravity(self, cells: np.ndarray | None = None, amplitude: Callable[[float], float] = full):
        """Gravity −g ẑ on the mass of ``cells`` (default: all active), scaled by amplitude(t)."""
        m = self.mass if cells is None else self.nodal_mass_of(cells)
        f = np.zeros((self.n_nodes, 2))
        f[:, 1] = -self.gravity * m
        self.loads.append(LoadGroup(f, amplitude, "gravity"))

    def add_nodal_force(self, force: np.ndarray, amplitude: Callable[[float], float], kind: str = "surcharge"):
        self.loads.append(LoadGroup(np.asarray(force).reshape(-1, 2), amplitude, kind))

    def replace_gravity(self) -> None:
        """One full-gravity load on the current lumped mass in place of all gravity loads
        (after a remap changed the mass; only once every gravity ramp has ended)."""
        if any(g.kind == "gravity" and g.amplitude(self.t) != 1.0 for g in self.loads):
            raise RuntimeError("replace_gravity during a gravity ramp")
        self.loads = [g for g in self.loads if g.kind != "gravity"]
        self.add_gravity()

    # ------------------------------------------------------------------ the step (thesis Fig. 3-3)
    def step(self) -> float:
        """Advance one accepted step; returns its Δt. Laghos' policy: a step longer than the
        configuration it produced allows is rejected and repeated with the new Δt."""
        while True:
            dt = self.dt
            t_mid, dt_avg = self.t + 0.5 * dt, (0.5 * (self.dt_prev + dt) if self.dt_prev > 0.0 else 0.5 * dt)
            self._clock(None)
            self._predict(dt_avg)                                # 1. a^n, v^{n+½}
            self._constrain(dt, dt_avg, t_mid)                   # 2. axis, contact, prescribed v
            d_plastic = self._update_quadrature_data(dt)         # 3. x^{n+1}, ε̇, Jaumann, law, ρ
            dt_crit = self._stable_dt()                          # 5. Δt of the new configuration
            if dt <= self.numerics.time_step_scale * dt_crit * (1.0 + REJECT_TOLERANCE):
                break
            self._reject(dt_crit)
        w_int, w_visc, w_hg = self._internal_force(dt)           # 4. f_int^{n+1}
        self._book_energy(dt, dt_avg, d_plastic, (w_visc, w_int, w_hg))
        self._commit(dt, dt_crit)
        return dt

    def _predict(self, dt_avg: float) -> None:
        """a^n = M⁻¹ (f_ext^n − f_int^n − α M v^{n−½}); v^{n+½} = v^{n−½} + Δt̄ a^n."""
        n = self.nodes
        if self._force_stale:  # a deferred internal force that no remap rebuilt
            self._assemble_internal_force(self._fvec)
            self._force_stale = False
        n.f_ext[:] = 0.0
        for g in self.loads:
            a = g.amplitude(self.t)
            if a != 0.0:
                _axpy(a, g.force, n.f_ext)
        np.copyto(n.v_old, n.v)
        _predict(n.v, n.f_ext, self.f_int, n.minv, self.damping, dt_avg, n.a)

    def _constrain(self, dt: float, dt_avg: float, t_mid: float) -> None:
        """Fixed components (axis, rollers) first, then contact; prescribed velocities win."""
        v = self.nodes.v
        for c in self.constraints:
            if c.value is None:
                v[c.dofs, c.comp] = 0.0
        for contact in self.contacts:
            contact.apply(self.x, v, self.nodes.m_inertial, dt, dt_avg)
        for c in self.constraints:
            v[c.dofs, c.comp] = 0.0 if c.value is None else c.value(t_mid)
        self._vvec.scatter_forward()
        self._clock("update")

    def _update_quadrature_data(self, dt: float) -> float:
        """Mid-step kinematics, end configuration, Jaumann rotation, the law, the density;
        returns the plastic dissipation (J). Fills ``q.new`` (Laghos' UpdateQuadratureData)."""
        x, q, num = self.x, self.q, self.numerics
        np.copyto(self._x_old, x)
        _move(x, self._x_old, self.nodes.v, self.node_dof, 0.5 * dt)
        self._velocity_gradient()
        kernels.kinematics(q.kin, self.forms.weights, dt, num.bbar, q.kinematics_out())
        _move(x, self._x_old, self.nodes.v, self.node_dof, dt)
        kernels.rotate(q.now.sig, q.spin, q.sig_rot)
        self._clock("strain")
        d_plastic = self.material.update(q.sig_rot, q.deps, q.now.state, q.new.sig, q.new.state, q.dV, dt)
        kernels.update_density(q.now.rho, q.dvol, dt, self.nq, num.bbar, q.new.rho)
        kernels.cell_average(q.new.rho, q.dV, self.nq, q.cells.rho)
        self._clock("constitutive")
        return d_plastic

    def _velocity_gradient(self) -> None:
        """∂v/∂x, v_r/r and r|det J| at the quadrature points of the active cells (compiled);
        one point: their means over the cell's exact volume (the uniform-strain cell)."""
        gradients, points = self._strain_path
        gradients(self.x, self.nodes.v, self.node_dof, self._active_tensor, points, self.q.kin)

    def _stable_dt(self) -> float:
        """min over cells of the stable Δt of the current configuration (all ranks)."""
        num = self.numerics
        dt_local = self._cell_dt()
        dt_crit = reduce_scalar(self.comm, dt_local, MPI.MIN)
        self._clock("dt")
        if not (dt_crit > 1e-6 * self._dt_crit0 and math.isfinite(dt_crit)):
            message = self._collapse_message(dt_local, dt_crit)
            np.copyto(self.x, self._x_old)
            raise InstabilityError(message)
        if dt_crit < num.min_time_step_fraction * self.dt_reference:
            message = self._fall_message(dt_crit)
            np.copyto(self.x, self._x_old)  # the state of the last accepted step
            raise InstabilityError(message)
        return dt_crit

    def _fall_message(self, dt_crit: float) -> str:
        """Why Δt fell below [numerics] min_time_step_fraction of its reference: the cell that
        limits it (collective), and what to do about it."""
        cell = self.limiting_cell(refresh=False)  # the trial configuration's lengths and wave speeds
        rho_c, r, z = cell["density"], cell["r"], cell["z"]
        rho0 = self.material.density
        head = (f"the stable Δt fell to {dt_crit:.3g} s at t = {self.t:.6g} s, below [numerics] "
                f"min_time_step_fraction = {self.numerics.min_time_step_fraction:g} of its {self.dt_reference:.3g} s; "
                f"the cell that limits it is at r = {r:.3g} m, z = {z:.3g} m with density {rho_c:.4g} kg/m³ "
                f"({100 * rho_c / rho0:.0f} % of the solid's {rho0:g}). ")
        if rho_c < EMPTIED * rho0:
            why = ("It has emptied: the solid there is pulled apart (the wave speed of a cell grows as its density "
                   "falls). Over an outlet this is an arch - the solid above holds while the outlet drains the "
                   f"cells below it; {self._arch_advice()}")
        else:
            why = (f"It has not emptied: a cell is being crushed or distorted: {self._distortion_hint()} (Or lower "
                   "min_time_step_fraction to run on.)")
        return head + why

    def _arch_advice(self) -> str:
        """What holds an arch over an outlet in this run, and what to change: the yield surface
        unless it is already Mohr-Coulomb's pyramid, then the element (docs/validation/ch6.md)."""
        tail = "a wider outlet, or (to run on regardless) a smaller min_time_step_fraction."
        if self.material.name != "mohr_coulomb":
            return ("a cone matched in compression (material.cone, docs/material.md) carries equal-biaxial "
                    "compression with no cohesion once φ > 36.87°, and is much stronger in extension than a "
                    "Mohr-Coulomb solid, so such arches hold. Fix: material.model = \"mohr_coulomb\" (φ at every "
                    f"Lode angle) or material.cone = \"extension\" for a discharge, {tail}")
        if self.numerics.integration == "full":
            return ("on Mohr-Coulomb's pyramid it is the element that holds it: a cell integrated at 2 × 2 "
                    "points resists the shearing and dilating patterns the collapse over an outlet needs (the "
                    "ch. 6 silo's arched over 2 cells across its outlet radius, and over 4 and 8 on an unstructured "
                    "mesh; docs/validation/ch6.md). Fix: numerics.integration = \"reduced\" (one point, the "
                    f"thesis' CAX4R), {tail}")
        return f"it holds even on Mohr-Coulomb's pyramid with one-point cells. Fix: {tail}"

    def limiting_cell(self, refresh: bool = True) -> dict[str, float]:
        """Collective: the active cell with the smallest stable Δt - where it is (centroid r, z),
        its characteristic length, density and stable Δt (s, before time_step_scale, with the
        bulk viscosity's reduction as the step computes it); NaN if no cell is active.
        ``refresh``: re-evaluate the lengths and wave speeds at the current configuration first."""
        collapsed = refresh and self._cell_dt() <= 0.0  # a collapsed cell: its length is not defined
        if self.comm.allreduce(collapsed, op=MPI.LOR):  # (decided together: the gather below is collective)
            return dict.fromkeys(("r", "z", "length", "density", "dt"), float("nan"))
        _, L, _, rho = cells = self.q.cells.arrays
        dt = np.empty(L.size)
        kernels.cell_dts(cells, self.numerics.bulk_viscosity, dt)
        i = int(np.argmin(dt)) if dt.size else -1
        mine = (np.inf, np.nan, np.nan, np.nan, np.nan)
        if i >= 0:
            r, z = self.mesh.geometry.x[self._active_nodes[i], :2].mean(axis=0)
            mine = (float(dt[i]), float(r), float(z), float(L[i]), float(rho[i]))
        dt_c, r, z, L_c, rho_c = min(self.comm.allgather(mine))
        return {"r": r, "z": z, "length": L_c, "density": rho_c, "dt": dt_c if np.isfinite(dt_c) else float("nan")}

    def _cell_dt(self) -> float:
        """This rank's smallest stable Δt of the current configuration; −(c + 1) if active cell c
        has collapsed or inverted (see :func:`kernels.stable_dt`)."""
        num = self.numerics
        return kernels.stable_dt(self.x, self._active_nodes, self._active_orientation,
                                 self.q.cells.arrays, self.material.wave_modulus, num.bulk_viscosity,
                                 num.mass_scaling, kernels.HOOP)

    def _collapse_message(self, dt_local: float, dt_crit: float) -> str:
        """Collective: where the mesh collapsed or inverted, and what to do."""
        where = None
        if dt_local <= 0.0 and self._active.size:
            c = int(-dt_local) - 1
            where = tuple(float(v) for v in self.mesh.geometry.x[self._active_nodes[c], :2].mean(axis=0))
        where = next((w for w in self.comm.allgather(where) if w is not None), None)
        if where is not None:
            return (f"a cell inverted at step {self.steps} (t = {self.t:.6g} s), near r = {where[0]:.3g} m, z = "
                    f"{where[1]:.3g} m: a corner turned inside out (the step is not kept; the results up to the "
                    f"last sample stand): {self._distortion_hint()}")
        return (f"an element collapsed at step {self.steps} (t = {self.t:.6g} s; stable Δt fell from "
                f"{self._dt_crit0:.3g} to {dt_crit:.3g} s): {self._distortion_hint()}")

    def _distortion_hint(self) -> str:
        scale = self.numerics.time_step_scale
        return (f"[numerics] time_step_scale = {scale:g} exceeds the stability limit: use 0.9 or less."
                if scale > 0.9 else "the mesh is tangled by large deformation: enable [ale] or smooth more often "
                "(ale.frequency), or refine where it distorts.")

    def _reject(self, dt_crit: float) -> None:
        """Undo the trial step (x, v of t_n) and retry with the Δt the new configuration allows."""
        np.copyto(self.x, self._x_old)
        np.copyto(self.nodes.v, self.nodes.v_old)
        self.dt = self.numerics.time_step_scale * dt_crit
        self.rejected += 1

    def _internal_force(self, dt: float) -> tuple[float, float]:
        """Force stress into the form's coefficients, then f_int^{n+1} by one compiled
        assembly (skipped if ``defer_force``: the remap that follows rebuilds it)."""
        num, q = self.numerics, self.q
        w_int, w_visc = kernels.closure(q.force_in(q.sig_rot, q.new), q.cells.arrays, num.bulk_viscosity, num.bbar,
                                        q.packed)
        w_hg, vec = 0.0, self._fvec_new
        if self._hourglass_on:  # Q of the hourglass modes from v^{n+½} on x^{n+1}, and their forces
            vec.array[:] = 0.0
            w_hg = kernels.hourglass_update(self.x, self.nodes.v, self.node_dof, self._active_tensor,
                                            (q.cells.rho, q.new.sig), self._hourglass_law, dt,
                                            (self._hourglass_stored(q.now), self._hourglass_stored(q.new),
                                             q.hourglass_viscous, vec.array.reshape(-1, 2)))
        if not self.defer_force:
            self._assemble_internal_force(vec, hourglass=not self._hourglass_on)
        self._clock("assembly")
        return w_int, w_visc, w_hg

    def _hourglass_stored(self, level) -> np.ndarray:
        """The stored (stiffness) hourglass force Q_s of a time level, (n_cells, 2); without the
        stiffness form one shared zero array for both levels (κ_s = 0 writes zeros into it)."""
        return level.state["hourglass"] if "hourglass" in level.state else self._no_hourglass

    def _book_energy(self, dt: float, dt_avg: float, d_plastic: float, work: tuple[float, float, float]) -> None:
        """Forces of step n acting over ½(Δx^{n−½} + Δx^{n+½}), into the ledger; ``work`` =
        (bulk-viscous, stress power, hourglass) of the step (J)."""
        n, e, own = self.nodes, self.energy, self.n_owned
        w_visc, w_int, w_hg = work
        w_ext, w_corr, w_damp = _work(n.work_in(), dt, dt_avg, self.damping, own)
        for g in self.loads:
            if g.kind == "gravity":
                e.gravity += g.amplitude(self.t) * _dot(g.force, n.span, own)
        e.external += w_ext + w_corr
        e.contact += w_corr
        e.damping += w_damp
        e.plastic += d_plastic
        e.viscous += w_visc
        e.internal_work += w_int
        e.hourglass += w_hg
        self._increment = (d_plastic, w_visc, w_int, w_hg)

    def _commit(self, dt: float, dt_crit: float) -> None:
        """t_{n+1} becomes t_n: swap the double buffers, advance time, take the next Δt."""
        self.q.swap()
        self._fvec, self._fvec_new = self._fvec_new, self._fvec
        for contact in self.contacts:  # the accepted step's forces join the history's interval
            contact.accept(dt)
        self.t += dt
        self.steps += 1
        self.dt_prev = dt
        self.dt_crit = dt_crit
        self.dt = self.numerics.time_step_scale * dt_crit
        self._force_stale = self.defer_force
        self._clock("update")

    # ------------------------------------------------------------------ rebuilds (start, activation, remap)
    def _update_stable_dt(self) -> None:
        """Stable Δt of the current configuration (after activation or a remap moved the mesh)."""
        num = self.numerics
        dt_local = self._cell_dt()
        dt_crit = reduce_scalar(self.comm, dt_local, MPI.MIN)
        if not (dt_crit > 0.0 and math.isfinite(dt_crit)):
            raise InstabilityError(self._collapse_message(dt_local, dt_crit))
        self.dt_crit = self._dt_crit0 = dt_crit
        if self.dt == 0.0:
            self.dt = num.time_step_scale * self.dt_crit

    def _assemble_internal_force(self, vec, hourglass: bool = True) -> None:
        """f_int = ∫ σ̃ : ε_axi(w) 2π r dx (the compiled form) + the hourglass forces of t_n,
        ghost contributions accumulated. ``hourglass=False``: the step's hourglass update has
        just put this step's hourglass forces into ``vec`` (zeroed before it), the form adds to them."""
        from dolfinx import fem, la

        if hourglass:
            vec.array[:] = 0.0
            if self._hourglass_on:
                kernels.hourglass_force(self.x, self.node_dof, self._active_tensor,
                                        (self._hourglass_stored(self.q.now), self.q.hourglass_viscous),
                                        vec.array.reshape(-1, 2))
        fem.assemble_vector(vec.array, self.force_form, constants=np.zeros(0), coeffs=self._coeffs)
        vec.scatter_reverse(la.InsertMode.add)

    def refresh_force(self) -> None:
        """Internal force and volumes from the stored stress at rest (start, activation, remap)."""
        q, num = self.q, self.numerics
        self._velocity_gradient()
        kernels.kinematics(q.kin, self.forms.weights, 0.0, num.bbar, q.kinematics_out())
        kernels.cell_average(q.now.rho, q.dV, self.nq, q.cells.rho)
        kernels.closure(q.force_in(q.now.sig, q.now), q.cells.arrays, (0.0, 0.0), num.bbar, q.packed)
        self._assemble_internal_force(self._fvec)
        self._force_stale = False

    def after_remap(self, dV: np.ndarray, sig_increment: np.ndarray | None = None) -> tuple[float, float]:
        """The mesh moved and ``sig``, ``state``, ``rho`` and ``v`` were remapped onto it:
        rebuild what depends on them (volumes, lumped mass, stable Δt, internal force).

        ``v`` must hold its owners' values on the ghost rows (the remapped velocity does).
        ``dV``: the quadrature-point volumes on the new mesh (the remap computed them; all
        cells are active in a discharge). The cell dilatation rate of the bulk viscosity
        keeps its value from the last Lagrangian step.

        ``sig_increment``: σ^{n+1} − σ^n of the last step at each point before the remap.
        The energy record is centred at t_{n+½}, the elastic part as the mean over σ^n and
        σ^{n+1}; the remapped σ^n is taken as the remapped σ^{n+1} minus that increment, so
        the first step after a remap books consistently (without it, half a step of stress
        power per remap shows up as balance error).

        Returns (seconds spent assembling an internal force that the last step deferred to
        this rebuild (:attr:`defer_force`): Lagrangian work, done here on the new mesh instead
        of on the old one, 0 if nothing was deferred; this rank's elastic energy as
        :meth:`mechanical_energy_local` counts it, taken in the same pass)."""
        num, q = self.numerics, self.q
        t_half = self.t - 0.5 * self.dt_prev  # where the staggered velocity lives
        for c in self.constraints:  # on owned and ghost dofs alike: ghosts stay consistent
            self.v[c.dofs, c.comp] = 0.0 if c.value is None else c.value(t_half)
        np.copyto(q.dV, dV)
        kernels.cell_average(q.now.rho, q.dV, self.nq, q.cells.rho)
        self._update_stable_dt()
        self.dt = num.time_step_scale * self.dt_crit
        self.rebuild_mass()
        kernels.closure(q.force_in(q.now.sig, q.now), q.cells.arrays, num.bulk_viscosity, num.bbar, q.packed)
        t0 = time.perf_counter()
        self._assemble_internal_force(self._fvec)
        deferred = time.perf_counter() - t0 if self._force_stale else 0.0
        self._force_stale = False
        if sig_increment is None:
            np.copyto(q.new.sig, q.now.sig)  # the "previous" stress of the energy average
            elastic = self.material.elastic_energy(q.now.sig, q.dV)
        else:
            elastic = self.material.elastic_energy_mean_from_increment(q.now.sig, sig_increment, q.dV, q.new.sig)
        np.multiply(self.v, self.dt_prev, out=self.nodes.dx_prev)
        return deferred, elastic

    # ------------------------------------------------------------------ diagnostics
    def global_energy(self) -> Energy:
        """The energy record at the last half step t_{n+½}, summed over ranks.

        The external work of step n spans x^{n−½} → x^{n+½} and pairs with the kinetic energy
        ½ M |v^{n+½}|²; the elastic energy and the dissipations, known at t_n and t_{n+1}, are
        taken at their mean. Every term is then centred at the same instant (second order)."""
        e = self.energy
        ke, el = self._kinetic_elastic_local()
        names = Energy.names()[2:]
        local = np.array([ke, el] + [getattr(e, k) for k in names])
        dp, dv, di, dh = self._increment
        local[2] -= 0.5 * dp
        local[3] -= 0.5 * dv
        local[8] -= 0.5 * di
        local[12] -= 0.5 * dh
        self.comm.Allreduce(MPI.IN_PLACE, local, op=MPI.SUM)  # (in place: it runs at the history rate)
        g = Energy(*local.tolist())
        self.energy_scale = max(self.energy_scale, g.scale)
        return g

    def _kinetic_elastic_local(self, increment: np.ndarray | None = None) -> tuple[float, float]:
        ke = self.kinetic_energy_local()
        if self.steps > 0:  # the previous stress is still in the double buffer
            return ke, self.material.elastic_energy_mean(self.q.now.sig, self.q.new.sig, self.q.dV, increment)
        if increment is not None:
            increment[:] = 0.0
        return ke, self.material.elastic_energy(self.q.now.sig, self.q.dV)

    def kinetic_energy_local(self) -> float:
        return _kinetic(self.nodes.m_inertial, self.nodes.v, self.n_owned)

    def mechanical_energy_local(self, increment: np.ndarray | None = None) -> float:
        """This rank's kinetic + elastic energy as :meth:`global_energy` counts them (J); with
        ``increment``, the last step's stress increment σ^{n+1} − σ^n is written into it."""
        return sum(self._kinetic_elastic_local(increment))

    def kinetic_energy_now(self) -> float:
        return self.comm.allreduce(self.kinetic_energy_local(), op=MPI.SUM)

    def check_finite(self) -> None:
        ok = bool(np.all(np.isfinite(self.v)) and np.all(np.isfinite(self.sig)))
        if not self.comm.allreduce(ok, op=MPI.LAND):
            raise InstabilityError(
                f"non-finite velocity or stress at step {self.steps} (t = {self.t:.6g} s): the explicit "
                f"integration is unstable. [numerics] time_step_scale = {self.numerics.time_step_scale:g} "
                "exceeds the stability limit; use 0.9 or less.")

    def displacement(self) -> np.ndarray:
        """Nodal displacement (block layout) from the geometry."""
        u = np.zeros_like(self.v)
        u[self.node_dof] = (self.mesh.geometry.x - self.x0)[:, :2]
        return u

    def quadrature_points(self) -> np.ndarray:
        """Current (r, z) of the active quadrature points, (n, 2), in state order."""
        from dolfinx import fem
        import ufl

        if not hasattr(self, "_xq_expr"):
            self._xq_expr = fem.Expression(ufl.SpatialCoordinate(self.mesh), self.forms.points)
        out = np.zeros((self._active.size, self.nq, 2))
        self._xq_expr.eval(self.mesh, self._active, out)
        return out.reshape(-1, 2)


# ---------------------------------------------------------------------------- helpers
def _no_clock(phase):
    return None


class _Clock:
    """clock(None) starts; clock(name) adds the time since the last call to timings[name]."""

    def __init__(self, timings):
        self.timings, self._now, self._t = timings, time.perf_counter, 0.0

    def __call__(self, phase):
        now = self._now()
        if phase is not None:
            self.timings[phase] += now - self._t
        self._t = now


@numba.njit(cache=True)
def _predict(v, f_ext, f_int, minv, alpha, dt_avg, a):
    for i in range(v.shape[0]):
        for k in range(2):
            a[i, k] = minv[i] * (f_ext[i, k] - f_int[i, k]) - alpha * v[i, k] * (minv[i] > 0.0)
            v[i, k] += dt_avg * a[i, k]


@numba.njit(cache=True, fastmath=kernels.FAST)
def _kinetic(m, v, n):
    e = 0.0
    for i in range(n):
        e += m[i] * (v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1])
    return 0.5 * e


@numba.njit(cache=True)
def _axpy(a, x, y):
    for i in range(x.shape[0]):
        y[i, 0] += a * x[i, 0]
        y[i, 1] += a * x[i, 1]


@numba.njit(cache=True)
def _dot(f, span, n):
    w = 0.0
    for i in range(n):
        w += f[i, 0] * span[i, 0] + f[i, 1] * span[i, 1]
    return w


@numba.njit(cache=True)
def _work(nodal, dt, dt_avg, alpha, n):
    """Work of step n over the owned nodes: external, constraint + contact (the velocity
    corrections as forces M Δv/Δt̄), and damping; updates Δx^{n−½} and the span buffer.
    nodal = (v, v_old, a, f_ext, m, dx_prev, span) (:meth:`NodalData.work_in`)."""
    v, v_old, a, f_ext, m, dx_prev, span = nodal
    w_ext = 0.0
    w_corr = 0.0
    w_damp = 0.0
    for i in range(n):
        for k in range(2):
            dx = v[i, k] * dt
            sp = 0.5 * (dx_prev[i, k] + dx)
            span[i, k] = sp
            dx_prev[i, k] = dx
            w_ext += f_ext[i, k] * sp
            w_corr += (m[i] * (v[i, k] - v_old[i, k]) / dt_avg - m[i] * a[i, k]) * sp
            if alpha > 0.0:
                w_damp += alpha * m[i] * v_old[i, k] * sp
    return w_ext, w_corr, w_damp


@numba.njit(cache=True)
def _move(x, x_old, v, node_dof, dt):
    for n in range(x.shape[0]):
        d = node_dof[n]
        x[n, 0] = x_old[n, 0] + dt * v[d, 0]
        x[n, 1] = x_old[n, 1] + dt * v[d, 1]


