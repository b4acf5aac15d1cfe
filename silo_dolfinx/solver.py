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

import numba
import numpy as np
from mpi4py import MPI

from silo_dolfinx import kernels
from silo_dolfinx._compat import geometry_dofmap
from silo_dolfinx._mpi import reduce_scalar
from silo_dolfinx.forms import AxisymmetricForms
from silo_dolfinx.geometry.quality import CYCLE
from silo_dolfinx.materials.base import Material

REJECT_TOLERANCE = 0.05


class InstabilityError(RuntimeError):
    """The explicit integration has become unstable (the message says why and what to change)."""


@dataclass
class Numerics:
    time_step_scale: float = 0.8
    bulk_viscosity: tuple[float, float] = (0.06, 1.2)
    mass_scaling: float = 1.0
    bbar: bool = True
    damping: float = 0.0  # mass-proportional damping coefficient α (1/s): f = −α M v

    @classmethod
    def from_scene(cls, scene) -> Numerics:
        n = scene.numerics
        return cls(n.time_step_scale, tuple(n.bulk_viscosity), n.mass_scaling)


@dataclass
class VelocityConstraint:
    """Velocity component ``comp`` of the nodes ``dofs`` is ``value(t)`` (0 if None)."""

    dofs: np.ndarray
    comp: int
    value: Callable[[float], float] | None = None


@dataclass
class Energy:
    kinetic: float = 0.0
    elastic: float = 0.0
    plastic: float = 0.0
    viscous: float = 0.0
    damping: float = 0.0
    external: float = 0.0
    gravity: float = 0.0
    contact: float = 0.0
    internal_work: float = 0.0  # stress power integrated (= elastic + plastic for small strains)
    remap: float = 0.0  # kinetic + elastic energy lost by ALE remaps (numerical dissipation)
    outflow: float = 0.0  # kinetic + elastic energy carried out through the outlet
    initial: float = 0.0  # energy stored in a prescribed initial state (a K0 stress field)

    @property
    def balance(self) -> float:
        return (self.kinetic + self.elastic + self.plastic + self.viscous + self.damping + self.remap
                + self.outflow - self.external - self.initial)

    @property
    def scale(self) -> float:
        return max(abs(self.external) + self.initial, self.kinetic + self.elastic + self.plastic, 1e-300)

    def relative_error(self, scale: float | None = None) -> float:
        """|balance| over the energy scale (default: this record's; the solver passes the
        largest scale reached so far, so that the quiet start does not inflate the ratio)."""
        return abs(self.balance) / max(self.scale if scale is None else scale, 1e-300)


@dataclass
class LoadGroup:
    """A nodal force (block array) times an amplitude a(t)."""

    force: np.ndarray
    amplitude: Callable[[float], float]
    kind: str = "gravity"


