"""A scene, run: mesh, silo model, stages (fill -> store -> discharge), outputs.

The silo model (:class:`SiloModel`) puts the boundary conditions of a silo on the generic
explicit solver:

* the axis r = 0: v_r = 0;
* the wall: kinematic contact with the analytic wall, continued beyond its top, with the
  scene's friction law; while the outlet is closed, a *gate* piece from the axis to the
  outlet edge is the first piece of the same contact wall (smooth, rough = wall law, or
  fixed), so the closed outlet is a contact surface like the others;
* gravity on the active cells, and a top surcharge on the top surface if asked.

Stages, each switching only the effects the scene asks for:

fill
    ``layers``: N horizontal layers by cell centroid; layer k is activated stress-free at
    k·T/N and its gravity ramped with a smooth step over ``ramp_fraction`` of its interval
    (the thesis ch. 3.4.1, 4.2.2); inactive layers are not integrated at all.
    ``ramp``: all cells, gravity ramped smoothly. ``k0``: geostatic stress, no stage.
store
    closed outlet, full gravity; ends at ``duration`` or once kinetic energy falls below
    ``kinetic_energy_tol`` × the work of gravity.
discharge
    ``free``: the gate is removed at once; ``controlled``: the outlet nodes move down at
    u(t) = u0/2 (1 − cos(π t/T)) then u0 (eq. 3-14).
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from silo_dolfinx._mpi import reduce_scalar
from silo_dolfinx.contact import COULOMB, NONE, STICK, FrictionLaw, WallContact
from silo_dolfinx.geometry.mesher import FACET_TAGS, SiloMesh, mesh_scene
from silo_dolfinx.geometry.wall import Segment, Wall
from silo_dolfinx.materials import make_material
from silo_dolfinx.output import Progress, Results
from silo_dolfinx.solver import ExplicitSolver, InstabilityError, Numerics, VelocityConstraint


def smooth_step(x: float) -> float:
    """Abaqus' smooth step: 0 -> 1 on [0, 1] with zero first and second derivatives at both ends."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    return x**3 * (10.0 - 15.0 * x + 6.0 * x * x)


def ramp_velocity(u0: float, ramp_time: float):
    """Eq. 3-14: u(t) = u0/2 (1 − cos(π t/T)) for t < T, then u0."""
    def u(t: float) -> float:
        if ramp_time <= 0.0 or t >= ramp_time:
            return u0
        return 0.5 * u0 * (1.0 - math.cos(math.pi * max(t, 0.0) / ramp_time))

    return u


