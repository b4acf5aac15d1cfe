"""The effects a scene may ask for, each one object, constructed only when the scene asks.

An effect attaches itself to the solver (a load, a velocity constraint, a contact set, a
per-step hook) and may react to the run's events: a stage begins (:meth:`Effect.begin`), an
ALE remap changed the mesh and the mass (:meth:`Effect.after_remap`). :func:`compose` reads
the scene and builds the list; an effect that is off is never built, so it allocates nothing
and costs nothing (tests/test_simulation.py checks both; benchmarks/effects_cost.py measures
what each one costs when on).

=================  ===========================================  =========================
effect             when it exists                               what it does
=================  ===========================================  =========================
gravity            always (loads.gravity > 0)                   −g ẑ on the active mass,
                                                                each layer's ramped in
surcharge          loads.top_surcharge > 0                      pressure on the top surface
wall               always                                       kinematic wall contact with
                                                                the scene's friction law
gate               until the outlet opens                       the closed outlet: a contact
                                                                surface (smooth/rough/fixed)
outlet_drive       discharge.mode = "controlled"                outlet nodes driven down at
                                                                eq. 3-14's velocity
damping            fill.damping > 0                             −α M v in the stages that
                                                                declare ``damped``
bulk_viscosity     numerics.bulk_viscosity ≠ (0, 0)             linear + quadratic bulk
                                                                viscosity in the closure
ale                ale.enabled and a discharge                  smoothing + remap every N
                                                                steps (a post-step hook)
tracers            ALE on and tracer_rows > 0                   material points (inside ALE)
=================  ===========================================  =========================

Output streams (energy and wall histories, profiles, fields, the outlet monitor) are effects
of the same kind; they live in :mod:`silo_dolfinx.output.streams`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from silo_dolfinx.contact import COULOMB, NONE, STICK, FrictionLaw, FrictionMemory, WallContact
from silo_dolfinx.geometry.mesher import FACET_TAGS
from silo_dolfinx.geometry.wall import Segment, Wall
from silo_dolfinx.solver import VelocityConstraint


def smooth_step(x: float) -> float:
    """Abaqus' smooth step: 0 -> 1 on [0, 1] with zero first and second derivatives at both ends."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    return x**3 * (10.0 - 15.0 * x + 6.0 * x * x)


@dataclass(frozen=True)
class SmoothRamp:
    """Load amplitude 0 -> 1 by :func:`smooth_step` from ``t0`` over ``duration`` (1 throughout if
    the duration is 0). Data, not a closure: the solver's loads are part of a checkpoint."""

    t0: float
    duration: float

    def __call__(self, t: float) -> float:
        return smooth_step((t - self.t0) / self.duration) if self.duration > 0.0 else 1.0


def ramp_velocity(u0: float, ramp_time: float):
    """Eq. 3-14: u(t) = u0/2 (1 − cos(π t/T)) for t < T, then u0."""
    def u(t: float) -> float:
        if ramp_time <= 0.0 or t >= ramp_time:
            return u0
        return 0.5 * u0 * (1.0 - math.cos(math.pi * max(t, 0.0) / ramp_time))

    return u


class Effect:
    """Base: an effect reacts to nothing unless it says so."""

    name = "effect"

    def begin(self, stage) -> None:
        """A stage begins (``stage.name``: fill, store, discharge)."""

    def after_remap(self) -> None:
        """An ALE remap moved the mesh and changed the lumped mass."""


class Gravity(Effect):
    """−g ẑ on the mass of the active cells; a new layer's share ramped by a smooth step."""

    name = "gravity"

    def __init__(self, model):
        self.solver = model.solver
        self.comm = model.sm.comm

    def load(self, cells: np.ndarray, new_cells: np.ndarray | None, amplitude) -> None:
        """Full gravity on the cells already there, ``amplitude(t)`` × gravity on ``new_cells``
        (None: all of ``cells`` are new). Global decisions: every rank takes the same branch."""
        s = self.solver
        old = cells if new_cells is None else np.setdiff1d(cells, new_cells)
        n_old = self.comm.allreduce(old.size if new_cells is not None else 0, op=MPI.SUM)
        if n_old == 0:
            s.add_gravity(amplitude=amplitude)
            return
        s.add_gravity(old.astype(np.int32))
        if self.comm.allreduce(new_cells.size, op=MPI.SUM) > 0:
            s.add_gravity(new_cells, amplitude)

    def after_remap(self) -> None:
        self.solver.replace_gravity()


