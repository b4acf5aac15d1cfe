"""Elastic-perfectly plastic Mohr–Coulomb, non-associated: the friction angle holds at every
Lode angle, not only where a Drucker–Prager cone was matched to it.

With the principal stresses σ1 ≥ σ2 ≥ σ3 (tension +)

Yield      F = (σ1 − σ3) + (σ1 + σ3) sin φ − 2c cos φ ≤ 0
Potential  G = (σ1 − σ3) + (σ1 + σ3) sin ψ                  (ψ ≤ φ; ψ = φ is associated)

— a hexagonal pyramid in principal space with its apex at the hydrostatic tension c cot φ. A
cone matched to it in axisymmetric compression (the scenes' default ``material.cone``) is
the pyramid's circumscribing cone: in triaxial extension it is a far stronger solid (φ 35° →
68°; docs/validation/ch6.md), and it lets arches stand over an outlet that this solid cannot
carry. Without cohesion no principal stress is tensile, so no tension cut-off is needed.

Return mapping (exact for perfect plasticity; de Souza Neto, Perić & Owen 2008, §8.2.2,
Boxes 8.4-8.5), in the principal axes of the elastic trial, which an isotropic law keeps.
With λ = K − 2G/3 the elastic response to the flow N = ∂G/∂σ of the main plane is
D N = (2λ sin ψ + 2G(1 + sin ψ), 2λ sin ψ, 2λ sin ψ − 2G(1 − sin ψ)), and F falls by
a Δγ with a = 4G + 4(λ + G) sin φ sin ψ per unit Δγ:

1. main plane: Δγ = F*/a; valid if the order σ1 ≥ σ2 ≥ σ3 survives;
2. otherwise an edge, chosen by the trial: (1 − sin ψ) σ1* − 2σ2* + (1 + sin ψ) σ3* < 0 is the
   compression edge σ1 = σ2 (the planes of σ1 − σ3 and σ2 − σ3 both active), otherwise the
   extension edge σ2 = σ3 (σ1 − σ3 and σ1 − σ2); two multipliers from a 2×2 system
   [a b; b a] with b the cross term (2G(1 − sin ψ)(1 − sin φ) + 4λ sin φ sin ψ, resp.
   2G(1 + sin ψ)(1 + sin φ) + 4λ sin φ sin ψ); valid if the edge's order survives;
3. otherwise the apex σ1 = σ2 = σ3 = c cot φ.

ε̄_p is √(2/3 e_p:e_p) of the plastic strain the return made (C⁻¹(σ* − σ)). Critical state:
with ``max_dilation`` ε_c > 0 a point flows at constant volume (ψ → 0) once ε̄_p reaches
ε_c / r, r = √3 sin ψ/√(1 + sin² ψ/3) the plastic volume change per ε̄_p on a face. A point
flowing on an edge dilates more per ε̄_p - 2 sin ψ/(1 ∓ sin ψ/3), +23 % on the compression
edge and +10 % on the extension edge for ψ = 10° - so it stops at up to that much more than ε_c
(tracking the volume change itself would take a second state field through every remap).

Recompaction (``recompaction``, off by default): a point returned to the apex has been pulled
apart - its grains have lost contact - and the volume it opened there is kept in the state
field ``opening``. A later compressive volume change first closes that opening, without stress
(a plastic compaction −closing/3 I, dissipating against the mean stress), before the grains
carry compression again. Without it the opened volume is permanent: a cell on the axis of a
flow channel, stretched at the apex and squeezed again, ratchets its density down while it
carries kPa of pressure (ch. 6: to 9 % of the density in 40 s, and the stable Δt with it).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from silo_dolfinx._jit_cache import numba
from silo_dolfinx.invariants import from_principal, principal
from silo_dolfinx.kernels import FAST
from silo_dolfinx.materials.base import (Material, close_opening, closing_work, equivalent_strain,
                                         plastic_strain_and_work)
from silo_dolfinx.theory import drucker_prager_cone


class MohrCoulomb(Material):
    name = "mohr_coulomb"
    plastic = True
    state_fields = {"eqps": 1}  # equivalent plastic strain

    def __init__(self, youngs_modulus, poisson_ratio, density, friction_angle, dilation_angle, cohesion,
                 max_dilation: float = 0.0, recompaction: bool = False):
        super().__init__(youngs_modulus, poisson_ratio, density)
        self.recompaction = bool(recompaction)
        if self.recompaction:  # the volume opened at the apex, closed again without stress
            self.state_fields = {"eqps": 1, "opening": 1}
        if not 0.0 <= dilation_angle <= friction_angle < 90.0:
            raise ValueError(f"angles φ = {friction_angle!r}, ψ = {dilation_angle!r}: need 0 ≤ ψ ≤ φ < 90 degrees")
        self.friction_angle, self.dilation_angle, self.cohesion = friction_angle, dilation_angle, cohesion
        self.sin_phi = math.sin(math.radians(friction_angle))
        self.sin_psi = math.sin(math.radians(dilation_angle))
        r = math.sqrt(3.0) * self.sin_psi / math.sqrt(1.0 + self.sin_psi**2 / 3.0)
        self.eqps_critical = max_dilation / r if max_dilation > 0.0 and r > 0.0 else math.inf
        self.apex = cohesion / math.tan(math.radians(friction_angle))  # hydrostatic tension (Pa)

    def update(self, sig, deps, state_old, sig_new, state_new, dV, dt=None) -> float:
        return float(_update(sig, deps, self.state_pair(state_old), self.parameters, sig_new,
                             self.state_pair(state_new), dV))

    @property
    def strength(self) -> tuple[float, float]:
        """The circumscribing cone's (tan β, d): the most shear q this solid carries at a pressure
        (in axisymmetric compression)."""
        beta = drucker_prager_cone(self.friction_angle, 0.0, "compression")[0]
        tan_beta = math.tan(math.radians(beta))
        return (tan_beta, tan_beta * self.apex)

    def mobilised_strength(self, sig: np.ndarray, out: np.ndarray) -> np.ndarray:
        """(σ_a − σ_k) / (2c cos φ − (σ_a + σ_k) sin φ) of the largest and smallest principal
        stresses (:meth:`Material.mobilised_strength`): the pyramid's own strength at the
        stress' Lode angle, not the circumscribing cone's."""
        _pyramid_mobilised(sig, self.sin_phi, self.parameters[4], out)
        return out

    @functools.cached_property
    def parameters(self) -> tuple[float, ...]:
        """The law's constants as its kernel reads them (K, G, sin φ, sin ψ, 2c cos φ, c cot φ, ε̄_p,c,
        recompaction 1/0)."""
        two_c_cos = 2.0 * self.cohesion * math.cos(math.radians(self.friction_angle))
        return tuple(map(float, (self.K, self.G, self.sin_phi, self.sin_psi, two_c_cos, self.apex,
                                 self.eqps_critical, self.recompaction)))

    def yield_function(self, sig: np.ndarray) -> np.ndarray:
        """F(σ) for an (n, 4) array (≤ 0 admissible)."""
        s = np.atleast_2d(np.asarray(sig, float))
        c, h = 0.5 * (s[:, 0] + s[:, 1]), 0.5 * (s[:, 0] - s[:, 1])
        r = np.hypot(h, s[:, 3])
        v = np.stack([c + r, c - r, s[:, 2]], axis=1)
        hi, lo = v.max(axis=1), v.min(axis=1)
        return (hi - lo) + (hi + lo) * self.sin_phi - self.parameters[4]


@numba.njit(cache=True)
def _pyramid_mobilised(sig, sin_phi, two_c_cos, out):
    """out = (a − k) / (2c cos φ − (a + k) sin φ), NaN where that strength is not positive."""
    for i in range(sig.shape[0]):
        a, _, k = principal(sig[i, 0], sig[i, 1], sig[i, 2], sig[i, 3])[:3]
        strength = two_c_cos - (a + k) * sin_phi
        out[i] = (a - k) / strength if strength > 0.0 else np.nan


@numba.njit(cache=True, inline="always")
def _return(abk, f, spsi, law):
    """The principal stresses a ≥ b ≥ k of a trial with F = f > 0 returned (module docstring);
    ψ's sine given (the critical state may have set it to 0), the rest from ``law``."""
    a, b, k = abk
    K, g, sphi, _, c2, apex, _, _ = law
    lam = K - 2.0 * g / 3.0
    d0 = 2.0 * lam * spsi + 2.0 * g * (1.0 + spsi)  # D N of the main plane, by principal axis
    d1 = 2.0 * lam * spsi
    d2 = 2.0 * lam * spsi - 2.0 * g * (1.0 - spsi)
    aa = 4.0 * g + 4.0 * (lam + g) * sphi * spsi
    x = f / aa
    an, bn, kn = a - x * d0, b - x * d1, k - x * d2
    if an >= bn >= kn:
        return an, bn, kn
    if (1.0 - spsi) * a - 2.0 * b + (1.0 + spsi) * k < 0.0:  # the compression edge σ1 = σ2
        f2 = (b - k) + (b + k) * sphi - c2
        bb = 2.0 * g * (1.0 - spsi) * (1.0 - sphi) + 4.0 * lam * sphi * spsi
        det = aa * aa - bb * bb
        x, y = (aa * f - bb * f2) / det, (aa * f2 - bb * f) / det
        an, bn, kn = a - x * d0 - y * d1, b - x * d1 - y * d0, k - (x + y) * d2
        if x >= 0.0 and y >= 0.0 and bn >= kn:
            return an, bn, kn
    else:  # the extension edge σ2 = σ3
        f2 = (a - b) + (a + b) * sphi - c2
        bb = 2.0 * g * (1.0 + spsi) * (1.0 + sphi) + 4.0 * lam * sphi * spsi
        det = aa * aa - bb * bb
        x, y = (aa * f - bb * f2) / det, (aa * f2 - bb * f) / det
        an, bn, kn = a - (x + y) * d0, b - x * d1 - y * d2, k - x * d2 - y * d1
        if x >= 0.0 and y >= 0.0 and an >= bn:
            return an, bn, kn
    return apex, apex, apex


