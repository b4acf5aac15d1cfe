"""The output streams of a running model, each built only when the scene asks for it.

=================  ==============================================  ==========================
stream             when it exists                                  writes
=================  ==============================================  ==========================
energy history     always                                          energy.csv
wall history       output.stations not empty                       wall_history.csv
point history      output.points not empty                         point_history.csv
shear zones        output.zone_bands > 0 and a plastic solid       shear_zones.csv
wall profiles      always (end of each stage)                      wall_profile_<stage>.csv
fields             output.field_interval > 0                       fields/ (VTX, snapshots)
discharge monitor  in a discharge                                  outlet.csv, mesh_quality.csv,
                                                                   tracers.csv (with tracers)
=================  ==============================================  ==========================

:class:`Outputs` samples the history streams at ``output.history_rate`` and the fields every
``output.field_interval`` of simulated time, and all of them at the end of each stage. Every
sample first checks that velocity and stress are finite: nothing non-finite is ever written.
Column names come from :mod:`silo_dolfinx.output.schema`.
"""

from __future__ import annotations

from collections import deque
from pathlib import Path

import numpy as np
from mpi4py import MPI

from silo_dolfinx._jit_cache import numba
from silo_dolfinx.geometry.mesher import FACET_TAGS
from silo_dolfinx.output import schema
from silo_dolfinx.output.writer import Results


class Outputs:
    """The scheduled output of a model into a :class:`Results` folder."""

    CHECKPOINT = ("next_history", "last_sample")

    def __init__(self, model, results: Results):
        self.model, self.results = model, results
        out = model.scene.output
        self.dt_history = 1.0 / out.history_rate
        self.next_history = 0.0
        self.energy = EnergyHistory(model, results)
        self.history: list = [self.energy]
        if len(out.stations):
            self.history.append(WallHistory(model, results))
        if len(out.points):
            self.history.append(PointHistory(model, results))
        if out.zone_bands > 0 and model.material.plastic:
            self.history.append(ShearZones(model, results))
        self.fields = FieldOutput(model, results, out.field_interval) if out.field_interval > 0 else None
        self.monitor = None  # the discharge's outlet and mesh-quality monitor
        self.last_sample = None  # simulated time of the last history sample
        self.muted = False  # nothing is written while a resumed run replays its set-up

    @property
    def max_abs_balance(self) -> float:
        return self.energy.max_abs_balance

    def maybe(self, stage: str) -> None:
        """Sample what is due at the current time."""
        if self.muted:
            return
        t = self.model.solver.t
        if t + 1e-12 >= self.next_history:
            self.sample(stage)
            while self.next_history <= t + 1e-12:
                self.next_history += self.dt_history
        if self.fields is not None:
            self.fields.maybe(t)

    def sample(self, stage: str) -> None:
        s = self.model.solver
        if s.t == self.last_sample:
            return  # a stage end that coincides with a periodic sample
        self.last_sample = s.t
        s.check_finite()  # nothing non-finite is ever written
        for stream in self.history:
            stream.sample(stage)
        self.results.heartbeat(stage=stage, t_reached=s.t, steps=s.steps)

    def stage_end(self, stage: str) -> None:
        """History sample, wall profile and fields at the end of a stage."""
        self.sample(stage)
        w = self.model.wall_state()
        if w is not None:
            f = schema.WALL_PROFILE
            self.results.write_table(f, np.column_stack([w[k] for k in f.names]).tolist(), stage=stage)
        if self.fields is not None:
            self.fields.at_stage_end(self.model.solver.t)

    def begin_discharge(self, model) -> None:
        self.monitor = DischargeMonitor(model, self.results, model.ale)
        self.history.append(self.monitor)

    def after_rezone(self, model, carried: dict, k: int) -> None:
        """The model moved to a new mesh (its ``k``-th rezone): every stream built on the old
        one is built again; ``carried`` maps each old material point to its carried self."""
        for stream in self.history:
            if hasattr(stream, "after_rezone"):
                stream.after_rezone(model, carried)
        if self.fields is not None:
            self.fields.after_rezone(k)

    def discharge_summary(self) -> dict:
        return self.monitor.summary() if self.monitor is not None else {}

    def close(self) -> None:
        if self.fields is not None:
            self.fields.close()