class SiloModel:
    """A scene's silo on the explicit solver: walls, gate, axis, loads, layers."""

    def __init__(self, scene, sm: SiloMesh):
        self.scene = scene
        self.sm = sm
        self.outline = sm.outline
        self.ale = None  # set by the discharge stage when [ale] is enabled
        self.material = make_material(scene.material)
        self.solver = ExplicitSolver(sm.mesh, self.material, Numerics.from_scene(scene),
                                     gravity=scene.loads.gravity)
        s = self.solver
        owned = lambda nodes: nodes[s.node_dof[nodes] < s.n_owned]  # noqa: E731
        self.wall_nodes = owned(sm.nodes_on("wall"))
        self.outlet_nodes = owned(sm.nodes_on("outlet"))
        self.axis_dofs = s.node_dof[sm.nodes_on("axis")]
        self.outlet_dofs_all = s.node_dof[sm.nodes_on("outlet")]
        s.constraints.append(VelocityConstraint(self.axis_dofs, 0))
        self.wall_law = FrictionLaw.from_wall(scene.wall)
        self.contact_wall_open = self.outline.contact_wall()
        self.outlet_open = False
        self._set_contact(closed=True)
        # Damping (fill and store only): fraction of critical of the fundamental vertical mode.
        c = math.sqrt(self.material.wave_modulus / self.material.density)
        self.fill_damping = 2.0 * scene.fill.damping * math.pi * c / (2.0 * self.outline.fill_height)
        self._surcharge_vec = None
        if scene.loads.top_surcharge > 0.0:
            self._surcharge_vec = self._surcharge_force(scene.loads.top_surcharge)

    # ------------------------------------------------------------------ walls
    def _set_contact(self, closed: bool) -> None:
        """Wall contact for the wall nodes; while closed, a gate contact for the outlet nodes.

        Two contact sets applied in turn (gate, then wall) rather than one chain, so a node at
        the outlet edge takes the floor reaction from the gate and the wall reaction from the
        wall, and each surface reports its own force."""
        s = self.solver
        wall = self.contact_wall_open
        self.contact = WallContact(wall, self.wall_nodes, s.node_dof[self.wall_nodes], [self.wall_law] * len(wall.pieces))
        contacts = [self.contact]
        if closed:
            r0 = self.outline.outlet_radius
            gate_law = {"smooth": FrictionLaw(NONE), "rough": self.wall_law,
                        "fixed": FrictionLaw(COULOMB, mu=STICK)}[self.scene.discharge.gate]
            # the gate reaches past the axis and the outlet edge, so its nodes are inside it
            gate = Wall([Segment((-0.5 * r0, 0.0), (1.5 * r0, 0.0))])
            self.gate = WallContact(gate, self.outlet_nodes, s.node_dof[self.outlet_nodes], [gate_law])
            contacts.insert(0, self.gate)
        s.contacts[:] = contacts
        # Nodes whose velocity is prescribed are driven and take no part in contact. (The axis
        # constraint v_r = 0 is compatible: the gate and floors it meets are horizontal.)
        for c in s.constraints:
            if c.value is not None:
                for contact in contacts:
                    contact.exclude(c.dofs)

    def open_outlet(self) -> None:
        """Remove the gate (free discharge) or drive the outlet (controlled discharge)."""
        d = self.scene.discharge
        self.outlet_open = True
        if d.mode == "controlled":
            u = ramp_velocity(d.velocity, d.ramp_time)
            t0 = self.solver.t
            self.solver.constraints.append(
                VelocityConstraint(self.outlet_dofs_all, 1, lambda t: -u(t - t0)))
        self._set_contact(closed=False)

    # ------------------------------------------------------------------ loads
    def _surcharge_force(self, pressure: float) -> np.ndarray:
        from dolfinx import fem, la

        p = fem.Constant(self.sm.mesh, float(pressure))
        form = self.solver.forms.surcharge_form(self.sm.facet_tags, FACET_TAGS["top"], p)
        b = fem.assemble_vector(form)
        b.scatter_reverse(la.InsertMode.add)
        b.scatter_forward()
        return b.array.reshape(-1, 2).copy()

    def layers(self) -> list[np.ndarray]:
        """Owned cells of each filling layer, bottom first (by initial centroid height; the
        mesher makes the layer tops mesh lines, so each layer is a full horizontal slab)."""
        n = self.scene.fill.layers if self.scene.fill.method == "layers" else 1
        from silo_dolfinx.geometry.quality import cell_corners

        zc = cell_corners(self.sm.mesh)[:, :, 1].mean(axis=1)
        k = np.minimum((zc / self.outline.fill_height * n).astype(int), n - 1)
        return [np.nonzero(k == i)[0].astype(np.int32) for i in range(n)]

    def activate(self, cells: np.ndarray, new_cells: np.ndarray | None, t0: float, ramp_time: float,
                 last: bool) -> None:
        """Integrate over ``cells``; ramp the gravity of ``new_cells`` from t0 (others: full)."""
        s = self.solver
        s.set_active_cells(cells)
        s.loads.clear()
        amp = (lambda t: smooth_step((t - t0) / ramp_time)) if ramp_time > 0 else (lambda t: 1.0)
        comm = self.sm.comm
        old = cells if new_cells is None else np.setdiff1d(cells, new_cells)
        n_old = comm.allreduce(old.size if new_cells is not None else 0, op=MPI.SUM)  # global decisions:
        if n_old == 0:                                                              # every rank takes
            s.add_gravity(amplitude=amp)                                            # the same branch
        else:
            s.add_gravity(old.astype(np.int32))
            if comm.allreduce(new_cells.size, op=MPI.SUM) > 0:
                s.add_gravity(new_cells, amp)
        if last and self._surcharge_vec is not None:
            s.add_nodal_force(self._surcharge_vec, amp, "surcharge")

    def set_geostatic_stress(self, k0: float) -> None:
        """σ_zz = −(ρ g (H − z) + q), σ_rr = σ_θθ = k0 σ_zz at every quadrature point."""
        s = self.solver
        xq = s.quadrature_points()
        H = self.outline.fill_height
        rho, g = self.material.density, s.gravity
        szz = -(rho * g * (H - xq[:, 1]) + self.scene.loads.top_surcharge)
        s.sig[:, 0] = k0 * szz
        s.sig[:, 1] = szz
        s.sig[:, 2] = k0 * szz
        s.sig[:, 3] = 0.0
        m = s.material
        if m.plastic:  # a K0 state outside the yield surface is first returned onto it (no dissipation booked)
            out = np.empty_like(s.sig)
            state = {k: a.copy() for k, a in s.state.items()}
            m.update(s.sig.copy(), np.zeros_like(s.sig), s.state, out, state, s.dV)
            s.sig[:] = out
        s.refresh_force()
        # stored without any work done on it: the energy balance starts from it
        s.energy.initial = s.material.elastic_energy(s.sig, s.dV)  # this rank's share (summed globally)

    def after_remap(self) -> None:
        """The mesh and the mass changed (ALE remap): gravity on the new mass, surcharge on
        the moved top."""
        self.solver.replace_gravity()
        if self._surcharge_vec is not None:
            f = self._surcharge_force(self.scene.loads.top_surcharge)
            for g in self.solver.loads:
                if g.kind == "surcharge":
                    g.force[:] = f

    # ------------------------------------------------------------------ wall output
    def wall_state(self) -> dict[str, np.ndarray] | None:
        """Per wall node (gathered on rank 0, sorted by arclength): s, r, z, p_n, p_s, slip."""
        from dolfinx import fem, la

        s = self.solver
        c = self.contact
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
        cols = np.column_stack([c.s, x[:, 0], x[:, 1], c.normal_force / a, c.shear_force / a,
                                c.slip_velocity, c.in_contact.astype(float)])[on_wall]
        parts = self.sm.comm.gather(cols, root=0)
        if parts is None:
            return None
        allc = np.concatenate(parts)
        allc = allc[np.argsort(allc[:, 0])]
        return dict(zip(("s", "r", "z", "p_n", "p_s", "slip_velocity", "in_contact"), allc.T))


