"""The solver's state as structs: quadrature data, nodal data, the energy ledger.

:class:`QuadratureData` is what Laghos calls its quadrature data: everything the force
operator reads, in one place — the stress, the material's declared state variables and the
density at every quadrature point (double-buffered: ``now`` is t_n, ``new`` is written by the
step and becomes ``now`` by :meth:`QuadratureData.swap`), and the per-step work arrays (strain
increment, spin, volumes, the rotated stress, the packed force-form coefficients, the cell
arrays of the stable-Δt and bulk-viscosity computations).

:class:`NodalData` holds the lumped mass and the nodal vectors of the central-difference
update in block layout (n_nodes, 2); the internal force is double-buffered in two dolfinx
``la.Vector`` s (so that ghost contributions can be accumulated) and swapped on commit.

:class:`Energy` is the ledger every effect books into (gravity, contact, damping, bulk
viscosity, the material's dissipation, ALE's remap and outflow).

Numba kernels take the tuples these structs hand out (:meth:`QuadratureData.kinematics_out`,
:meth:`QuadratureData.force_in`, :attr:`CellData.arrays`), not loose arrays.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np


@dataclass
class PointState:
    """One time level of the quadrature data: stress (n, 4), the law's state, density (n,)."""

    sig: np.ndarray
    state: dict[str, np.ndarray]
    rho: np.ndarray

    @classmethod
    def allocate(cls, n: int, state_fields: dict[str, int], density: float) -> PointState:
        """Only the state variables the law declares are allocated (an elastic solid: none)."""
        return cls(np.zeros((n, 4)), {k: np.zeros((n, c) if c > 1 else n) for k, c in state_fields.items()},
                   np.full(n, density))

    def arrays(self, nq: int, state_fields: dict[str, int]):
        """(name, (n_cells, nq, components) view) of every quadrature field (stress first)."""
        yield "sig", self.sig.reshape(-1, nq, 4)
        for k, c in state_fields.items():
            yield k, self.state[k].reshape(-1, nq, c)
        yield "rho", self.rho.reshape(-1, nq, 1)


@dataclass
class CellData:
    """Per active cell: volumetric strain rate, characteristic length, wave speed, density."""

    trd: np.ndarray
    L: np.ndarray
    c: np.ndarray
    rho: np.ndarray

    @property
    def arrays(self) -> tuple:
        return self.trd, self.L, self.c, self.rho


@dataclass
class QuadratureData:
    """Everything the internal-force operator reads, over the active cells (see module doc)."""

    now: PointState
    new: PointState
    sig_rot: np.ndarray  # σ^n rotated to t_{n+1} (Jaumann)
    deps: np.ndarray  # strain increment over the step (rr, zz, θθ, γrz)
    spin: np.ndarray  # rotation angle ω Δt
    dvol: np.ndarray  # volumetric strain rate (density update)
    dV: np.ndarray  # quadrature volume 2π r |det J| w_q
    cells: CellData
    kin: np.ndarray  # (nc, nq, 6) velocity gradient, v_r/r, r|det J| (kernels.gradients_q1)
    packed: np.ndarray  # (nc, nq·4) force stress σ̃: the internal-force form's coefficient
    hourglass_viscous: np.ndarray  # (nc, 2) viscous hourglass force Q_v of the last step (reduced integration)

    @classmethod
    def allocate(cls, nc: int, nq: int, state_fields: dict[str, int], density: float) -> QuadratureData:
        n = nc * nq
        return cls(PointState.allocate(n, state_fields, density), PointState.allocate(n, state_fields, 0.0),
                   np.zeros((n, 4)), np.zeros((n, 4)), np.zeros(n), np.zeros(n), np.zeros(n),
                   CellData(np.zeros(nc), np.zeros(nc), np.zeros(nc), np.full(nc, density)),
                   np.zeros((nc, nq, 6)), np.zeros((nc, nq * 4)), np.zeros((nc, 2)))

    def swap(self) -> None:
        """Commit: t_{n+1} becomes t_n (the old level is the next step's output buffer)."""
        self.now, self.new = self.new, self.now

    def kinematics_out(self) -> tuple:
        """What :func:`silo_dolfinx.kernels.kinematics` writes."""
        return self.deps, self.spin, self.dvol, self.dV, self.cells.trd

    def force_in(self, sig_old: np.ndarray, level: PointState) -> tuple:
        """What :func:`silo_dolfinx.kernels.closure` reads at the quadrature points."""
        return sig_old, level.sig, self.deps, self.dV, level.rho


@dataclass
class NodalData:
    """Lumped mass and the nodal vectors of the central-difference update (block (n, 2))."""

    v: np.ndarray  # v^{n+½}: a view of the velocity Function's array
    v_old: np.ndarray  # v^{n−½} (kept for a rejected step and the contact work)
    a: np.ndarray  # a^n
    f_ext: np.ndarray
    dx_prev: np.ndarray  # Δx^{n−½}
    span: np.ndarray  # ½(Δx^{n−½} + Δx^{n+½}): what the forces of step n work over
    mass: np.ndarray  # true lumped mass (n,)
    m_inertial: np.ndarray  # mass × mass_scaling
    minv: np.ndarray  # 1/m_inertial where m > 0, else 0
    active: np.ndarray  # nodes carrying mass

    @classmethod
    def allocate(cls, v: np.ndarray) -> NodalData:
        n = v.shape[0]
        return cls(v, *(np.zeros_like(v) for _ in range(5)), np.zeros(n), np.zeros(n), np.zeros(n),
                   np.zeros(n, bool))

    def work_in(self) -> tuple:
        """What the work kernel reads and updates."""
        return self.v, self.v_old, self.a, self.f_ext, self.m_inertial, self.dx_prev, self.span


@dataclass
class Energy:
    """The energy ledger (J, full 360°): every effect books its work or dissipation here."""

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
    hourglass: float = 0.0  # work against the hourglass control (reduced integration; Abaqus' ALLAE)

    @classmethod
    def names(cls) -> list[str]:
        return [f.name for f in fields(cls)]

    @property
    def balance(self) -> float:
        return (self.kinetic + self.elastic + self.plastic + self.viscous + self.damping + self.remap
                + self.outflow + self.hourglass - self.external - self.initial)

    @property
    def scale(self) -> float:
        return max(abs(self.external) + self.initial, self.kinetic + self.elastic + self.plastic, 1e-300)

    def relative_error(self, scale: float | None = None) -> float:
        """|balance| over the energy scale (default: this record's; the solver passes the
        largest scale reached so far, so that the quiet start does not inflate the ratio)."""
        return abs(self.balance) / max(self.scale if scale is None else scale, 1e-300)
