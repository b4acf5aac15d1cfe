"""Arbitrary Lagrangian–Eulerian discharge (thesis ch. 3.2): smooth, then remap.

The explicit solver takes Lagrangian steps (the mesh moves with the material). Every
``frequency`` steps, :meth:`ALE.apply` runs the two other stages of the operator split:

1. **smoothing** (:mod:`.smoothing`): new node positions — outlet Eulerian, walls and top
   following the material normal to them and relaxed along them, interior smoothed by the
   Laplacian/mid-area averages of eqs. 3-4, 3-5;
2. **remap** (:mod:`.remap`): quadrature data (stress, plastic strain, any material state,
   density) and nodal velocity carried from the Lagrangian mesh to the smoothed one by a
   conservative, bound-preserving flux-form remap; material crossing the outlet leaves.

The free surface's nodes are placed on the material surface keeping the volume under it, and
with ``max_surface_slope`` > 0 a surface steeper than that slumps (:mod:`.slump`); after the
remap the volume each top edge swept moves along the top row as material, so that every top
cell keeps its density.

Then the solver rebuilds what depends on mesh and state (lumped mass by dolfinx assembly,
volumes, stable Δt, internal force) and the model its loads (gravity on the new mass). The
energy the remap removes (upwinding) and the energy the discharged material carries away
are booked in the energy balance. :class:`Tracers` follow material points for flow patterns.

Cell data move as cell means (mass-weighted) with each cell's internal variation restored
within local bounds (:func:`.remap.redistribute`), so a mesh that does not move is left
exactly as it was.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI

from silo_dolfinx.ale.remap import (RemapError, RemapReport, Remapper, cell_state, cell_volume_density,
                                    redistribute)
from silo_dolfinx.geometry.cells import qp_volumes, tensor_nodes
from silo_dolfinx.ale.slump import TopRow
from silo_dolfinx.ale.smoothing import Smoother
from silo_dolfinx.ale.tracers import Tracers

__all__ = ["ALE", "Remapper", "Smoother", "Tracers", "RemapReport"]


@dataclass
class ALEStats:
    remaps: int = 0
    substeps: int = 0
    max_courant: float = 0.0
    outflow_mass: float = 0.0  # kg (rank-local; :meth:`ALE.totals` sums)
    outflow_momentum_z: float = 0.0
    seconds: dict = field(default_factory=lambda: {"smoothing": 0.0, "remap": 0.0, "rebuild": 0.0})


class ALE:
    """Smoothing + remap of a :class:`~silo_dolfinx.simulation.SiloModel` during discharge; a
    post-step hook of the time loop (:meth:`before_step`, :meth:`after_step`)."""

    CHECKPOINT = ("_steps0", "stats")

    def __init__(self, model, config):
        """``config``: the scene's [ale] section (frequency, sweeps, laplacian_weight,
        mid_area_weight, remap_order, predictor, smoothing_objective, tracer_rows/columns)."""
        s = model.solver
        if s.active_cells.size != s.n_cells_owned:
            raise RuntimeError("ALE needs every cell active (it starts with the discharge)")
        self.model = model
        self.solver = s
        self.mesh = model.sm.mesh
        a = config
        self.frequency = a.frequency
        self.smoother = Smoother(model.sm, model.contact_wall_open, laplacian_weight=a.laplacian_weight,
                                 mid_area_weight=a.mid_area_weight, sweeps=a.sweeps, predictor=a.predictor,
                                 objective=a.smoothing_objective, max_surface_slope=a.max_surface_slope)
        self.remapper = Remapper(self.mesh, model.sm.facets("outlet"), a.remap_order)
        self.cn_tensor = tensor_nodes(self.mesh, s.n_cells_owned)
        self.fields = [("sig", 4)] + list(s.point_fields.items())  # the law's state, the hourglass force
        self.k = sum(c for _, c in self.fields)
        n = s.n_cells_owned * s.nq
        no = s.n_cells_owned
        self._dV = np.zeros(n)
        self._means, self._lo, self._hi = np.zeros((no, self.k)), np.zeros((no, self.k)), np.zeros((no, self.k))
        self._vol, self._rho = np.zeros(no), np.zeros(no)
        self._dsig = np.zeros((n, 4))
        # velocity dofs numbered as the geometry nodes (usual for P1): remap the solver's array itself
        self._same_numbering = bool(np.array_equal(s.node_dof, np.arange(s.node_dof.size)))
        # cells that touch the outlet: the only ones whose energy can leave
        f2c = self.mesh.topology.connectivity(1, 2)
        outlet = model.sm.facets("outlet")
        cells = np.concatenate([f2c.links(f) for f in outlet]) if len(outlet) else np.zeros(0, np.int32)
        self._outlet_cells = np.unique(cells[cells < no]).astype(np.int64)  # empty on ranks away from it
        self._outlet_points = (self._outlet_cells[:, None] * s.nq + np.arange(s.nq)).ravel()
        self._top_row = TopRow(model.sm, self.smoother, no)
        self.stats = ALEStats()
        self.tracers = Tracers(self, a.tracer_rows, a.tracer_columns) if a.tracer_rows * a.tracer_columns > 0 else None
        self.followers: list[Tracers] = []  # material points of the outputs (``follow``)
        self._steps0 = s.steps

    def take_over(self, old: ALE) -> dict:
        """Go on from ``old``, the ALE of the mesh this one's replaced (a rezone): its counters,
        its tracers and material points carried onto this mesh (collective). Returns the
        carried material point of each of ``old``'s, by ``id``."""
        self.stats = old.stats
        self.smoother.backoffs = old.smoother.backoffs
        if old.tracers is not None:
            self.tracers = old.tracers.carried(self)
        self.followers = [f.carried(self) for f in old.followers]
        return {id(f): g for f, g in zip(old.followers, self.followers)}

    def follow(self, points: np.ndarray) -> Tracers:
        """Material points seeded now at ``points`` and carried through every remap."""
        self.followers.append(Tracers(self, 0, 0, points))
        return self.followers[-1]

    def due(self) -> bool:
        return (self.solver.steps - self._steps0) % self.frequency == 0

    def due_next(self) -> bool:
        """Whether the next step ends with a remap (its internal force can then be skipped)."""
        return (self.solver.steps + 1 - self._steps0) % self.frequency == 0

    # ------------------------------------------------------------------ the post-step hook
    def before_step(self) -> None:
        """A step that ends with a remap skips its internal force: the remap's rebuild
        assembles it on the new mesh anyway (the solver's ``defer_force``; if no remap
        follows after all, the solver assembles it before it is used)."""
        self.solver.defer_force = self.due_next()

    def after_step(self) -> None:
        """Every ``frequency`` steps: smooth + remap."""
        if self.due():
            self.apply()

    # ------------------------------------------------------------------ the split step
    def apply(self) -> RemapReport:
        """Smooth the mesh and remap the state onto it (between two solver steps)."""
        s = self.solver
        nq = s.nq
        x = self.mesh.geometry.x
        xL = np.ascontiguousarray(x[:, :2])
        t0 = time.perf_counter()
        xS = self.smoother.smooth(xL)
        t1 = time.perf_counter()

        # cell means of the quadrature data at the Lagrangian positions
        no = s.n_cells_owned
        qp_volumes(xL, self.cn_tensor, s.forms.points, s.forms.weights, no, self._dV)
        means, lo, hi, rho = self._means, self._lo, self._hi, self._rho
        cell_volume_density(s.rho, nq, self._dV, self._vol, rho)
        for j0, a in self._field_arrays():
            cell_state(a, nq, self._dV, self._vol, j0, means, lo, hi)
        v = s.v if self._same_numbering else np.ascontiguousarray(s.v[s.node_dof])  # remapped in place
        before = s.mechanical_energy_local(increment=self._dsig)  # and the last step's stress increment
        elastic_density = self._elastic_per_mass()  # J/kg of the outlet cells, for what flows out

        try:
            rep = self.remapper.remap(xL, xS, rho, means, v, bounds=(lo, hi))
        except RemapError as err:  # on every rank: the run stops where it is, its results readable
            from silo_dolfinx.solver import InstabilityError

            raise InstabilityError(f"at t = {s.t:.6g} s {err}: the mesh has drifted far from the material "
                                   f"(Δt {s.dt:.3g} s, {self.frequency} steps per remap). Fix: [ale] frequency "
                                   "smaller (remap more often), or see the Δt diagnosis if Δt has fallen.") from err
        # the volumes the top edges swept (surface placement, slump) move along the top row as material
        self._top_row.transfer(self.smoother.top_swept, self.remapper.last_volumes, rho, means, (lo, hi))
        t2 = time.perf_counter()

        # write back: mesh, quadrature data, velocity; rebuild what depends on them
        x[:, :2] = xS
        qp_volumes(xS, self.cn_tensor, s.forms.points, s.forms.weights, no, self._dV)
        for j0, a in self._field_arrays():
            redistribute(a, nq, self._dV, means, lo, hi, j0)
        s.rho.reshape(-1, nq)[:] = rho[:, None]
        if not self._same_numbering:
            s.v[s.node_dof] = v
        deferred, elastic = s.after_remap(self._dV, self._dsig if s.steps > 0 else None)
        self.model.after_remap()
        for tr in ([self.tracers] if self.tracers is not None else []) + self.followers:
            tr.relocate(xL, xS)
        out_el = float(np.dot(rep.outflow_cells[self._outlet_cells], elastic_density))
        out = rep.outflow_kinetic + out_el
        s.energy.outflow += out
        s.energy.remap += before - (s.kinetic_energy_local() + elastic) - out
        t3 = time.perf_counter()

        st = self.stats
        st.remaps += 1
        st.substeps += rep.substeps
        st.max_courant = max(st.max_courant, rep.courant)
        st.outflow_mass += rep.outflow_mass
        st.outflow_momentum_z += rep.outflow_momentum[1]
        st.seconds["smoothing"] += t1 - t0
        st.seconds["remap"] += t2 - t1
        st.seconds["rebuild"] += t3 - t2 - deferred  # the deferred internal force is the Lagrangian step's
        return rep

    def _field_arrays(self):
        """(first column in the remapped (n, k) cell arrays, (n·nq, c) view of the solver's
        current array) for every remapped quadrature field: the stress and the material's
        state. Fetched each time: the solver swaps its double buffers every step."""
        s = self.solver
        j0 = 0
        for name, c in self.fields:
            yield j0, (s.sig if name == "sig" else s.state[name]).reshape(-1, c)
            j0 += c

    def _elastic_per_mass(self) -> np.ndarray:
        """Elastic energy per unit mass of the owned cells at the outlet (J/kg)."""
        s = self.solver
        nq = s.nq
        c = self._outlet_cells
        idx = self._outlet_points
        e = s.material.elastic_energy_density(s.sig[idx]) * self._dV[idx]
        return e.reshape(-1, nq).sum(axis=1) / np.maximum(self._rho[c] * self._vol[c], 1e-300)

    # ------------------------------------------------------------------ diagnostics
    def totals(self) -> dict:
        """Global counters (collective)."""
        c = self.solver.comm
        st = self.stats
        return {"remaps": st.remaps, "substeps": st.substeps, "max_courant": st.max_courant,
                "discharged_mass": c.allreduce(st.outflow_mass, op=MPI.SUM),
                "smoothing_backoffs": self.smoother.backoffs,
                "seconds": {k: c.allreduce(v, op=MPI.MAX) for k, v in st.seconds.items()}}