class Recorder:
    """Time histories, profiles and fields of a running model into a :class:`Results` folder."""

    ENERGY_COLUMNS = ["t", "stage", "kinetic", "elastic", "plastic", "viscous", "damping", "remap", "outflow",
                      "initial", "gravity_work", "external_work", "contact_work", "balance", "relative_error"]
    WALL_COLUMNS = ["t", "station", "s", "r", "z", "p_n", "p_s", "slip_velocity"]
    PROFILE_COLUMNS = ["s", "r", "z", "p_n", "p_s", "slip_velocity", "in_contact"]

    def __init__(self, model: SiloModel, results: Results):
        self.model = model
        self.results = results
        out = model.scene.output
        self.dt_history = 1.0 / out.history_rate
        self.dt_fields = out.field_interval
        self.next_history = 0.0
        self.next_fields = 0.0
        wall = model.outline.wall
        st = np.asarray(out.stations, float)
        self.station_s = wall.s_at_height(st) if out.station_coordinate == "z" else st
        self.energy_csv = results.series("energy.csv", self.ENERGY_COLUMNS)
        self.wall_csv = results.series("wall_history.csv", self.WALL_COLUMNS)
        self.max_abs_balance = 0.0  # largest |balance| seen, J
        self._last_t = None
        self._last_fields = None
        self._fields = None
        self.monitor = None  # the discharge stage's outlet and mesh-quality monitor

    def maybe(self, stage: str) -> None:
        t = self.model.solver.t
        if t + 1e-12 >= self.next_history:
            self.history(stage)
            while self.next_history <= t + 1e-12:
                self.next_history += self.dt_history
        if t + 1e-12 >= self.next_fields:
            self.fields()
            while self.next_fields <= t + 1e-12:
                self.next_fields += self.dt_fields

    def history(self, stage: str) -> None:
        s = self.model.solver
        if s.t == self._last_t:
            return  # a stage end that coincides with a periodic sample
        self._last_t = s.t
        s.check_finite()  # nothing non-finite is ever written
        e = s.global_energy()
        err = e.relative_error(s.energy_scale)
        self.max_abs_balance = max(self.max_abs_balance, abs(e.balance))
        if self.monitor is not None:
            self.monitor.sample()
        self.energy_csv.write([s.t, stage, e.kinetic, e.elastic, e.plastic, e.viscous, e.damping, e.remap,
                               e.outflow, e.initial, e.gravity, e.external, e.contact, e.balance, err])
        w = self.model.wall_state()
        if w is not None and w["s"].size:
            rows = []
            for k, ss in enumerate(self.station_s):
                vals = [float(np.interp(ss, w["s"], w[name])) for name in ("r", "z", "p_n", "p_s", "slip_velocity")]
                rows.append([s.t, k, float(ss), *vals])
            self.wall_csv.write(*rows)

    def stage_end(self, stage: str) -> None:
        """History sample, wall profile and fields at the end of a stage."""
        self.history(stage)
        self.profile(stage)
        if self._last_fields != self.model.solver.t:
            self.fields()

    def profile(self, stage: str) -> None:
        w = self.model.wall_state()
        if w is not None:
            rows = np.column_stack([w[k] for k in self.PROFILE_COLUMNS]).tolist()
            self.results.write_rows(f"wall_profile_{stage}.csv", self.PROFILE_COLUMNS, rows)

    def fields(self) -> None:
        fw = self._fields or FieldWriter(self.model, self.results.path("fields"))
        self._fields = fw
        fw.write(self.model.solver.t)
        self._last_fields = self.model.solver.t

    def close(self) -> None:
        if self._fields is not None:
            self._fields.close()