class ExplicitSolver:
    """Central-difference dynamics of an axisymmetric solid on a moving mesh."""

    def __init__(self, mesh, material: Material, numerics: Numerics | None = None, *, gravity: float = 0.0):
        self.mesh = mesh
        self.comm = mesh.comm
        self.material = material
        self.numerics = numerics or Numerics()
        self.gravity = gravity
        self.forms = AxisymmetricForms(mesh)
        V = self.forms.V
        self.V = V
        imap = V.dofmap.index_map
        self.n_owned = imap.size_local
        self.n_nodes = imap.size_local + imap.num_ghosts
        nq = self.forms.nq
        self.nq = nq
        tdim = mesh.topology.dim
        self.n_cells_owned = mesh.topology.index_map(tdim).size_local

        # node <-> dof maps (Q1 geometry: one geometry node per vertex, same local order)
        gdm = geometry_dofmap(mesh)
        vdm = V.dofmap.list
        self.cell_nodes = np.ascontiguousarray(gdm[:, CYCLE].astype(np.int64))  # boundary cycle
        self.node_dof = np.empty(mesh.geometry.x.shape[0], np.int64)
        self.node_dof[gdm.ravel()] = vdm.ravel()
        self.dof_node = np.empty(self.n_nodes, np.int64)
        self.dof_node[self.node_dof] = np.arange(self.node_dof.size)

        # nodal arrays (block layout (n_nodes, 2)); v lives in the velocity Function, the
        # internal forces in two la.Vectors (swapped on commit) so ghosts can be accumulated
        from dolfinx import la

        self._vvec = self.forms.velocity.x
        self.v = self._vvec.array.reshape(-1, 2)
        self._v_old = np.zeros_like(self.v)
        self.a = np.zeros_like(self.v)
        self._fvec = la.vector(imap, 2)
        self._fvec_new = la.vector(imap, 2)
        self.f_int = self._fvec.array.reshape(-1, 2)
        # a remap follows this step (set by the ALE driver): its rebuild assembles the internal
        # force on the new mesh, so the step skips its own (stale until then: checked below)
        self.defer_force = False
        self._force_stale = False
        self._f_new = self._fvec_new.array.reshape(-1, 2)
        self.f_ext = np.zeros_like(self.v)
        self._f_prev = np.zeros_like(self.v)  # total force of the previous step (for work)
        self._dx_prev = np.zeros_like(self.v)
        self._span = np.zeros_like(self.v)
        self.mass = np.zeros(self.n_nodes)  # true lumped mass
        self.m_inertial = np.zeros(self.n_nodes)
        self.minv = np.zeros(self.n_nodes)
        self.active_nodes = np.zeros(self.n_nodes, bool)  # nodes carrying mass
        self._mass_vec = la.vector(imap, 1)  # the lumped mass, assembled in place
        self.x0 = mesh.geometry.x.copy()
        self._x_old = mesh.geometry.x.copy()

        self.constraints: list[VelocityConstraint] = []
        self.contacts = []
        self.loads: list[LoadGroup] = []
        self.energy = Energy()
        self.t = 0.0
        self.steps = 0
        self.rejected = 0
        self.dt_prev = 0.0
        self.dt = 0.0
        self.dt_crit = math.inf
        self._active = None
        self.timings: dict[str, float] = {}
        self._clock = _no_clock
        self.set_active_cells(np.arange(self.n_cells_owned, dtype=np.int32))

    def profile(self, on: bool = True) -> None:
        """Accumulate wall-clock seconds per phase of the step in ``timings`` (benchmarks)."""
        self.timings = {k: 0.0 for k in ("update", "strain", "constitutive", "dt", "assembly")}
        self._clock = _Clock(self.timings) if on else _no_clock

    # ------------------------------------------------------------------ state and layers
    def _alloc_state(self, nc: int):
        nq = self.nq
        n = nc * nq
        self.sig = np.zeros((n, 4))
        self._sig_new = np.zeros((n, 4))
        self._sig_rot = np.zeros((n, 4))
        self.state = {k: np.zeros((n, c) if c > 1 else n) for k, c in self.material.state_fields.items()}
        self._state_new = {k: np.zeros_like(a) for k, a in self.state.items()}
        self.rho = np.full(n, self.material.density)
        self._rho_new = np.zeros(n)
        self.deps = np.zeros((n, 4))
        self.spin = np.zeros(n)
        self.dvol = np.zeros(n)
        self.dV = np.zeros(n)
        self.trd_cell = np.zeros(nc)
        self.L_cell = np.zeros(nc)
        self.c_cell = np.zeros(nc)
        self.rho_cell = np.full(nc, self.material.density)
        self.kin = np.zeros((nc, nq, 6))
        self.packed = np.zeros((nc, nq * 4))

    def set_active_cells(self, cells: np.ndarray, *, keep_state: bool = True) -> None:
        """Integrate over ``cells`` only (owned, sorted); state of cells already active is kept."""
        cells = np.asarray(np.sort(cells), np.int32)
        old = self._active
        if old is not None and keep_state:
            fields = self.material.state_fields
            saved = self.sig.reshape(-1, self.nq, 4), {k: a.reshape(old.size, self.nq, fields[k]) for k, a in
                                                       self.state.items()}, self.rho.reshape(-1, self.nq)
        self._alloc_state(cells.size)
        if old is not None and keep_state:
            kept = np.isin(old, cells)  # cells that stay active keep their state
            pos = np.searchsorted(cells, old[kept])
            self.sig.reshape(-1, self.nq, 4)[pos] = saved[0][kept]
            for k, a in self.state.items():
                a.reshape(cells.size, self.nq, self.material.state_fields[k])[pos] = saved[1][k][kept]
            self.rho.reshape(-1, self.nq)[pos] = saved[2][kept]
        self._active = cells
        self.force_form, self._force_key = self.forms.internal_force(cells)
        self._mass_form = self.forms.mass_form(cells)
        self._coeffs = {self._force_key: self.packed}
        self._update_geometry_cache()
        self.rebuild_mass()
        self.refresh_force()

    @property
    def active_cells(self) -> np.ndarray:
        return self._active

    def rebuild_mass(self) -> None:
        """Lumped mass from the current densities (after activation or a remap)."""
        m = self.forms.lumped_mass(self.rho.reshape(-1, self.nq), self._active, self._mass_form,
                                   out=self._mass_vec)
        self.mass[:] = m
        np.multiply(m, self.numerics.mass_scaling, out=self.m_inertial)
        self.minv[:] = 0.0
        np.divide(1.0, self.m_inertial, out=self.minv, where=m > 0.0)
        np.greater(m, 0.0, out=self.active_nodes)

    def nodal_mass_of(self, cells: np.ndarray) -> np.ndarray:
        """Lumped mass of a subset of the active cells (e.g. one layer), per node."""
        pos = np.searchsorted(self._active, cells)
        rho = self.rho.reshape(-1, self.nq)[pos]
        return self.forms.lumped_mass(rho, cells)

    # ------------------------------------------------------------------ loads
    def add_gravity(self, cells: np.ndarray | None = None, amplitude: Callable[[float], float] = lambda t: 1.0):
        """Gravity −g ẑ on the mass of ``cells`` (default: all active), scaled by amplitude(t)."""
        m = self.mass if cells is None else self.nodal_mass_of(cells)
        f = np.zeros((self.n_nodes, 2))
        f[:, 1] = -self.gravity * m
        self.loads.append(LoadGroup(f, amplitude, "gravity"))

    def add_nodal_force(self, force: np.ndarray, amplitude: Callable[[float], float], kind: str = "surcharge"):
        self.loads.append(LoadGroup(np.asarray(force).reshape(-1, 2), amplitude, kind))

    def _external_force(self, t: float) -> None:
        self.f_ext[:] = 0.0
        for g in self.loads:
            a = g.amplitude(t)
            if a != 0.0:
                _axpy(a, g.force, self.f_ext)

    # ------------------------------------------------------------------ geometry caches
    def _update_geometry_cache(self) -> None:
        """Corner nodes of the active cells (they change with activation only) and Δt."""
        self._active_nodes = np.ascontiguousarray(self.cell_nodes[self._active])
        self._update_stable_dt()

    def _update_stable_dt(self) -> None:
        """Stable Δt of the current configuration (after activation or a remap moved the mesh)."""
        x = self.mesh.geometry.x
        self.dt_crit = kernels.stable_dt(x, self._active_nodes, self.rho_cell, self.material.wave_modulus,
                                         self.trd_cell, *self.numerics.bulk_viscosity,
                                         self.numerics.mass_scaling, self.L_cell, self.c_cell, kernels.HOOP)
        self.dt_crit = reduce_scalar(self.comm, self.dt_crit, MPI.MIN)
        self._dt_crit0 = self.dt_crit
        if self.dt == 0.0:
            self.dt = self.numerics.time_step_scale * self.dt_crit

    def _assemble_internal_force(self, vec) -> None:
        from dolfinx import fem, la

        vec.array[:] = 0.0
        fem.assemble_vector(vec.array, self.force_form, constants=np.zeros(0), coeffs=self._coeffs)
        vec.scatter_reverse(la.InsertMode.add)

    def refresh_force(self) -> None:
        """Internal force and volumes from the stored stress at rest (start, activation, remap)."""
        self.forms.kinematics.eval(self.mesh, self._active, self.kin)
        kernels.kinematics(self.kin, self.forms.weights, 0.0, self.numerics.bbar, self.deps, self.spin,
                           self.dvol, self.dV, self.trd_cell)
        kernels.cell_average(self.rho, self.dV, self.nq, self.rho_cell)
        kernels.closure(self.sig, self.sig, self.deps, self.dV, self.trd_cell, self.rho, self.L_cell,
                        self.c_cell, 0.0, 0.0, self.numerics.bbar, self.nq, self.packed)
        self._assemble_internal_force(self._fvec)
        self._force_stale = False

    # ------------------------------------------------------------------ the step
    def step(self) -> float:
        """Advance one (accepted) step; returns its Δt."""
        while True:
            dt = self.dt
            if self._try_step(dt):
                return dt
            self.rejected += 1

    def _try_step(self, dt: float) -> bool:
        num = self.numerics
        x = self.mesh.geometry.x
        clock = self._clock
        dt_avg = 0.5 * (self.dt_prev + dt) if self.dt_prev > 0.0 else 0.5 * dt
        t_mid = self.t + 0.5 * dt

        # 1. predict
        clock(None)
        if self._force_stale:  # a deferred internal force that no remap rebuilt
            self._assemble_internal_force(self._fvec)
            self._force_stale = False
        self._external_force(self.t)
        np.copyto(self._v_old, self.v)
        _predict(self.v, self.f_ext, self.f_int, self.minv, num.damping, dt_avg, self.a)
        # 2. fixed components (axis, rollers) first; contact; then prescribed velocities win
        for c in self.constraints:
            if c.value is None:
                self.v[c.dofs, c.comp] = 0.0
        for contact in self.contacts:
            contact.apply(x, self.v, self.m_inertial, dt, dt_avg)
        for c in self.constraints:
            self.v[c.dofs, c.comp] = 0.0 if c.value is None else c.value(t_mid)
        self._vvec.scatter_forward()
        clock("update")

        # 3. update: mid-step kinematics, then end configuration
        np.copyto(self._x_old, x)
        _move(x, self._x_old, self.v, self.node_dof, 0.5 * dt)
        self.forms.kinematics.eval(self.mesh, self._active, self.kin)
        kernels.kinematics(self.kin, self.forms.weights, dt, num.bbar, self.deps, self.spin, self.dvol,
                           self.dV, self.trd_cell)
        _move(x, self._x_old, self.v, self.node_dof, dt)
        kernels.rotate(self.sig, self.spin, self._sig_rot)
        clock("strain")
        d_plastic = self.material.update(self._sig_rot, self.deps, self.state, self._sig_new, self._state_new,
                                         self.dV)
        kernels.update_density(self.rho, self.dvol, dt, self.nq, num.bbar, self._rho_new)
        kernels.cell_average(self._rho_new, self.dV, self.nq, self.rho_cell)
        clock("constitutive")

        # 5. stable Δt on the new configuration (before committing)
        dt_crit = kernels.stable_dt(x, self._active_nodes, self.rho_cell, self.material.wave_modulus,
                                    self.trd_cell, *num.bulk_viscosity, num.mass_scaling, self.L_cell,
                                    self.c_cell, kernels.HOOP)
        dt_crit = reduce_scalar(self.comm, dt_crit, MPI.MIN)
        clock("dt")
        if not (dt_crit > 1e-6 * self._dt_crit0 and math.isfinite(dt_crit)):
            np.copyto(x, self._x_old)
            hint = (f"[numerics] time_step_scale = {num.time_step_scale:g} exceeds the stability limit: use 0.9 "
                    "or less." if num.time_step_scale > 0.9 else "the mesh is tangled by large deformation: "
                    "enable [ale], or refine where it distorts.")
            raise InstabilityError(
                f"an element collapsed at step {self.steps} (t = {self.t:.6g} s; stable Δt fell from "
                f"{self._dt_crit0:.3g} to {dt_crit:.3g} s): {hint}")
        if dt > num.time_step_scale * dt_crit * (1.0 + REJECT_TOLERANCE):
            np.copyto(x, self._x_old)
            np.copyto(self.v, self._v_old)
            self.dt = num.time_step_scale * dt_crit
            return False

        # 4. internal force on the new configuration
        w_int, w_visc = kernels.closure(self._sig_rot, self._sig_new, self.deps, self.dV, self.trd_cell,
                                        self._rho_new, self.L_cell, self.c_cell, *num.bulk_viscosity, num.bbar,
                                        self.nq, self.packed)
        if not self.defer_force:
            self._assemble_internal_force(self._fvec_new)
        clock("assembly")

        # energy: forces of step n acting over ½(Δx^{n−½} + Δx^{n+½})
        n = self.n_owned
        w_ext, w_corr, w_damp = _work(self.v, self._v_old, self.a, self.f_ext, self.m_inertial, self._dx_prev,
                                      self._span, dt, dt_avg, num.damping, n)
        e = self.energy
        for g in self.loads:
            if g.kind == "gravity":
                e.gravity += g.amplitude(self.t) * _dot(g.force, self._span, n)
        e.external += w_ext + w_corr
        e.contact += w_corr
        e.damping += w_damp
        e.plastic += d_plastic
        e.viscous += w_visc
        e.internal_work += w_int
        self._last_increment = (d_plastic, w_visc, w_int)

        # commit
        self.sig, self._sig_new = self._sig_new, self.sig
        self.state, self._state_new = self._state_new, self.state
        self.rho, self._rho_new = self._rho_new, self.rho
        self.f_int, self._f_new = self._f_new, self.f_int
        self._fvec, self._fvec_new = self._fvec_new, self._fvec
        self.t += dt
        self.steps += 1
        self.dt_prev = dt
        self.dt_crit = dt_crit
        self.dt = num.time_step_scale * dt_crit
        self._force_stale = self.defer_force
        clock("update")
        return True

    # ------------------------------------------------------------------ diagnostics
    def global_energy(self) -> Energy:
        """The energy record at the last half step t_{n+½}, summed over ranks.

        The external work of step n spans x^{n−½} → x^{n+½} and pairs with the kinetic energy
        ½ M |v^{n+½}|²; the elastic energy and the dissipations, known at t_n and t_{n+1}, are
        taken at their mean. Every term is then centred at the same instant (second order)."""
        e = self.energy
        ke, el = self._kinetic_elastic_local()
        dp, dv, di = getattr(self, "_last_increment", (0.0, 0.0, 0.0))
        names = ["plastic", "viscous", "damping", "external", "gravity", "contact", "internal_work", "remap",
                 "outflow", "initial"]
        local = np.array([ke, el] + [getattr(e, k) for k in names])
        local[2] -= 0.5 * dp
        local[3] -= 0.5 * dv
        local[8] -= 0.5 * di
        tot = self.comm.allreduce(local, op=MPI.SUM)
        g = Energy(*map(float, tot))
        self.energy_scale = max(getattr(self, "energy_scale", 0.0), g.scale)
        return g

    def _kinetic_elastic_local(self, increment: np.ndarray | None = None) -> tuple[float, float]:
        ke = self.kinetic_energy_local()
        if self.steps > 0:  # the previous stress is still in the double buffer
            return ke, self.material.elastic_energy_mean(self.sig, self._sig_new, self.dV, increment)
        if increment is not None:
            increment[:] = 0.0
        return ke, self.material.elastic_energy(self.sig, self.dV)

    def kinetic_energy_local(self) -> float:
        return _kinetic(self.m_inertial, self.v, self.n_owned)

    def mechanical_energy_local(self, increment: np.ndarray | None = None) -> float:
        """This rank's kinetic + elastic energy as :meth:`global_energy` counts them (J); with
        ``increment``, the last step's stress increment σ^{n+1} − σ^n is written into it."""
        return sum(self._kinetic_elastic_local(increment))

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
        num = self.numerics
        t_half = self.t - 0.5 * self.dt_prev  # where the staggered velocity lives
        for c in self.constraints:  # on owned and ghost dofs alike: ghosts stay consistent
            self.v[c.dofs, c.comp] = 0.0 if c.value is None else c.value(t_half)
        np.copyto(self.dV, dV)
        kernels.cell_average(self.rho, self.dV, self.nq, self.rho_cell)
        self._update_stable_dt()
        self.dt = num.time_step_scale * self.dt_crit
        self.rebuild_mass()
        kernels.closure(self.sig, self.sig, self.deps, self.dV, self.trd_cell, self.rho, self.L_cell, self.c_cell,
                        *num.bulk_viscosity, num.bbar, self.nq, self.packed)
        t0 = time.perf_counter()
        self._assemble_internal_force(self._fvec)
        deferred = time.perf_counter() - t0 if self._force_stale else 0.0
        self._force_stale = False
        if sig_increment is None:
            np.copyto(self._sig_new, self.sig)  # the "previous" stress of the energy average
            elastic = self.material.elastic_energy(self.sig, self.dV)
        else:
            elastic = self.material.elastic_energy_mean_from_increment(self.sig, sig_increment, self.dV,
                                                                       self._sig_new)
        np.multiply(self.v, self.dt_prev, out=self._dx_prev)
        return deferred, elastic

    def replace_gravity(self) -> None:
        """One full-gravity load on the current lumped mass in place of all gravity loads
        (after a remap changed the mass; only once every gravity ramp has ended)."""
        if any(g.kind == "gravity" and g.amplitude(self.t) != 1.0 for g in self.loads):
            raise RuntimeError("replace_gravity during a gravity ramp")
        self.loads = [g for g in self.loads if g.kind != "gravity"]
        self.add_gravity()

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
def _work(v, v_old, a, f_ext, m, dx_prev, span, dt, dt_avg, alpha, n):
    """Work of step n over the owned nodes: external, constraint + contact (the velocity
    corrections as forces M Δv/Δt̄), and damping; updates Δx^{n−½} and the span buffer."""
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