@numba.njit(cache=True, fastmath=FAST)
def _update(sig, deps, old, law, sig_new, new, dV):
    """The return map over all points; also the plastic dissipation σ_mid : Δε_p (σ_mid the mean
    of the rotated start and the end stress, the trapezoidal partner of the internal work) and
    ε̄_p. law = (K, G, sin φ, sin ψ, 2c cos φ, c cot φ, ε̄_p,c, recompaction)
    (:attr:`MohrCoulomb.parameters`); old, new = (ε̄_p, opening) arrays (without recompaction
    the opening is not read or written)."""
    K, G, sphi, spsi0, c2, apex, eqps_c, recompact = law
    eqps, opening = old
    eqps_new, opening_new = new
    diss = 0.0
    lam = K - 2.0 * G / 3.0
    two_g = 2.0 * G
    c = lam / (3.0 * lam + 2.0 * G)
    for i in range(sig.shape[0]):
        e0, e1, e2, e3 = deps[i, 0], deps[i, 1], deps[i, 2], deps[i, 3]
        tr = e0 + e1 + e2
        op = 0.0
        closing = 0.0
        if recompact > 0.0:
            e0, e1, e2, tr, op, closing = close_opening(e0, e1, e2, opening[i])
        t0 = sig[i, 0] + lam * tr + two_g * e0
        t1 = sig[i, 1] + lam * tr + two_g * e1
        t2 = sig[i, 2] + lam * tr + two_g * e2
        t3 = sig[i, 3] + G * e3
        a, b, k, cs, sn, hoop = principal(t0, t1, t2, t3)
        f = (a - k) + (a + k) * sphi - c2
        eqps_new[i] = eqps[i]
        if f <= 0.0:
            s0, s1, s2, s3 = t0, t1, t2, t3
        else:
            spsi = spsi0 if eqps[i] < eqps_c else 0.0
            an, bn, kn = _return((a, b, k), f, spsi, law)
            s0, s1, s2, s3 = from_principal(an, bn, kn, cs, sn, hoop)
            w2, p0, p1, p2, p3 = plastic_strain_and_work(sig[i], (t0, t1, t2, t3), (s0, s1, s2, s3), c, G)
            diss += 0.5 * dV[i] * w2
            eqps_new[i] = eqps[i] + equivalent_strain(p0, p1, p2, p3)
            if recompact > 0.0 and an == apex and kn == apex:  # pulled apart: remember the opening
                op += max(p0 + p1 + p2, 0.0)
        sig_new[i, 0], sig_new[i, 1], sig_new[i, 2], sig_new[i, 3] = s0, s1, s2, s3
        if recompact > 0.0:
            opening_new[i] = op
            diss += 0.5 * dV[i] * closing_work(closing, sig[i], s0, s1, s2)
    return diss