class EnergyHistory:
    """energy.csv: the ledger summed over ranks, its balance and relative error."""

    CHECKPOINT = ("max_abs_balance",)

    def __init__(self, model, results: Results):
        self.solver = model.solver
        self.csv = results.table(schema.ENERGY)
        self.max_abs_balance = 0.0  # largest |balance| seen, J

    def sample(self, stage: str) -> None:
        s = self.solver
        e = s.global_energy()
        self.max_abs_balance = max(self.max_abs_balance, abs(e.balance))
        self.csv.write([s.t, stage, e.kinetic, e.elastic, e.plastic, e.viscous, e.damping, e.remap, e.outflow,
                        e.initial, e.hourglass, e.gravity, e.external, e.contact, e.balance,
                        e.relative_error(s.energy_scale)])


class WallHistory:
    """wall_history.csv: pressures and slip at the wall stations (interpolated along s), each
    sample the mean over the interval since the previous one (``output.history_sampling =
    "mean"``) or the step at the sample (``"instant"``)."""

    CHECKPOINT = ()

    def __init__(self, model, results: Results):
        self.model = model
        out = model.scene.output
        st = np.asarray(out.stations, float)
        self.station_s = model.outline.wall.s_at_height(st) if out.station_coordinate == "z" else st
        self.interval_mean = out.history_sampling == "mean"
        self.csv = results.table(schema.WALL_HISTORY)

    def sample(self, stage: str) -> None:
        w = self.model.wall_state(self.interval_mean)
        if w is None or not w["s"].size:
            return
        cols = np.column_stack([self.station_s, *(np.interp(self.station_s, w["s"], w[name])
                                                  for name in schema.WALL_HISTORY.names[3:])])
        self.csv.write(*_indexed_rows(self.model.solver.t, cols))


def _indexed_rows(t: float, cols: np.ndarray):
    """Rows (t, index, *values) of a per-station or per-point history sample, as Python
    numbers (one tolist(), no per-value numpy scalars)."""
    return ([t, k, *row] for k, row in enumerate(cols.tolist()))