class Surcharge(Effect):
    """A uniform pressure on the top surface (loads.top_surcharge), applied with the last layer."""

    name = "surcharge"

    def __init__(self, model, pressure: float):
        self.model, self.pressure = model, float(pressure)
        self.force = self._assemble()

    def _assemble(self) -> np.ndarray:
        from dolfinx import fem, la

        sm = self.model.sm
        p = fem.Constant(sm.mesh, self.pressure)
        form = self.model.solver.forms.surcharge_form(sm.facet_tags, FACET_TAGS["top"], p)
        b = fem.assemble_vector(form)
        b.scatter_reverse(la.InsertMode.add)
        b.scatter_forward()
        return b.array.reshape(-1, 2).copy()

    def load(self, amplitude) -> None:
        self.model.solver.add_nodal_force(self.force, amplitude, "surcharge")

    def after_remap(self) -> None:
        """The top moved: the same pressure on its new shape."""
        f = self._assemble()
        for g in self.model.solver.loads:
            if g.kind == "surcharge":
                g.force[:] = f


class WallFriction(Effect):
    """Kinematic contact of the wall nodes with the analytic wall and the scene's friction law
    (none, Coulomb, eq. 7-1; with the limit's memory if the scene gives one). The wall is continued beyond its top (material at the top corner
    always has a wall beside it) and a flat floor, by a quarter of the outlet's shortest edge,
    beyond the outlet edge, with the wall's friction (:data:`LEAD_IN`; a hopper's wall ends at
    the outlet edge: its material leaves along it)."""

    name = "wall"
    #: The wall's continuation past the outlet edge, in outlet edges. The node at the outlet
    #: edge is the one wall node the flow drags past the wall's end. The wall used to end
    #: exactly there, so once friction let it slide a round-off past the edge it fell free and
    #: dragged the edge of the cell beside the outlet through the outlet plane: a flat bottom's
    #: flow switched, at a moment set by round-off, between two rates (ch. 6, h 0.02 m: 0.91
    #: kg/s, Beverloo's, and 2.5 kg/s, a third of it the cell beside the outlet sheared out;
    #: docs/validation/ch6.md). The smoothing puts the node back at every remap, so a short
    #: continuation holds it. With the wall's friction, the node at the joint keeps the
    #: friction it had (frictionless, it lost the floor's friction in filling and changed the
    #: ch. 6 fill's slip-stick realisation). (Held so, the ch. 8.4 flat bottom's coaxial core
    #: fell freely down a one-cell pipe at five cells across the outlet radius, with this length
    #: or half the outlet radius: a resolution effect - at ten cells it settles; docs/validation/ch8.md.)
    LEAD_IN = 0.25

    def __init__(self, model):
        s = model.solver
        self.law = FrictionLaw.from_wall(model.scene.wall)
        wall = model.contact_wall_open
        lead = model.outline.under_outlet_edge(self.LEAD_IN * model.sm.shortest_facet("outlet"))
        if lead is not None and lead.length > 0.0:
            wall = Wall([lead] + list(wall.pieces))
        self.contact = WallContact(wall, model.wall_nodes, s.node_dof[model.wall_nodes], [self.law] * len(wall.pieces),
                                   FrictionMemory.from_wall(model.scene.wall))
        s.contacts.append(self.contact)


class OutletGate(Effect):
    """The closed outlet: a contact surface from past the axis to past the outlet edge,
    applied before the wall (so a node at the outlet edge takes the floor reaction from the
    gate and the wall reaction from the wall). Smooth, rough (the wall's law) or fixed."""

    name = "gate"

    def __init__(self, model):
        s = model.solver
        law = {"smooth": FrictionLaw(NONE), "rough": model.wall.law,
               "fixed": FrictionLaw(COULOMB, mu=STICK)}[model.scene.discharge.gate]
        r0 = model.outline.outlet_radius
        gate = Wall([Segment((-0.5 * r0, 0.0), (1.5 * r0, 0.0))])
        self.contact = WallContact(gate, model.outlet_nodes, s.node_dof[model.outlet_nodes], [law])
        self.solver = s
        s.contacts.insert(0, self.contact)

    def begin(self, stage) -> None:
        if stage.name == "discharge":
            self.remove()

    def remove(self) -> None:
        if self.contact in self.solver.contacts:
            self.solver.contacts.remove(self.contact)