class FieldWriter:
    """VTX output for ParaView: nodal velocity and displacement; cell-mean stress and invariants."""

    CELL_FIELDS = ("stress_rr", "stress_zz", "stress_tt", "stress_rz", "p", "q", "q_over_p", "density")

    def __init__(self, model: SiloModel, folder: Path):
        from dolfinx import fem, io

        self.model = model
        s = model.solver
        mesh = model.sm.mesh
        if mesh.comm.rank == 0:
            folder.mkdir(parents=True, exist_ok=True)
        mesh.comm.barrier()
        self.disp = fem.Function(s.V, name="displacement")
        W = fem.functionspace(mesh, ("DG", 0))
        names = list(self.CELL_FIELDS) + (["eqps"] if "eqps" in s.state else [])
        self.cell = {n: fem.Function(W, name=n) for n in names}
        self._buf = np.zeros(s.n_cells_owned)
        self.w_nodes = io.VTXWriter(mesh.comm, folder / "nodes.bp", [s.forms.velocity, self.disp], engine="BP4")
        self.w_cells = io.VTXWriter(mesh.comm, folder / "cells.bp", list(self.cell.values()), engine="BP4")
        self.folder = folder
        self.count = 0

    def write(self, t: float) -> None:
        from silo_dolfinx import kernels

        s = self.model.solver
        self.disp.x.array[:] = s.displacement().ravel()
        cells = s.active_cells
        sig = s.sig
        p = -(sig[:, 0] + sig[:, 1] + sig[:, 2]) / 3.0
        m = -p
        j2 = 0.5 * ((sig[:, 0] - m) ** 2 + (sig[:, 1] - m) ** 2 + (sig[:, 2] - m) ** 2) + sig[:, 3] ** 2
        q = np.sqrt(3.0 * j2)
        values = {"stress_rr": sig[:, 0], "stress_zz": sig[:, 1], "stress_tt": sig[:, 2], "stress_rz": sig[:, 3],
                  "p": p, "q": q, "q_over_p": np.where(p > 1e-9, q / np.maximum(p, 1e-9), 0.0), "density": s.rho}
        if "eqps" in self.cell:
            values["eqps"] = s.state["eqps"]
        avg = np.zeros(cells.size)
        snapshot = {}
        for name, f in self.cell.items():
            kernels.cell_average(np.ascontiguousarray(values[name]), s.dV, s.nq, avg)
            f.x.array[:] = 0.0
            f.x.array[cells] = avg
            f.x.scatter_forward()
            snapshot[name] = avg.copy()
        self.w_nodes.write(t)
        self.w_cells.write(t)
        self._snapshot(t, snapshot)

    def _snapshot(self, t: float, cell_values: dict) -> None:
        """fields/snapshot_NNNN.npz on rank 0: active cells' corners and cell means, owned
        nodes' positions and velocities (for `silo report`: renders, flow-channel boundary)."""
        s = self.model.solver
        comm = self.model.sm.comm
        x = self.model.sm.mesh.geometry.x
        corners = x[s.active_cell_nodes][:, :, :2]
        owned_nodes = np.nonzero(s.node_dof < s.n_owned)[0]
        parts = comm.gather((corners, cell_values, x[owned_nodes, :2], s.v[s.node_dof[owned_nodes]]), root=0)
        ale = self.model.ale
        tracers = ale.tracers.gather() if ale is not None and ale.tracers is not None else None
        if parts is None:
            return
        data = {"t": t, "corners": np.concatenate([p[0] for p in parts]),
                "node_xy": np.concatenate([p[2] for p in parts]), "node_velocity": np.concatenate([p[3] for p in parts])}
        for name in cell_values:
            data[f"cell_{name}"] = np.concatenate([p[1][name] for p in parts])
        if tracers is not None:
            data.update({f"tracer_{k}": v for k, v in tracers.items()})
        np.savez_compressed(self.folder / f"snapshot_{self.count:04d}.npz", **data)
        self.count += 1

    def close(self) -> None:
        self.w_nodes.close()
        self.w_cells.close()