class PointHistory:
    """point_history.csv: stress at interior points (output.points), each the mean of the cell
    that holds it. Fixed points (``output.point_motion = "fixed"``, the thesis') are located
    afresh at every sample, the mesh moving under them. Material points (``"material"``) stay
    where they are until the outlet opens and are then carried with the solid: between remaps
    a point keeps its cell and reference coordinates (the mesh moves with the material) and
    ALE relocates it at every remap as it does its tracers; one that leaves through the
    outlet has no value from then on.

    With ``output.history_sampling = "mean"`` a sample is the mean over the accepted steps
    since the previous one (a post-step hook adds each step's cell means, Δt-weighted) in the
    cells located at the previous sample - the mesh moves a small fraction of a cell in one
    interval; an activation of cells (a filling layer) relocates and restarts the interval."""

    def __init__(self, model, results: Results):
        from silo_dolfinx.geometry.cells import tensor_nodes

        self.model = model
        self.points = np.asarray(model.scene.output.points, float).reshape(-1, 2)
        self.material = model.scene.output.point_motion == "material"
        self.follower = None  # the material points once the discharge has started
        s = model.solver
        self.cn = tensor_nodes(model.sm.mesh, s.n_cells_owned)
        self.csv = results.table(schema.POINT_HISTORY)
        self._x = np.zeros((model.sm.mesh.geometry.x.shape[0], 2))
        n = self.points.shape[0]
        self.interval_mean = model.scene.output.history_sampling == "mean"
        self._acc = np.zeros((n, 6))  # ∫ (cell-mean σ, v) dt over the interval, this rank's points
        self._span = np.zeros(1)  # ∫ dt
        self._where = None  # (points this rank supplies, their active-cell rows, their cells, positions, owners)
        self._q = None  # the solver's quadrature data the rows index (replaced when cells activate)
        if self.interval_mean:
            model.hooks.append(self)

    def checkpoint_state(self) -> dict:
        """The material points, once seeded, and the interval so far (:mod:`silo_dolfinx.checkpoint`)."""
        from silo_dolfinx.checkpoint import capture

        return {"follower": None if self.follower is None else capture(self.follower),
                "acc": self._acc.copy(), "span": self._span.copy()}

    def restore_state(self, saved: dict) -> None:
        """Seeded again (collective) if they had been, then put where they were."""
        from silo_dolfinx.checkpoint import restore

        if saved["follower"] is not None:
            self.follower = self.follower or self._seed()
            restore(self.follower, saved["follower"])
        self._acc[:], self._span[:] = saved["acc"], saved["span"]
        self._locate()

    def _cells(self) -> tuple[np.ndarray, np.ndarray]:
        """(owned cell or −1, position) of every point on this rank."""
        from silo_dolfinx.ale.tracers import locate_points

        if self.follower is None:
            return locate_points(self._x, self.cn, self.model.solver.n_cells_owned, self.points)[0], self.points
        f = self.follower
        cell, pos = np.full(self.points.shape[0], -1, np.int64), np.full(self.points.shape, np.nan)
        cell[f.id], pos[f.id] = f.cell, f.positions(self._x)
        return cell, pos

    def _locate(self) -> None:
        """Which rank supplies each point, from which active-cell row (collective: the lowest
        rank that finds a point)."""
        s, comm = self.model.solver, self.model.sm.comm
        self._x[:] = self.model.sm.mesh.geometry.x[:, :2]
        cell, pos = self._cells()
        active = s.active_cells
        at = np.minimum(np.searchsorted(active, cell), max(active.size - 1, 0))
        found = (cell >= 0) & (active[at] == cell) if active.size else np.zeros(cell.size, bool)
        owner = np.where(found, comm.rank, comm.size).astype(np.int64)
        comm.Allreduce(MPI.IN_PLACE, owner, op=MPI.MIN)
        mine = np.nonzero(found & (owner == comm.rank))[0]
        self._where = (mine, at[mine], cell[mine], pos, owner)
        self._q = s.q

    def _add_cell_means(self, acc: np.ndarray, weight: float) -> None:
        """acc[point] += weight × (the located cell's mean stress, mean nodal velocity) now, for
        the points this rank supplies (one compiled call: it runs after every step)."""
        s = self.model.solver
        mine, rows, cells = self._where[:3]
        _add_cell_means(acc, (mine, rows, cells), (s.sig.reshape(-1, 4), s.dV, s.nq),
                        (s.nodes.v, s.node_dof, self.cn), weight)

    # the post-step hook (interval means)
    def before_step(self) -> None:
        pass

    def after_step(self) -> None:
        """Add the accepted step's cell means, weighted by its Δt, to the interval."""
        s = self.model.solver
        if self._q is not s.q:  # cells were activated: the rows moved (collective, every rank alike)
            self._locate()
            self._acc[:], self._span[:] = 0.0, 0.0
        self._add_cell_means(self._acc, s.dt_prev)
        self._span += s.dt_prev

    def values(self) -> np.ndarray:
        """(n_points, 8): position, cell-mean stress and cell-mean velocity (the mean of the
        cell's four nodes) of every point - now, or over the interval since the last sample -
        NaN where no active cell holds one (collective)."""
        comm = self.model.sm.comm
        averaged = self.interval_mean and self._span[0] > 0.0 and self._q is self.model.solver.q
        if not averaged:
            self._locate()
        mine, _, _, pos, owner = self._where
        out = np.zeros((self.points.shape[0], 9))  # position, stress, velocity, 1 where a rank has the point
        if averaged:
            out[mine, 2:8] = self._acc[mine] / self._span[0]
        else:
            now = np.zeros((self.points.shape[0], 6))
            self._add_cell_means(now, 1.0)
            out[mine, 2:8] = now[mine]
        if averaged and self.follower is not None:
            # a material point is written where it is now, by the rank that holds it now (an ALE
            # remap may have carried it across a partition boundary during the interval)
            self._x[:] = self.model.sm.mesh.geometry.x[:, :2]
            pos = self._cells()[1]
            held = np.nonzero(np.isfinite(pos[:, 0]))[0]
        else:
            held = mine
        out[held, :2] = pos[held]
        out[held, 8] = 1.0
        comm.Allreduce(MPI.IN_PLACE, out, op=MPI.SUM)
        out[(owner == comm.size) | (out[:, 8] == 0.0)] = np.nan
        if self.follower is None:
            out[:, :2] = self.points  # a fixed point has its position whether or not a cell holds it
        return out[:, :8]

    def sample(self, stage: str) -> None:
        from silo_dolfinx.invariants import p_q, stress_ratio

        if self.material and self.follower is None and stage == "discharge":
            self.follower = self._seed()  # where the fixed points are: the interval's cells stand
        v = self.values()
        if self.interval_mean:  # the next interval: where the points are now
            self._locate()
            self._acc[:], self._span[:] = 0.0, 0.0
        p, q = p_q(v[:, 2:6])
        ratio = stress_ratio(p, q, self.model.p_stress_free)
        cols = np.column_stack([v[:, :6], p, q, ratio, v[:, 6:]])
        self.csv.write(*_indexed_rows(self.model.solver.t, cols))

    def after_rezone(self, model, carried: dict) -> None:
        """A new mesh: its cells, the material points carried onto it (the interval restarts
        at the next step: the solver's quadrature data are new)."""
        from silo_dolfinx.geometry.cells import tensor_nodes

        self.cn = tensor_nodes(model.sm.mesh, model.solver.n_cells_owned)
        self._x = np.zeros((model.sm.mesh.geometry.x.shape[0], 2))
        if self.follower is not None:
            self.follower = carried[id(self.follower)]

    def _seed(self):
        """The material points, seeded where the fixed points are now."""
        ale = self.model.ale
        if ale is not None:
            return ale.follow(self.points)
        self._x[:] = self.model.sm.mesh.geometry.x[:, :2]
        return _Pinned(self._x, self.cn, self.model.solver.n_cells_owned, self.points, self.model.sm.comm)


