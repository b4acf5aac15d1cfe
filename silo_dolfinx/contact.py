"""Rigid-wall contact: node-to-analytic-wall, kinematic (predictor-corrector), with friction.

Why kinematic rather than penalty: a penalty spring stiff enough to keep penetration small
shrinks the stable time step (the thesis' Table 3-3: ×10 stiffness → 34 % of Δt, ×100 →
13 %). The kinematic method adds no stiffness — the stable Δt is the material's — and it
enforces the constraint exactly, to round-off, each step (the approach of Abaqus/Explicit's
kinematic contact and of DYNA's constraint methods, on a lumped mass).

For each wall node (owned by this rank, so each node is treated once) after the velocity
predictor v*:

1. predicted position x* = x + Δt v*; signed gap g = distance of x* to the wall along the
   closest-point projection (exact segments and arcs: finite sliding round corners);
2. g < 0 (penetration): the normal velocity is corrected so that x* lands on the wall,
   Δv = (g/Δt) n; the normal contact force is N = M |g| / (Δt Δt̄);
3. friction: the force that would stop tangential slip is T = M |v_t| / Δt̄; if T ≤ μ N the
   node sticks (v_t = 0), else it slips with T = μ N opposing the slip; μ is constant
   (Coulomb) or μ_k + (μ_s − μ_k) exp(−ϖ v_slip) (eq. 7-1, μ_s deciding stick) evaluated at
   the slip speed that results from the step (solved by fixed-point iteration);
4. separation (g ≥ 0) costs nothing: no force.

Optionally (``wall.regularisation_length`` L > 0) the friction limit follows the normal force
with a memory - the simplified Prakash–Clifton law of Cochard & Rice (2000) as Kammer et al.
(2014) use it on a deformable-rigid interface: the limit is μ Ñ, with Ñ relaxing towards the
contact force N at the rate (|v_slip| + v*)/L,

    dÑ/dt = −(|v_slip| + v*)/L · (Ñ − N),

integrated exactly over each step (Ñ ← N + (Ñ − N)·exp(−(|v_slip| + v*)Δt/L), v_slip the last
step's slip speed, N this step's force: L → 0 gives Coulomb's instantaneous limit to round-off).
Coulomb friction between a deformable solid and a rigid wall can make steady sliding unstable
(a flutter: Martins et al. 1995) and, above a μ set by the solid's Poisson ratio, ill-posed:
disturbances grow at a rate that rises without bound as their wavelength shrinks (Renardy
1992). On a mesh the fastest-growing disturbance is then the shortest the mesh carries, so what
grows depends on the element size. The memory bounds that growth (the strength cannot
follow a normal-force change faster than (|v| + v*)/L): with it, the problem has a length of its
own. Ñ is state kept per node (checkpointed; it moves with its node when ALE slides the node
along the wall - the smoothing moves a wall node a fraction of an element per remap, and Ñ
relaxes over L/(|v| + v*) anyway).

Wall pressures are the forces over the node's tributary area ∫ N_a 2π r ds. Besides the last
step's forces each node keeps their time integrals since the wall history's last sample
(:meth:`WallContact.interval_means`): the history records the mean over each sampling interval,
as a pressure cell does, not one step of it (an instant sample folds anything faster than half
the history rate into the record's band: the stiff ch. 4 solid rings at ~157 Hz at point e,
which 200-Hz instants show as a 43-Hz peak).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from silo_dolfinx._jit_cache import numba
from silo_dolfinx.geometry.wall import Wall

NONE, COULOMB, VELOCITY = 0, 1, 2
STICK = math.inf  # a friction coefficient that always sticks (a fixed gate)


@dataclass(frozen=True)
class FrictionLaw:
    """μ(v_slip): kind NONE, COULOMB (mu) or VELOCITY (mu_static, mu_kinetic, decay s/m)."""

    kind: int
    mu: float = 0.0
    mu_static: float = 0.0
    mu_kinetic: float = 0.0
    decay: float = 0.0

    @classmethod
    def from_wall(cls, w) -> FrictionLaw:
        if w["friction"] == "none":
            return cls(NONE)
        if w["friction"] == "coulomb":
            return cls(COULOMB, mu=w["mu"])
        return cls(VELOCITY, mu_static=w["mu_static"], mu_kinetic=w["mu_kinetic"], decay=w["decay"])

    def coefficient(self, slip_speed):
        """μ at a slip speed (m/s), vectorised."""
        s = np.asarray(slip_speed, float)
        if self.kind == NONE:
            return np.zeros_like(s)
        if self.kind == COULOMB:
            return np.full_like(s, self.mu)
        from silo_dolfinx.theory import dynamic_friction

        return dynamic_friction(s, self.mu_static, self.mu_kinetic, self.decay)

    def as_array(self) -> np.ndarray:
        return np.array([self.kind, self.mu, self.mu_static, self.mu_kinetic, self.decay], float)


@dataclass(frozen=True)
class FrictionMemory:
    """The simplified Prakash–Clifton memory of the friction limit (module docstring): a length
    L (m) and a speed v* (m/s); the limit μ Ñ relaxes towards μ N over L/(|v_slip| + v*)."""

    length: float
    speed: float

    @classmethod
    def from_wall(cls, w) -> FrictionMemory | None:
        """The scene's wall memory, or None (Coulomb's instantaneous limit: nothing is built)."""
        if w["friction"] == "none" or w["regularisation_length"] <= 0.0:
            return None
        return cls(w["regularisation_length"], w["regularisation_speed"])


class WallContact:
    """Kinematic contact of a node set with an analytic wall; one friction law per piece, and
    optionally a :class:`FrictionMemory` (its per-node state :attr:`lagged_normal`)."""

    CHECKPOINT = ("normal_force", "shear_force", "slip_velocity", "in_contact", "s", "normal", "_p", "interval", "interval_span")

    def __init__(self, wall: Wall, nodes: np.ndarray, dofs: np.ndarray, laws: list[FrictionLaw],
                 memory: FrictionMemory | None = None):
        """``nodes``: geometry-node indices (owned only), ``dofs``: their velocity block indices,
        ``laws``: a friction law per wall piece, ``memory``: the friction limit's memory (None:
        Coulomb's instantaneous limit, no state)."""
        self.wall = wall
        self.nodes = np.asarray(nodes, np.int64)
        self.dofs = np.asarray(dofs, np.int64)
        if len(laws) != len(wall.pieces):
            raise ValueError("one friction law per wall piece")
        self.laws = laws
        self._law_table = np.array([law.as_array() for law in laws])
        self._frictionless = all(law.kind == NONE for law in laws)
        n = self.nodes.size
        self.normal_force = np.zeros(n)  # N (newton), last step
        self.shear_force = np.zeros(n)  # T (newton, signed along the wall tangent)
        self.slip_velocity = np.zeros(n)  # m/s along the tangent after friction
        self.in_contact = np.zeros(n, bool)
        self.s = np.zeros(n)  # arclength of the contact point
        self.normal = np.zeros((n, 2))
        self._p = np.zeros((n, 2))
        self.interval = np.zeros((n, 3))  # ∫ N dt, ∫ T dt, ∫ slip dt since the last interval_means()
        self.interval_span = np.zeros(1)  # ∫ dt over the same steps (one for every node)
        self.memory = memory
        self._memory = np.array([memory.length, memory.speed] if memory else [0.0, 0.0])
        self.lagged_normal = np.zeros(n if memory else 0)  # Ñ (newton): the force the limit μ Ñ reads
        if memory:
            self.CHECKPOINT = WallContact.CHECKPOINT + ("lagged_normal",)
        # the projection of every step, into arrays kept here (no allocation per step)
        self._gap, self._closest, self._piece = np.zeros(n), np.zeros((n, 2)), np.zeros(n, np.int64)
        t0 = np.subtract(wall.pieces[0].start, wall.point_at(min(1e-9, wall.length))[0])
        t1 = np.subtract(wall.point_at(max(wall.length - 1e-9, 0.0))[0], wall.pieces[-1].end)
        # start point, outward direction beyond the start, end point, outward direction beyond the end
        self._ends = np.array([*wall.start, *(t0 / np.linalg.norm(t0)), *wall.end, *(-t1 / np.linalg.norm(t1))])

    def exclude(self, dofs: np.ndarray) -> None:
        """Drop nodes whose velocity is prescribed: they are driven, not in contact."""
        keep = ~np.isin(self.dofs, dofs)
        self.nodes, self.dofs = self.nodes[keep], self.dofs[keep]
        for name in ("normal_force", "shear_force", "slip_velocity", "in_contact", "s", "normal", "_p", "_gap",
                     "_closest", "_piece", "interval") + (("lagged_normal",) if self.memory else ()):
            setattr(self, name, getattr(self, name)[keep])

    def apply(self, x: np.ndarray, v: np.ndarray, mass: np.ndarray, dt: float, dt_avg: float) -> None:
        """Correct the predicted velocities ``v`` (block array) of the contact nodes in place."""
        if self.nodes.size == 0:
            return
        _predict(self._p, x, self.nodes, v, self.dofs, dt)
        self.wall.project_into(self._p, (self._gap, self._closest, self.normal, self.s, self._piece))
        _open_ends(self._gap, self.s, self._p, self._ends, self.wall.length)
        _correct(v, self.dofs, mass, (self._gap, self.normal, self._piece),
                 (self._law_table, self.lagged_normal, self._memory), (dt, dt_avg, self._frictionless), self.outputs)

    def accept(self, dt: float) -> None:
        """The step whose forces :meth:`apply` computed is accepted (a rejected trial is not):
        add them, weighted by its Δt, to the interval integrals."""
        if self.nodes.size:
            _accumulate(self.interval, self.normal_force, self.shear_force, self.slip_velocity, dt)
        self.interval_span += dt

    def interval_means(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(N, T, slip velocity) per node averaged over the steps since the last call, which
        starts the next interval; the last step's values where no step has been taken since."""
        span = float(self.interval_span[0])
        if span <= 0.0:
            return self.normal_force.copy(), self.shear_force.copy(), self.slip_velocity.copy()
        means = self.interval / span
        self.interval[:] = 0.0
        self.interval_span[:] = 0.0
        return means[:, 0], means[:, 1], means[:, 2]

    @property
    def outputs(self) -> tuple:
        """(normal force, shear force, slip velocity, in contact) per node, as the kernel writes them."""
        return self.normal_force, self.shear_force, self.slip_velocity, self.in_contact


@numba.njit(cache=True)
def _accumulate(acc, N, T, slip, dt):
    """Add one step's forces and slip, weighted by its Δt, to the interval integrals."""
    for k in range(acc.shape[0]):
        acc[k, 0] += N[k] * dt
        acc[k, 1] += T[k] * dt
        acc[k, 2] += slip[k] * dt


@numba.njit(cache=True)
def _open_ends(gap, s, p, ends, length):
    """The wall ends at its first and last points: beyond them there is nothing to touch.

    'Beyond' means past the end along the wall's direction by more than round-off, so a node
    sitting at the end (a corner node of the fill) keeps its wall."""
    tol = 1e-9 * length
    for k in range(gap.shape[0]):
        if s[k] <= 1e-12 * length:
            if (p[k, 0] - ends[0]) * ends[2] + (p[k, 1] - ends[1]) * ends[3] > tol:
                gap[k] = np.inf
        elif s[k] >= length * (1.0 - 1e-12):
            if (p[k, 0] - ends[4]) * ends[6] + (p[k, 1] - ends[5]) * ends[7] > tol:
                gap[k] = np.inf


@numba.njit(cache=True)
def _predict(p, x, nodes, v, dofs, dt):
    """The contact nodes' predicted positions x + Δt v^{n+½}, into p."""
    for k in range(p.shape[0]):
        p[k, 0] = x[nodes[k], 0] + dt * v[dofs[k], 0]
        p[k, 1] = x[nodes[k], 1] + dt * v[dofs[k], 1]


@numba.njit(cache=True)
def _correct(v, dofs, mass, projection, friction, steps, out):
    """projection = (gap, normal, piece) of each node's predicted position; friction = (the law
    table, one row per wall piece; Ñ per node; the memory's (L, v*), L = 0: none); steps = (Δt,
    Δt̄, frictionless); out = (N, T, slip, in_contact) per node (:attr:`WallContact.outputs`;
    slip holds the last step's on entry)."""
    gap, normal, piece = projection
    laws, lagged, memory = friction
    dt, dt_avg, frictionless = steps
    N_out, T_out, slip_out, contact = out
    for k in range(dofs.shape[0]):
        i = dofs[k]
        g = gap[k]
        N = 0.0 if g >= 0.0 else mass[i] * (-g) / (dt * dt_avg)
        N_limit = N
        if memory[0] > 0.0:  # Ñ ← N + (Ñ − N) exp(−(|v_slip| + v*) Δt / L)
            N_limit = N + (lagged[k] - N) * math.exp(-(abs(slip_out[k]) + memory[1]) * dt / memory[0])
            lagged[k] = N_limit
        if g >= 0.0 or mass[i] <= 0.0:
            N_out[k] = 0.0
            T_out[k] = 0.0
            contact[k] = False
            slip_out[k] = v[i, 0] * (-normal[k, 1]) + v[i, 1] * normal[k, 0]
            continue
        contact[k] = True
        nr, nz = normal[k, 0], normal[k, 1]
        tr, tz = -nz, nr
        # normal: land exactly on the wall
        v[i, 0] += g / dt * nr
        v[i, 1] += g / dt * nz
        N_out[k] = N
        vt = v[i, 0] * tr + v[i, 1] * tz
        if frictionless:
            T_out[k] = 0.0
            slip_out[k] = vt
            continue
        law = laws[piece[k]]
        kind = int(law[0])
        if kind == 0:
            mu = 0.0
        elif kind == 1:
            mu = law[1]
        else:
            mu = law[2]  # static: μ at zero slip speed decides stick
        T_stick = mass[i] * abs(vt) / dt_avg
        if T_stick <= mu * N_limit:
            dv = -vt
            T_out[k] = -mass[i] * vt / dt_avg
        else:
            sgn = 1.0 if vt > 0.0 else -1.0
            if kind == 2:
                # μ at the slip speed that results: v = |v*| − μ(v) N Δt̄/M, by fixed point (a
                # contraction: |dμ/dv| N Δt̄/M ≤ ϖ (μs − μk) N Δt̄/M, small)
                h = N_limit * dt_avg / mass[i]
                speed = abs(vt)
                for _ in range(50):
                    mu = law[3] + (law[2] - law[3]) * math.exp(-law[4] * speed)
                    speed_new = abs(vt) - mu * h
                    if abs(speed_new - speed) <= 1e-13 * (1.0 + abs(vt)):
                        break
                    speed = speed_new
            T_max = mu * N_limit
            dv = -sgn * T_max * dt_avg / mass[i]
            T_out[k] = -sgn * T_max
        v[i, 0] += dv * tr
        v[i, 1] += dv * tz
        slip_out[k] = vt + dv