# ---------------------------------------------------------------------------- the run
def total_time(scene) -> float:
    f = 0.0 if scene.fill.method == "k0" else scene.fill.duration
    d = scene.discharge.duration if scene.discharge.mode != "none" else 0.0
    return f + scene.store.duration + d


def run(scene, out: str | Path, comm=None, *, progress_every: float = 5.0) -> dict:
    """Run a scene into the results folder ``out``; returns the summary (also on disk)."""
    comm = MPI.COMM_WORLD if comm is None else comm
    results = Results(out, scene, comm)
    wall0 = time.time()
    recorder = None
    try:
        sm = mesh_scene(scene, comm)
        from silo_dolfinx.geometry.plot import plot_mesh
        from silo_dolfinx.geometry.quality import quality_report

        q = quality_report(sm.mesh)
        plot_mesh(sm, results.path("mesh.png"), title=f"{scene.title}: {q['cells']} cells")
        model = SiloModel(scene, sm)
        s = model.solver
        results.update(cells=q["cells"], mesh_quality=q, material=model.material.name,
                       stable_dt_initial=s.dt_crit, time_step_scale=s.numerics.time_step_scale,
                       ale=("on in the discharge" if scene.ale.enabled and scene.discharge.mode != "none" else
                            "off (Lagrangian)"))
        recorder = Recorder(model, results)
        progress = Progress(comm, total_time(scene), every=progress_every)
        stages = _fill(model, recorder, progress)
        stages.append(_store(model, recorder, progress))
        if scene.discharge.mode != "none":
            stages.append(_discharge(model, recorder, progress))
        e = s.global_energy()
        results.summary["warnings"] += _dilation_warnings(scene, stages)
        results.update(stages=stages, steps=s.steps, rejected_steps=s.rejected, simulated_time=s.t,
                       energy={k: getattr(e, k) for k in ("kinetic", "elastic", "plastic", "viscous", "damping",
                                                          "gravity", "external", "contact")},
                       energy_balance_error=e.relative_error(s.energy_scale),
                       energy_balance_error_max=recorder.max_abs_balance / max(s.energy_scale, 1e-300),
                       steps_per_second=s.steps / max(time.time() - wall0, 1e-9))
        results.finish("completed")
    except InstabilityError as err:
        results.finish("failed", str(err))
        raise
    except BaseException as err:
        results.finish("failed", f"{type(err).__name__}: {err}")
        raise
    finally:
        if recorder is not None:
            recorder.close()
    return results.summary


def _advance(model: SiloModel, t_end: float, stage: str, recorder: Recorder, progress, stop=None,
             label: str | None = None, ale=None) -> None:
    """The time loop (thesis ch. 3): Lagrangian step (predict, internal force, contact,
    update), then every N steps smoothing + remap."""
    s = model.solver
    while s.t < t_end * (1 - 1e-12) - 1e-15:
        remaining = t_end - s.t
        if s.dt > remaining:
            s.dt = remaining
        s.defer_force = ale is not None and ale.due_next()
        s.step()
        if ale is not None and ale.due():
            ale.apply()
        recorder.maybe(stage)
        progress(label or stage, s.t, s.steps, s.dt)
        if stop is not None and recorder.next_history - recorder.dt_history <= s.t and stop():
            break