@numba.njit(cache=True)
def _add_cell_means(acc, where, stress, nodal, weight):
    """acc[k] += weight × (volume-weighted mean stress of cell row r, mean velocity of its four
    nodes) for (k, r, cell) in where = (points, active-cell rows, cells); stress = (σ (n·nq,
    4), point volumes, nq); nodal = (v (nodes, 2), node → velocity block, cell → nodes)."""
    points, rows, cells = where
    sig, dV, nq = stress
    v, node_dof, cn = nodal
    for i in range(points.shape[0]):
        k, r = points[i], rows[i]
        vol = 0.0
        for q in range(nq):
            vol += dV[r * nq + q]
        for j in range(4):
            m = 0.0
            for q in range(nq):
                m += sig[r * nq + q, j] * dV[r * nq + q]
            acc[k, j] += weight * m / vol
        for a in range(4):
            d = node_dof[cn[cells[i], a]]
            acc[k, 4] += 0.25 * weight * v[d, 0]
            acc[k, 5] += 0.25 * weight * v[d, 1]


class ShearZones:
    """shear_zones.csv: where the solid is failing, per height band - the share of each band's
    loaded solid at yield (the law's :meth:`~silo_dolfinx.materials.base.Material.mobilised_strength`
    ≥ ``YIELDED``), the mean share of its strength mobilised and the share separated - as
    instants at the history rate (one compiled pass over the quadrature points and one
    reduction a sample). The bands stand still: the thesis' contours of q/p (Figs. 4-19,
    8-13) read as a map in height and time, on which a zone that moves is seen moving."""

    YIELDED = 0.99  # on the surface to within the 1 % a viscoplastic point relaxes by in ~τ/100
    CHECKPOINT = ()

    def __init__(self, model, results: Results):
        self.model = model
        n = model.scene.output.zone_bands
        z = model.sm.mesh.geometry.x[:, 1]
        bottom = model.sm.comm.allreduce(float(z.min()) if z.size else np.inf, op=MPI.MIN)
        self.edges = np.linspace(bottom, model.outline.fill_height, n + 1)
        self._mobilised = np.empty(0)
        self._sums = np.zeros((4, n))  # volume, separated, yielded and Σ mobilised·dV of the loaded, per band
        self.csv = results.table(schema.SHEAR_ZONES)

    def sample(self, stage: str) -> None:
        m = self.model
        s = m.solver
        sig = s.sig.reshape(-1, 4)
        if self._mobilised.size != sig.shape[0]:  # cells were activated (a layer) or the mesh replaced
            self._mobilised = np.empty(sig.shape[0])
        m.material.mobilised_strength(sig, self._mobilised)
        self._sums[:] = 0.0
        _band_sums(m.sm.mesh.geometry.x, s.active_cell_nodes, (sig, s.dV, s.nq, self._mobilised),
                   (self.edges, m.p_stress_free, self.YIELDED), self._sums)
        m.sm.comm.Allreduce(MPI.IN_PLACE, self._sums, op=MPI.SUM)
        volume, separated, yielded, mobilised = self._sums
        loaded = volume - separated
        with np.errstate(divide="ignore", invalid="ignore"):
            cols = np.column_stack([self.edges[:-1], self.edges[1:], volume, separated / volume, yielded / loaded,
                                    mobilised / loaded])
        cols[volume <= 0.0, 3:] = np.nan
        cols[loaded <= 0.0, 4:] = np.nan
        self.csv.write(*_indexed_rows(s.t, cols))


