"""Viscoplasticity of the Duvaut–Lions kind around any rate-independent law (optional).

A rate-independent solid that yields along a band localises into whatever band the mesh offers:
it has no length of its own, and a non-associated cone (ψ < φ) can lose ellipticity without any
softening. Delaying the plastic flow by a relaxation time τ gives it one - in a dynamic problem
the band width scales with the wave speed times τ (Needleman 1988, Comput. Methods Appl. Mech.
Eng. 67; Sluys & de Borst 1992) - at the price of a rate-dependent strength: the stress may lie
outside the yield surface by the overstress σ − σ̄ = τ C : ε̇_vp.

Duvaut–Lions (Simo & Hughes 1998, §2.7): ε̇_vp = C⁻¹ : (σ − σ̄)/τ, σ̄ the stress returned to the
yield surface - the closest point for an associated law, the return along the flow rule for a
non-associated one: what the rate-independent law returns. Backward Euler gives a blend of the
elastic trial σ_e = σ_n + C : Δε and the law's return σ̄ of it,

    σ_n+1 = a σ_e + (1 − a) σ̄,    a = 1/(1 + Δt/τ),

and the law's history variables (ε̄_p, the opening) blend between their old and returned values
the same way. τ → 0 is the law itself; τ → ∞ is elastic. The blend is unconditionally stable, so
it does not limit the step. The plastic dissipation is ½ (σ_n + σ_n+1) : C⁻¹ (σ_e − σ_n+1) -
exact for the trapezoidal energy balance whatever σ_n+1 is (:func:`plastic_strain_and_work`).
In simple shear at a constant rate γ̇ from the yield surface (ψ 0) the overstress of the shear
stress grows as G τ γ̇ (1 − e^(−t/τ)) (tests/test_materials.py).
"""

from __future__ import annotations

from silo_dolfinx._jit_cache import numba
from silo_dolfinx.materials.base import Material, elastic_trial, plastic_strain_and_work


class Viscoplastic(Material):
    """``law`` with its plastic flow delayed by ``relaxation_time`` τ (s) (module docstring).
    It declares the law's state and strength; :meth:`update` needs the step's Δt."""

    plastic = True

    def __init__(self, law: Material, relaxation_time: float):
        if not law.plastic:
            raise ValueError(f"a {law.name} solid has no plastic flow to delay (relaxation_time)")
        if not relaxation_time > 0.0:
            raise ValueError("relaxation_time must be positive (0: use the law itself)")
        super().__init__(law.E, law.nu, law.density)
        self.law, self.relaxation_time = law, float(relaxation_time)
        self.name, self.state_fields, self.recompaction = law.name, law.state_fields, law.recompaction

    @property
    def rate_independent(self) -> Material:
        return self.law

    @property
    def strength(self) -> tuple[float, float]:
        return self.law.strength

    def mobilised_strength(self, sig, out):
        return self.law.mobilised_strength(sig, out)  # above 1: the overstress

    def update(self, sig, deps, state_old, sig_new, state_new, dV, dt=None) -> float:
        if dt is None or not dt > 0.0:
            raise ValueError(f"a viscoplastic law needs the step's Δt (got {dt!r})")
        self.law.update(sig, deps, state_old, sig_new, state_new, dV)  # σ̄, the law's return
        a = 1.0 / (1.0 + dt / self.relaxation_time)
        for name in self.state_fields:
            _blend(state_old[name], state_new[name], a)
        return float(_relax(sig, deps, sig_new, self.K, self.G, a, dV))


@numba.njit(cache=True)
def _blend(old, new, a):
    """new ← a old + (1 − a) new, in place (any shape)."""
    o, n = old.reshape(-1), new.reshape(-1)
    for i in range(n.size):
        n[i] = a * o[i] + (1.0 - a) * n[i]


@numba.njit(cache=True)
def _relax(sig, deps, sig_new, K, G, a, dV):
    """sig_new (the law's return σ̄) ← a σ_e + (1 − a) σ̄; returns the plastic dissipation."""
    lam = K - 2.0 * G / 3.0
    c = lam / (3.0 * lam + 2.0 * G)
    diss = 0.0
    for i in range(sig.shape[0]):
        e0, e1, e2, e3 = elastic_trial(sig[i], deps[i], K, G)
        s0 = a * e0 + (1.0 - a) * sig_new[i, 0]
        s1 = a * e1 + (1.0 - a) * sig_new[i, 1]
        s2 = a * e2 + (1.0 - a) * sig_new[i, 2]
        s3 = a * e3 + (1.0 - a) * sig_new[i, 3]
        sig_new[i, 0], sig_new[i, 1], sig_new[i, 2], sig_new[i, 3] = s0, s1, s2, s3
        diss += 0.5 * dV[i] * plastic_strain_and_work(sig[i], (e0, e1, e2, e3), (s0, s1, s2, s3), c, G)[0]
    return diss