def _stage_record(name: str, t0: float, model: SiloModel, steps0: int, wall0: float) -> dict:
    s = model.solver
    return {"name": name, "t_start": t0, "t_end": s.t, "steps": s.steps - steps0,
            "wall_clock_s": round(time.time() - wall0, 3), "dt_last": s.dt_prev,
            "density_min": reduce_scalar(s.comm, float(s.rho_cell.min(initial=np.inf)), MPI.MIN)}


DILATION_WARNING = 0.5  # a cell below this fraction of the solid's density is no granular solid


def _dilation_warnings(scene, stages: list[dict]) -> list[str]:
    """A warning for each stage that ended with a cell dilated below half the solid's density,
    naming the cause: without a critical state (max_dilation = 0, ψ > 0) the cone's dilation
    never stops; with one, what remains is tensile separation at the cone's apex (a solid
    stretched at near-zero pressure: the free-fall zone above an outlet, a free-surface
    crater), which a Drucker-Prager solid never recompacts."""
    m = scene.material
    rho0 = m.density
    out = []
    for st in stages:
        if st["density_min"] < DILATION_WARNING * rho0:
            head = (f"[material] by the end of the {st['name']} stage a cell had dilated to {st['density_min']:.4g} "
                    f"kg/m³ ({100 * st['density_min'] / rho0:.0f} % of density = {rho0:g}): ")
            if m.get("dilation_angle", 0.0) > 0.0 and m.get("max_dilation", 0.0) == 0.0:
                out.append(head + f"with dilation_angle = {m.dilation_angle:g} and max_dilation = 0 the solid dilates "
                           "for as long as it shears. Set material.max_dilation > 0 (the default 0.05: a critical "
                           "state) or dilation_angle = 0 if the flowing solid should keep its density.")
            else:
                out.append(head + "the cone's dilation is bounded (max_dilation or ψ = 0), so this is tensile "
                           "separation at the cone's apex, where the solid is stretched at near-zero pressure (the "
                           "free-fall zone above an outlet, a free-surface crater); Drucker-Prager does not "
                           "recompact it. Its stable Δt falls with its density.")
    return out


def _fill(model: SiloModel, recorder: Recorder, progress) -> list[dict]:
    sc = model.scene
    s = model.solver
    f = sc.fill
    s.damping = model.fill_damping
    t0, steps0, wall0 = s.t, s.steps, time.time()
    if f.method == "k0":
        model.activate(np.arange(s.n_cells_owned, dtype=np.int32), None, 0.0, 0.0, last=True)
        model.set_geostatic_stress(f.k0)
        recorder.stage_end("fill")
        return [dict(_stage_record("fill", t0, model, steps0, wall0), method="k0")]
    layers = model.layers()
    n = len(layers)
    T = f.duration / n
    active = np.zeros(0, np.int32)
    for k, cells in enumerate(layers):
        active = np.union1d(active, cells).astype(np.int32)
        model.activate(active, cells, s.t, f.ramp_fraction * T, last=(k == n - 1))
        recorder.maybe("fill")
        _advance(model, t0 + (k + 1) * T, "fill", recorder, progress, label=f"fill {k + 1}/{n}")
    recorder.stage_end("fill")
    return [dict(_stage_record("fill", t0, model, steps0, wall0), method=f.method, layers=n)]


def _store(model: SiloModel, recorder: Recorder, progress) -> dict:
    sc = model.scene
    s = model.solver
    t0, steps0, wall0 = s.t, s.steps, time.time()
    tol = sc.store.kinetic_energy_tol
    stop = None
    if tol > 0.0:
        def stop():
            e = s.global_energy()
            return e.kinetic < tol * max(e.gravity, 1e-300)
    _advance(model, t0 + sc.store.duration, "store", recorder, progress, stop)
    recorder.stage_end("store")
    return dict(_stage_record("store", t0, model, steps0, wall0), ended_on="kinetic energy"
                if s.t < t0 + sc.store.duration * (1 - 1e-9) else "duration")


def _discharge(model: SiloModel, recorder: Recorder, progress) -> dict:
    sc = model.scene
    s = model.solver
    s.damping = 0.0
    t0, steps0, wall0 = s.t, s.steps, time.time()
    model.open_outlet()
    a = sc.ale
    ale = None
    if a.enabled:
        from silo_dolfinx.ale import ALE

        ale = ALE(model, frequency=a.frequency, sweeps=a.sweeps, laplacian_weight=a.laplacian_weight,
                  mid_area_weight=a.mid_area_weight, remap_order=a.remap_order, predictor=a.predictor,
                  objective=a.smoothing_objective, tracers=(a.tracer_rows, a.tracer_columns))
    model.ale = ale
    monitor = DischargeMonitor(model, recorder.results, ale)
    recorder.monitor = monitor
    _advance(model, t0 + sc.discharge.duration, "discharge", recorder, progress, ale=ale)
    recorder.stage_end("discharge")
    record = dict(_stage_record("discharge", t0, model, steps0, wall0), mode=sc.discharge.mode)
    record.update(monitor.summary())
    return record