@numba.njit(cache=True)
def _band_sums(x, cells, points, bands, out):
    """out[:, band] += (volume, separated volume, yielded volume, Σ mobilised · dV over the
    loaded) of the quadrature points of ``cells`` (n, 4 nodes), each in the band of its cell's
    centroid; points = (σ (n·nq, 4), dV, nq, mobilised strength), bands = (edges, the
    stress-free pressure, the mobilised strength counted as yield)."""
    sig, dV, nq, mob = points
    edges, p_free, yielded = bands
    n = edges.size - 1
    z0, dz = edges[0], (edges[-1] - edges[0]) / n
    for c in range(cells.shape[0]):
        zc = 0.25 * (x[cells[c, 0], 1] + x[cells[c, 1], 1] + x[cells[c, 2], 1] + x[cells[c, 3], 1])
        k = int(np.floor((zc - z0) / dz))
        if k < 0 or k >= n:
            continue
        for q in range(nq):
            i = c * nq + q
            v = dV[i]
            out[0, k] += v
            p = -(sig[i, 0] + sig[i, 1] + sig[i, 2]) / 3.0
            if p <= p_free or not np.isfinite(mob[i]):
                out[1, k] += v
                continue
            if mob[i] >= yielded:
                out[2, k] += v
            out[3, k] += mob[i] * v


class _Pinned:
    """Material points of a Lagrangian mesh: each keeps its cell and (ξ, η) for good."""

    CHECKPOINT = ("id", "cell", "xi")

    def __init__(self, x, cn, n_owned: int, points, comm):
        from silo_dolfinx.ale.tracers import locate_points

        cell, xi = locate_points(x, cn, n_owned, points)
        owner = np.where(cell >= 0, comm.rank, comm.size).astype(np.int64)
        comm.Allreduce(MPI.IN_PLACE, owner, op=MPI.MIN)
        keep = (cell >= 0) & (owner == comm.rank)
        self.id, self.cell, self.xi, self.cn = np.nonzero(keep)[0], cell[keep], xi[keep], cn

    def positions(self, x) -> np.ndarray:
        from silo_dolfinx.ale.tracers import map_points

        return map_points(x, self.cn, self.cell, self.xi)


