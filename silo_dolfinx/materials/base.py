"""The material interface: state arrays in, state arrays out, vectorised over quadrature points.

A material is an isotropic hypo-elastic(-plastic) law for the objective stress increment
of an axisymmetric point. Arrays are (n, 4) stress/strain in (rr, zz, θθ, rz) order with
engineering shear strain; ``state`` holds the extra history variables the law declares in
``state_fields`` (name -> components), and only those are allocated by the solver.

``update`` takes the stress already rotated to the end of the step (Jaumann) and the
strain increment, writes the new stress and state, and returns the plastic dissipation
Σ σ : Δε_p dV over the points (J). Sign convention: tension positive; the mean pressure
p = −tr σ/3 is positive in compression, as in the thesis.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np

from silo_dolfinx._jit_cache import numba
from silo_dolfinx.invariants import invariants, mean_j2
from silo_dolfinx.kernels import FAST

__all__ = ["Material", "elastic_trial", "equivalent_strain", "invariants", "plastic_strain_and_work"]  # invariants: silo_dolfinx.invariants


class Material(ABC):
    name = "material"
    plastic = False
    state_fields: dict[str, int] = {}
    recompaction = False  # whether the law keeps the volume opened at its apex (state field "opening")

    def __init__(self, youngs_modulus: float, poisson_ratio: float, density: float):
        E, nu = youngs_modulus, poisson_ratio
        self.E, self.nu, self.density = E, nu, density
        self.K = E / (3.0 * (1.0 - 2.0 * nu))
        self.G = E / (2.0 * (1.0 + nu))

    @property
    def strength(self) -> tuple[float, float]:
        """(tan β, d) of the shear strength q_y = p tan β + d the law caps q at; (−1, 0) for a
        law without one (the hourglass control's stiffness is then not capped)."""
        return (-1.0, 0.0)

    def mobilised_strength(self, sig: np.ndarray, out: np.ndarray) -> np.ndarray:
        """The share of its shear strength each of the (n, 4) stresses mobilises, written into
        ``out`` (n,) and returned: 1 on the yield surface (above 1: a rate-dependent law's
        overstress), below 1 inside it; NaN at or beyond the apex, where the solid has no shear
        strength (a separated point). Only a plastic law has one: asking an elastic law is a
        misuse (the shear-zone stream is built for plastic solids only), a TypeError."""
        raise TypeError(f"the {self.name} law has no yield surface: a mobilised strength needs a plastic law")

    @property
    def rate_independent(self) -> Material:
        """The law without any rate dependence (what a stress is projected with when no time
        passes, as at a K0 start): the law itself but for
        :class:`~silo_dolfinx.materials.viscoplastic.Viscoplastic`'s."""
        return self

    @property
    def wave_modulus(self) -> float:
        """P-wave (constrained) modulus λ + 2μ = K + 4G/3 (Pa)."""
        return self.K + 4.0 * self.G / 3.0

    @abstractmethod
    def update(self, sig, deps, state_old, sig_new, state_new, dV, dt=None) -> float:
        """New stress and state from the rotated stress and the strain increment; returns the
        plastic dissipation (J). ``dt``, the step (s), is read only by a rate-dependent law
        (:class:`~silo_dolfinx.materials.viscoplastic.Viscoplastic`)."""

    def state_pair(self, state) -> tuple[np.ndarray, np.ndarray]:
        """(ε̄_p, opening) arrays of a state, as the plastic kernels read them (without
        recompaction the second is ε̄_p's array again, never read or written)."""
        return state["eqps"], state["opening"] if self.recompaction else state["eqps"]

    def elastic_energy(self, sig: np.ndarray, dV: np.ndarray) -> float:
        """Stored elastic energy Σ ½ σ:C⁻¹:σ dV (J)."""
        return float(_elastic_energy(sig, dV, self.K, self.G))

    def elastic_energy_mean(self, sig: np.ndarray, sig_prev: np.ndarray, dV: np.ndarray,
                            increment: np.ndarray | None = None) -> float:
        """½ (elastic energy of ``sig`` + of ``sig_prev``) in one pass (J): the energy record's
        value at the half step; with ``increment``, also writes sig − sig_prev into it."""
        if increment is None:
            return float(_elastic_energy_mean(sig, sig_prev, dV, self.K, self.G))
        return float(_energy_mean_and_difference(sig, sig_prev, dV, self.K, self.G, increment, False))

    def elastic_energy_mean_from_increment(self, sig: np.ndarray, increment: np.ndarray, dV: np.ndarray,
                                           sig_prev: np.ndarray) -> float:
        """Writes the previous stress sig − increment into ``sig_prev`` and returns ½ (elastic
        energy of ``sig`` + of it), in one pass (J)."""
        return float(_energy_mean_and_difference(sig, increment, dV, self.K, self.G, sig_prev, True))

    def elastic_energy_density(self, sig: np.ndarray) -> np.ndarray:
        """½ σ:C⁻¹:σ at every point (J/m³)."""
        out = np.empty(sig.shape[0])
        _elastic_density(sig, self.K, self.G, out)
        return out


@numba.njit(cache=True, inline="always")
def _density(s, K, G):
    m, j2 = mean_j2(s)
    return 0.5 * m * m / K + 0.5 * j2 / G


# reassociation lets the energy sums vectorise (it changes them by round-off only)
@numba.njit(cache=True, fastmath=FAST)
def _elastic_energy(sig, dV, K, G):
    e = 0.0
    for i in range(sig.shape[0]):
        e += dV[i] * _density(sig[i], K, G)
    return e


@numba.njit(cache=True, fastmath=FAST)
def _elastic_energy_mean(sig, sig_prev, dV, K, G):
    e = 0.0
    for i in range(sig.shape[0]):
        e += dV[i] * (_density(sig[i], K, G) + _density(sig_prev[i], K, G))
    return 0.5 * e


@numba.njit(cache=True, fastmath=FAST)
def _energy_mean_and_difference(a, b, dV, K, G, out, of_difference):
    """out = a − b; returns ½ Σ dV (e(a) + e(b)), or with ``of_difference`` ½ Σ dV (e(a) + e(out))."""
    e = 0.0
    for i in range(a.shape[0]):
        for j in range(4):
            out[i, j] = a[i, j] - b[i, j]
        e += dV[i] * (_density(a[i], K, G) + (_density(out[i], K, G) if of_difference else _density(b[i], K, G)))
    return 0.5 * e


@numba.njit(cache=True)
def _elastic_density(sig, K, G, out):
    for i in range(sig.shape[0]):
        out[i] = _density(sig[i], K, G)


@numba.njit(cache=True, inline="always")
def plastic_strain_and_work(old, trial, new, c, G):
    """The plastic strain a return made, Δε_p = C⁻¹(σ_trial − σ_new) (engineering shear), and
    (σ_old + σ_new) : Δε_p - twice its dissipation at the step's mid-point stress, the partner
    of the trapezoidal internal work ½(σ_n + σ_n+1) : Δε (σ_new : Δε_p would leave a first-order
    gap in the energy balance). ``old`` a stress row, ``trial`` and ``new`` 4-tuples; c = λ/(3λ +
    2G). Returns (that product, the four components)."""
    o0, o1, o2, o3 = old[0], old[1], old[2], old[3]
    t0, t1, t2, t3 = trial
    s0, s1, s2, s3 = new
    r0, r1, r2, r3 = t0 - s0, t1 - s1, t2 - s2, t3 - s3
    rt = r0 + r1 + r2
    two_g = 2.0 * G
    p0 = (r0 - c * rt) / two_g
    p1 = (r1 - c * rt) / two_g
    p2 = (r2 - c * rt) / two_g
    p3 = r3 / G
    return (o0 + s0) * p0 + (o1 + s1) * p1 + (o2 + s2) * p2 + (o3 + s3) * p3, p0, p1, p2, p3


@numba.njit(cache=True, inline="always")
def close_opening(e0, e1, e2, op):
    """Recompaction, before the trial: a compressive volume change first closes the opening
    ``op`` (volume a point opened at its yield surface's apex), without stress - its grains only
    come back into contact. Returns the strain's normal components left to load the point, their
    trace, the opening left and the volume closed."""
    tr = e0 + e1 + e2
    closing = 0.0
    if tr < 0.0 and op > 0.0:
        closing = min(-tr, op)
        e0 += closing / 3.0
        e1 += closing / 3.0
        e2 += closing / 3.0
        tr += closing
        op -= closing
    return e0, e1, e2, tr, op, closing


@numba.njit(cache=True, inline="always")
def closing_work(closing, old, s0, s1, s2):
    """Twice the work of closing ``closing`` of opening, a plastic compaction −closing/3 I, against
    the step's mid-point mean stress (the partner of :func:`plastic_strain_and_work`)."""
    return -closing * (old[0] + old[1] + old[2] + s0 + s1 + s2) / 3.0


@numba.njit(cache=True, inline="always")
def equivalent_strain(p0, p1, p2, p3):
    """√(2/3 e:e) of a strain increment (rr, zz, θθ, rz; engineering shear), e its deviator."""
    pm = (p0 + p1 + p2) * (1.0 / 3.0)
    return math.sqrt(2.0 / 3.0 * ((p0 - pm) ** 2 + (p1 - pm) ** 2 + (p2 - pm) ** 2 + 0.5 * p3 * p3))


@numba.njit(cache=True, inline="always")
def elastic_trial(sig, de, K, G):
    """sig + D : de for one point (isotropic, engineering shear), as four components."""
    lam = K - 2.0 * G / 3.0
    tr = de[0] + de[1] + de[2]
    return (sig[0] + lam * tr + 2.0 * G * de[0], sig[1] + lam * tr + 2.0 * G * de[1],
            sig[2] + lam * tr + 2.0 * G * de[2], sig[3] + G * de[3])