class DischargeMonitor:
    """Outlet flow and mesh quality during the discharge: ``outlet.csv`` and ``mesh_quality.csv``.

    outlet.csv: t, discharged_mass (kg: counted by the remap as it leaves through the
    Eulerian outlet; without ALE, the mass of cells below the outlet plane), mass_in_silo,
    mass_flow_rate (kg/s: the mass actually leaving, discharged mass over the last 0.05 s),
    mean_outlet_velocity (m/s, downward, area-weighted over the outlet), mass_balance_error
    (relative), nominal_mass_flow_rate (kg/s: the thesis' definition, the solid's density ×
    outlet area × mean outlet velocity, ρ0·A·v; above the real one where the outlet material
    is looser than ρ0), dt (s: the current stable time step).
    mesh_quality.csv: t, top_drop (m, the free surface on the axis), min_scaled_jacobian,
    max_aspect_ratio (the Fig. 3-18 quantities)."""

    OUTLET_COLUMNS = ["t", "discharged_mass", "mass_in_silo", "mass_flow_rate", "mean_outlet_velocity",
                      "mass_balance_error", "nominal_mass_flow_rate", "dt"]
    MESH_COLUMNS = ["t", "top_drop", "min_scaled_jacobian", "max_aspect_ratio"]
    RATE_WINDOW = 0.05  # s: the mass flow rate is the discharged mass over this trailing window

    def __init__(self, model: SiloModel, results: Results, ale=None):
        from dolfinx import la

        from silo_dolfinx._compat import geometry_dofmap
        from silo_dolfinx.ale.remap import _orientation
        from silo_dolfinx.geometry.quality import CYCLE

        self.model = model
        self.ale = ale
        s = model.solver
        self.results = results
        self.outlet_csv = results.series("outlet.csv", self.OUTLET_COLUMNS)
        self.mesh_csv = results.series("mesh_quality.csv", self.MESH_COLUMNS)
        self._form = s.forms.tributary_area_form(model.sm.facet_tags, FACET_TAGS["outlet"])
        self._area = la.vector(s.V.dofmap.index_map, 2)
        mesh = model.sm.mesh
        self._cn_t = np.ascontiguousarray(geometry_dofmap(mesh)[: s.n_cells_owned].astype(np.int64))
        self._cn = np.ascontiguousarray(self._cn_t[:, CYCLE])
        self._orient = _orientation(mesh.geometry.x, self._cn)
        top = model.sm.nodes_on("top")
        axis = model.sm.nodes_on("axis")
        self._axis_top = np.intersect1d(top, axis)
        self._z_top0 = self._axis_top_z()
        self.t0 = s.t
        self.mass0 = self._mass_in_silo()[0]
        from collections import deque

        self._hist = deque([(s.t, 0.0)])
        self.worst_balance = 0.0
        self.aspect0 = self._quality()[1]
        self.flow = []  # (t, rate) samples

    def _axis_top_z(self) -> float:
        x = self.model.sm.mesh.geometry.x
        z = float(x[self._axis_top, 1].max()) if self._axis_top.size else -np.inf
        return self.model.sm.comm.allreduce(z, op=MPI.MAX)

    def _mass_in_silo(self) -> tuple[float, float]:
        """(mass in the silo, mass below the outlet plane) over all ranks (kg)."""
        from silo_dolfinx.ale.remap import qp_volumes

        s = self.model.solver
        x = np.ascontiguousarray(self.model.sm.mesh.geometry.x[:, :2])
        dV = np.zeros(s.n_cells_owned * s.nq)
        qp_volumes(x, self._cn_t, np.ascontiguousarray(s.forms.points, dtype=float),
                   np.ascontiguousarray(s.forms.weights, dtype=float), s.n_cells_owned, dV)
        m = (s.rho * dV).reshape(-1, s.nq).sum(axis=1)
        below = x[self._cn_t].mean(axis=1)[:, 1] < 0.0
        tot = self.model.sm.comm.allreduce(np.array([m[~below].sum(), m[below].sum()]), op=MPI.SUM)
        return float(tot[0]), float(tot[1])

    def _quality(self) -> tuple[float, float]:
        from silo_dolfinx.geometry.quality import worst_cells

        x = self.model.sm.mesh.geometry.x
        s_, a = worst_cells(x, self._cn, self._orient, self._cn.shape[0])
        c = self.model.sm.comm
        return c.allreduce(s_, op=MPI.MIN), c.allreduce(a, op=MPI.MAX)

    def sample(self) -> None:
        from dolfinx import fem, la

        s = self.model.solver
        inside, below = self._mass_in_silo()
        out = self.ale.totals()["discharged_mass"] if self.ale is not None else below
        # over a trailing window: the remap counts outflow in packets (every `frequency` steps),
        # so the difference between two consecutive samples aliases
        self._hist.append((s.t, out))
        while len(self._hist) > 2 and self._hist[1][0] <= s.t - self.RATE_WINDOW:
            self._hist.popleft()
        t_prev, out_prev = self._hist[0]
        rate = (out - out_prev) / (s.t - t_prev) if s.t > t_prev else 0.0
        self._area.array[:] = 0.0
        fem.assemble_vector(self._area.array, self._form)
        self._area.scatter_reverse(la.InsertMode.add)
        w = self._area.array.reshape(-1, 2)[: s.n_owned, 0]
        vz = s.v[: s.n_owned, 1]
        num = self.model.sm.comm.allreduce(np.array([float(np.dot(w, -vz)), float(w.sum())]), op=MPI.SUM)
        v_mean = num[0] / num[1] if num[1] > 0 else 0.0
        err = (self.mass0 - inside - (out if self.ale is not None else 0.0)) / self.mass0
        self.worst_balance = max(self.worst_balance, abs(err))
        nominal = self.model.scene.material.density * num[0]  # ρ0 ∫ −v_z dA
        self.outlet_csv.write([s.t, out, inside, rate, v_mean, err, nominal, s.dt_prev])
        smin, amax = self._quality()
        self.mesh_csv.write([s.t, self._z_top0 - self._axis_top_z(), smin, amax])
        self.flow.append((s.t, rate, v_mean, amax, out, nominal))

    def summary(self) -> dict:
        d = {"mass_at_opening": self.mass0, "mass_balance_error_max": self.worst_balance}
        if self.flow:
            f = np.array(self.flow)
            t = f[:, 0] - self.t0
            late = t >= 0.5 * t[-1]  # the second half: past the start-up transient
            i0 = int(np.argmax(late))
            span = f[-1, 0] - f[i0, 0]
            d.update(mean_mass_flow_rate_second_half=float((f[-1, 4] - f[i0, 4]) / span) if span > 0 else 0.0,
                     mean_outlet_velocity_second_half=float(f[late, 2].mean()),
                     mean_nominal_mass_flow_rate_second_half=float(f[late, 5].mean()),
                     initial_max_aspect_ratio=self.aspect0, final_max_aspect_ratio=float(f[-1, 3]))
        if self.ale is not None:
            d["ale"] = self.ale.totals()
            if self.ale.tracers is not None:
                d["tracers"] = self._write_tracers()
        return d

    def _write_tracers(self) -> dict:
        """tracers.csv: one row per tracer: id, row (seeding line, 0 = lowest), r0, z0 (seed),
        r, z (now; empty once discharged), discharged_at (s; empty while inside)."""
        g = self.ale.tracers.gather()  # collective
        comm = self.model.sm.comm
        if g is None:
            return comm.bcast(None, root=0)
        rows = [[int(i), int(k), *p0, *p, ""] for i, k, p0, p in zip(g["id"], g["row"], g["initial"], g["xy"])]
        rows += [[int(i), int(k), *p0, "", "", float(t)]
                 for i, k, p0, t in zip(g["out_id"], g["out_row"], g["out_initial"], g["out_t"])]
        self.results.write_rows("tracers.csv", ["id", "row", "r0", "z0", "r", "z", "discharged_at"],
                                sorted(rows, key=lambda r: r[0]))
        return comm.bcast({"seeded": len(rows), "inside": int(g["id"].size), "discharged": int(g["out_id"].size)},
                          root=0)