class FieldOutput:
    """VTX fields every ``interval`` s of simulated time and at each stage end (the writer
    itself is built at the first output; a resumed run writes new VTX files, numbered)."""

    CHECKPOINT = ("next", "_last", "written")

    def __init__(self, model, results: Results, interval: float):
        self.model, self.folder, self.interval = model, results.path("fields"), interval
        # a resumed run's VTX files are nodes_resumed<k>.bp, ..., a rezoned mesh's nodes_rezone<k>.bp
        self.tail = f"_resumed{results.resumed}" if results.resumed else ""
        self.mesh_number = 0
        self.next = 0.0
        self.writer = None
        self.written = 0  # snapshots so far (their numbering continues in a resumed run)
        self._last = None

    def maybe(self, t: float) -> None:
        if t + 1e-12 >= self.next:
            self.write(t)
            while self.next <= t + 1e-12:
                self.next += self.interval

    def at_stage_end(self, t: float) -> None:
        if self._last != t:
            self.write(t)

    def after_rezone(self, k: int) -> None:
        """The ``k``-th rezone: the next fields go into new VTX files, on the new mesh."""
        if self.writer is not None:
            self.writer.close()
        self.writer = None
        self.tail, self.mesh_number = f"_rezone{k}", k

    def write(self, t: float) -> None:
        self.writer = self.writer or FieldWriter(self.model, self.folder, self.tail, self.mesh_number)
        self.writer.write(t, self.written)
        self.written += 1
        self._last = t

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()


class FieldWriter:
    """VTX output for ParaView: nodal velocity and displacement; cell means of the stress, its
    invariants, the density and every scalar state variable the material declares."""

    CELL_FIELDS = ("stress_rr", "stress_zz", "stress_tt", "stress_rz", "p", "q", "q_over_p", "density")

    def __init__(self, model, folder: Path, tail: str = "", mesh_number: int = 0):
        from dolfinx import fem, io

        self.model, self.mesh_number = model, mesh_number  # (the snapshots' ``mesh``: rezones so far)
        s = model.solver
        mesh = model.sm.mesh
        if mesh.comm.rank == 0:
            folder.mkdir(parents=True, exist_ok=True)
        mesh.comm.barrier()
        self.disp = fem.Function(s.V, name="displacement")
        W = fem.functionspace(mesh, ("DG", 0))
        self.state_fields = [k for k, c in s.material.state_fields.items() if c == 1]
        self.cell = {n: fem.Function(W, name=n) for n in list(self.CELL_FIELDS) + self.state_fields}
        self.w_nodes = io.VTXWriter(mesh.comm, folder / f"nodes{tail}.bp", [s.forms.velocity, self.disp], engine="BP4")
        self.w_cells = io.VTXWriter(mesh.comm, folder / f"cells{tail}.bp", list(self.cell.values()), engine="BP4")
        self.folder = folder

    def write(self, t: float, number: int) -> None:
        from silo_dolfinx import kernels
        from silo_dolfinx.invariants import p_q, stress_ratio

        s = self.model.solver
        self.disp.x.array[:] = s.displacement().ravel()
        cells = s.active_cells
        sig = s.sig
        p, q = p_q(sig)
        values = {"stress_rr": sig[:, 0], "stress_zz": sig[:, 1], "stress_tt": sig[:, 2], "stress_rz": sig[:, 3],
                  "p": p, "q": q, "density": s.rho}
        values.update({k: s.state[k] for k in self.state_fields})
        avg = np.zeros(cells.size)
        snapshot = {}
        for name, f in self.cell.items():
            if name == "q_over_p":  # of the cell means (NaN in a stress-free cell: invariants.stress_ratio)
                avg[:] = stress_ratio(snapshot["p"], snapshot["q"], self.model.p_stress_free)
            else:
                kernels.cell_average(np.ascontiguousarray(values[name]), s.dV, s.nq, avg)
            f.x.array[:] = 0.0
            f.x.array[cells] = avg
            f.x.scatter_forward()
            snapshot[name] = avg.copy()
        self.w_nodes.write(t)
        self.w_cells.write(t)
        self._snapshot(t, snapshot, number)

    def _snapshot(self, t: float, cell_values: dict, number: int) -> None:
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
        data = {"t": t, "mesh": self.mesh_number, "corners": np.concatenate([p[0] for p in parts]),
                "node_xy": np.concatenate([p[2] for p in parts]), "node_velocity": np.concatenate([p[3] for p in parts])}
        for name in cell_values:
            data[f"cell_{name}"] = np.concatenate([p[1][name] for p in parts])
        if tracers is not None:
            data.update({f"tracer_{k}": v for k, v in tracers.items()})
        np.savez_compressed(self.folder / f"snapshot_{number:04d}.npz", **data)

    def close(self) -> None:
        self.w_nodes.close()
        self.w_cells.close()