class OutletDrive(Effect):
    """Controlled discharge: from the opening, the outlet nodes move down at eq. 3-14's
    u(t) = u0/2 (1 − cos(π t/T)), then u0. Driven nodes take no part in contact.

    The outlet's edge node is both the feeder's and the wall's, and its motion decides what
    the remap lets out beside it. Driven down with its radial motion free (as it was), the
    solid's pressure pushed it into the wall a little each step, the smoothing put it back,
    and the wall edge beside it swept the difference out of the silo: a leak set by the
    pressure, not by u0 - 1.1-1.4 kg/s from a 2-m wheat bin at any feeder speed (+45 % at
    0.05 m/s, 5× at 0.005). Now, chosen once from the wall's slope at the outlet edge:

    * a wall steeper than 45° (a hopper): the node slides down the wall with the feeder,
      v = −u (dr/dz, 1) - both its edges move along themselves, so what leaves is exactly
      the outlet's ρ u A (the wheat bin at 0.05 and 0.005 m/s: −0.6 %);
    * a flatter wall or a floor: the node goes straight down at u/2, the mean of the feeder
      and the wall at rest beside it. Driven at u, the floor edge beside it swept a sliver
      under the floor that gave +h/R0 (+7 % at 14 cells across the outlet radius, +32 % at 3);
      left on the floor, the outlet's last edge sweeps half its ring, −h/R0; at u/2 the two
      halves cancel: −0.1 % at 14 cells, +4 % at 3 (tests/test_ale.py)."""

    name = "outlet_drive"
    #: The steepest slope dr/dz of the wall at the outlet edge along which the edge node slides
    #: with the feeder (45°); flatter, it moves straight down at half the feeder's speed.
    SLIDE_SLOPE = 1.0

    def __init__(self, model):
        self.model = model
        d = model.scene.discharge
        self.velocity = ramp_velocity(d.velocity, d.ramp_time)
        self.t0 = None  # the opening time, once the discharge has begun

    def begin(self, stage) -> None:
        if stage.name == "discharge":
            self.drive(self.model.solver.t)

    def edge_rule(self) -> tuple[float, float]:
        """(dr/dt, dz/dt) of the outlet's edge node per unit feeder speed u (module docstring),
        from the wall's tangent (dr, dz) at the outlet edge (its normal into the wall turned)."""
        n = self.model.outline.wall.point_normal_at(0.0)[1][0]
        dr, dz = -n[1], n[0]
        if abs(dr) <= self.SLIDE_SLOPE * dz:
            return float(-dr / dz), -1.0
        return 0.0, -0.5

    def drive(self, t0: float) -> None:
        """Drive the outlet nodes from the opening time ``t0`` on (again after a rezone)."""
        m, u = self.model, self.velocity
        s, sm = m.solver, m.sm
        self.t0 = t0
        edge = s.node_dof[np.intersect1d(sm.nodes_on("outlet"), sm.nodes_on("wall"))]
        inner = np.setdiff1d(m.outlet_dofs_all, edge)
        vr, vz = self.edge_rule()
        s.constraints += [VelocityConstraint(inner, 1, lambda t: -u(t - t0)),
                          VelocityConstraint(edge, 0, lambda t: vr * u(t - t0)),
                          VelocityConstraint(edge, 1, lambda t: vz * u(t - t0))]
        for contact in s.contacts:
            contact.exclude(m.outlet_dofs_all)


class Damping(Effect):
    """Mass-proportional damping −α M v in the stages that declare ``damped`` (fill, store):
    ``fill.damping`` is its fraction of critical for the fill's fundamental vertical mode,
    α = 2 ζ ω₁ with ω₁ = π c / (2 H)."""

    name = "damping"

    def __init__(self, model, fraction: float):
        m = model.material
        c = math.sqrt(m.wave_modulus / m.density)
        self.alpha = 2.0 * fraction * math.pi * c / (2.0 * model.outline.fill_height)


class BulkViscosity(Effect):
    """Linear and quadratic bulk viscosity (b1, b2) in the closure and the stable Δt."""

    name = "bulk_viscosity"

    def __init__(self, model, b1: float, b2: float):
        self.coefficients = (b1, b2)


class ALEEffect(Effect):
    """Smoothing + remap every N steps of the discharge (:class:`silo_dolfinx.ale.ALE`),
    built when the discharge begins (it needs every cell active); a post-step hook."""

    name = "ale"

    def __init__(self, model):
        self.model = model
        self.ale = None

    def begin(self, stage) -> None:
        if stage.name != "discharge":
            return
        from silo_dolfinx.ale import ALE

        self.ale = ALE(self.model, self.model.scene.ale)
        self.model.ale = self.ale
        self.model.hooks.append(self.ale)


def compose(model) -> dict[str, Effect]:
    """The effects ``model.scene`` asks for, by name, in the order they act."""
    sc = model.scene
    fx: list[Effect] = [Gravity(model)]
    if sc.loads.top_surcharge > 0.0:
        fx.append(Surcharge(model, sc.loads.top_surcharge))
    model.wall = WallFriction(model)
    fx.append(model.wall)
    fx.append(OutletGate(model))
    if sc.discharge.mode == "controlled":
        fx.append(OutletDrive(model))
    if sc.fill.damping > 0.0:
        fx.append(Damping(model, sc.fill.damping))
    if any(b > 0.0 for b in sc.numerics.bulk_viscosity):
        fx.append(BulkViscosity(model, *sc.numerics.bulk_viscosity))
    if sc.ale.enabled and sc.discharge.mode != "none":
        fx.append(ALEEffect(model))
    return {e.name: e for e in fx}