class DischargeMonitor:
    """Outlet flow and mesh quality during the discharge: outlet.csv and mesh_quality.csv
    (columns in :mod:`silo_dolfinx.output.schema`); tracers.csv at the end if ALE has tracers."""

    RATE_WINDOW = 0.05  # s: the mass flow rate is the discharged mass over this trailing window
    CHECKPOINT = ("t0", "mass0", "_hist", "worst_balance", "min_quality", "aspect0", "axis_top_height", "flow",
                  "_z_top0")

    def __init__(self, model, results: Results, ale=None):
        self.model, self.results = model, results
        s = model.solver
        self.outlet_csv = results.table(schema.OUTLET)
        self.mesh_csv = results.table(schema.MESH_QUALITY)
        self.after_rezone(model)
        self.ale = ale
        now = self._measure()
        self._z_top0 = self.axis_top_height = now["axis_top"]
        self.t0 = s.t
        self.mass0 = now["inside"]
        self._hist = deque([(s.t, 0.0)])
        self.worst_balance = 0.0
        self.min_quality, self.aspect0 = now["min_quality"], now["max_aspect"]
        self.flow = []  # (t, rate, v_mean, max aspect ratio, discharged, nominal) samples

    def after_rezone(self, model, carried: dict | None = None) -> None:
        """What the monitor takes from the mesh (again after a rezone; its records go on)."""
        from dolfinx import la

        from silo_dolfinx.geometry.cells import cycle_nodes, orientation, tensor_nodes

        s, mesh = model.solver, model.sm.mesh
        self.ale = model.ale
        self._form = s.forms.tributary_area_form(model.sm.facet_tags, FACET_TAGS["outlet"])
        self._area = la.vector(s.V.dofmap.index_map, 2)
        self._cn_t = tensor_nodes(mesh, s.n_cells_owned)
        self._cn = cycle_nodes(mesh, s.n_cells_owned)
        self._orient = orientation(mesh.geometry.x, self._cn)
        self._axis_top = np.intersect1d(model.sm.nodes_on("top"), model.sm.nodes_on("axis"))
        self._dV = np.zeros(s.n_cells_owned * s.nq)  # work array of _measure (at the history rate)
        if carried is not None:  # the new mesh's worst cell (the rezone and the stop test read it)
            self.min_quality = self._measure()["min_quality"]

    def _measure(self) -> dict[str, float]:
        """What a sample reads off the mesh and the state, over all ranks in two reductions (it
        runs at the history rate): the mass in the silo and below the outlet plane, the mass
        the remap has let out, ∫ −v_z dA over the outlet and its area (kg, kg, kg, m³/s, m²);
        the worst cell's scaled Jacobian, the largest aspect ratio, the height of the top's axis
        node."""
        from dolfinx import fem, la

        from silo_dolfinx.geometry.cells import qp_volumes, worst_cells

        s = self.model.solver
        x = self.model.sm.mesh.geometry.x
        qp_volumes(x, self._cn_t, s.forms.points, s.forms.weights, s.n_cells_owned, self._dV)
        inside, below = _mass_split(x, self._cn_t, s.rho, self._dV, s.nq)
        self._area.array[:] = 0.0  # the outlet nodes' tributary areas ∫ N_a dA
        fem.assemble_vector(self._area.array, self._form)
        self._area.scatter_reverse(la.InsertMode.add)
        w = self._area.array.reshape(-1, 2)[: s.n_owned, 0]
        let_out = self.ale.stats.outflow_mass if self.ale is not None else 0.0
        sums = np.array([inside, below, let_out, float(np.dot(w, -s.v[: s.n_owned, 1])), float(w.sum())])
        smin, amax = worst_cells(x, self._cn, self._orient, self._cn.shape[0])
        top = float(x[self._axis_top, 1].max()) if self._axis_top.size else -np.inf
        comm = self.model.sm.comm
        worst = np.array([-smin, amax, top])
        comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
        comm.Allreduce(MPI.IN_PLACE, worst, op=MPI.MAX)
        return dict(zip(("inside", "below", "let_out", "flux", "area"), sums.tolist())) | {
            "min_quality": -float(worst[0]), "max_aspect": float(worst[1]), "axis_top": float(worst[2])}

    def sample(self, stage: str = "discharge") -> None:
        s = self.model.solver
        now = self._measure()
        inside, flux, area, amax = now["inside"], now["flux"], now["area"], now["max_aspect"]
        out = now["let_out"] if self.ale is not None else now["below"]
        # over a trailing window: the remap counts outflow in packets (every `frequency` steps),
        # so the difference between two consecutive samples aliases
        self._hist.append((s.t, out))
        while len(self._hist) > 2 and self._hist[1][0] <= s.t - self.RATE_WINDOW:
            self._hist.popleft()
        t_prev, out_prev = self._hist[0]
        rate = (out - out_prev) / (s.t - t_prev) if s.t > t_prev else 0.0
        v_mean = flux / area if area > 0 else 0.0
        err = (self.mass0 - inside - (out if self.ale is not None else 0.0)) / self.mass0
        self.worst_balance = max(self.worst_balance, abs(err))
        nominal = self.model.scene.material.density * flux  # ρ0 ∫ −v_z dA
        self.outlet_csv.write([s.t, out, inside, rate, v_mean, err, nominal, s.dt_prev])
        self.min_quality, self.axis_top_height = now["min_quality"], now["axis_top"]
        self.mesh_csv.write([s.t, self._z_top0 - self.axis_top_height, self.min_quality, amax])
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
            if f[-1, 0] > self.t0:  # the mass leaving in each quarter of the stage (an arch: the last near 0)
                from silo_dolfinx.analysis import windowed_mass_flow

                tq, mq = np.concatenate([[self.t0], f[:, 0]]), np.concatenate([[0.0], f[:, 4]])
                d["mass_flow_quarters"] = windowed_mass_flow(tq, mq, 0.25 * (f[-1, 0] - self.t0))[1].tolist()
        if self.ale is not None:
            d["ale"] = self.ale.totals()
            if self.ale.tracers is not None:
                d["tracers"] = self._write_tracers()
        return d

    def _write_tracers(self) -> dict:
        """tracers.csv: one row per tracer (schema.TRACERS)."""
        g = self.ale.tracers.gather()  # collective
        comm = self.model.sm.comm
        if g is None:
            return comm.bcast(None, root=0)
        rows = [[int(i), int(k), *p0, *p, ""] for i, k, p0, p in zip(g["id"], g["row"], g["initial"], g["xy"])]
        rows += [[int(i), int(k), *p0, "", "", float(t)]
                 for i, k, p0, t in zip(g["out_id"], g["out_row"], g["out_initial"], g["out_t"])]
        self.results.write_table(schema.TRACERS, sorted(rows, key=lambda r: r[0]))
        return comm.bcast({"seeded": len(rows), "inside": int(g["id"].size), "discharged": int(g["out_id"].size)},
                          root=0)


@numba.njit(cache=True)
def _mass_split(x, cn, rho, dV, nq):
    """[mass of the cells whose centroid is above z = 0 (in the silo), mass of those below
    (discharged, on a mesh that keeps them)] of the owned cells ``cn`` (n, 4)."""
    out = np.zeros(2)
    for c in range(cn.shape[0]):
        m = 0.0
        for q in range(nq):
            m += rho[c * nq + q] * dV[c * nq + q]
        zc = 0.25 * (x[cn[c, 0], 1] + x[cn[c, 1], 1] + x[cn[c, 2], 1] + x[cn[c, 3], 1])
        out[1 if zc < 0.0 else 0] += m
    return out
