"""Elastic-perfectly plastic Drucker-Prager, non-associated, in the thesis' convention.

Yield      F = q − p tan β − d ≤ 0          (q = √(3 J2), p = −tr σ/3, compression +)
Potential  G = q − p tan ψ                  (ψ ≤ β; ψ = β is associated)

Return mapping (exact for this linear cone; de Souza Neto, Perić & Owen 2008, §8.3):
with the elastic trial (p*, q*, s*), the flow ∂G/∂σ = (3/2) s/q + (tan ψ/3) I gives

    q = q* − 3G Δλ,   p = p* + K tan ψ Δλ,   Δλ = F* / (3G + K tan β tan ψ),

valid while q ≥ 0. Otherwise the trial lies beyond the apex and the stress returns to the
apex p = −d/tan β, q = 0. Δλ is also the equivalent (deviatoric) plastic strain increment;
the plastic volume change is tan ψ Δλ (dilation for ψ > 0).

Critical state: with ``max_dilation`` ε_c > 0 (the scenes' default) a point stops dilating
once its plastic volume change tan ψ · ε̄_p reaches ε_c (ψ → 0 from then on), as a sheared
granular solid does at its critical state. Without it the density near an outlet keeps falling.

Tension cut-off: a cone steeper than tan β = 3/2 (a Mohr–Coulomb φ > 36.87° matched in
compression) contains states with a tensile principal stress even without cohesion (e.g.
σ1 = σ2 compressive, σ3 > 0). Such cones get a Rankine cut-off through the apex: no principal
stress above T = d/tan β (tension +). A point beyond it returns in principal space with
associated Rankine flow (Δε_p along the offending principal directions, as FLAC's tension
correction): σ_a = T, the others lowered by λ Δλ_a; two active planes share their corner, three
give the apex. The returned state lies inside the cone (it lowers q and raises p), its
dissipation T Δλ ≥ 0; ε̄_p (the cone's shear strain, which drives the critical state) is not
changed by it. For tan β ≤ 3/2 no admissible state has a principal stress above T, and the
cut-off is never evaluated.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from silo_dolfinx._jit_cache import numba
from silo_dolfinx.invariants import deviator_q_p, from_principal, invariants, principal
from silo_dolfinx.materials.base import (Material, close_opening, closing_work, equivalent_strain,
                                         plastic_strain_and_work)


class DruckerPrager(Material):
    name = "drucker_prager"
    plastic = True
    state_fields = {"eqps": 1}  # equivalent plastic strain

    def __init__(self, youngs_modulus, poisson_ratio, density, friction_angle, dilation_angle, cohesion,
                 max_dilation: float = 0.0, recompaction: bool = False):
        super().__init__(youngs_modulus, poisson_ratio, density)
        self.recompaction = bool(recompaction)
        if self.recompaction:  # the volume opened at the apex, closed again without stress
            self.state_fields = {"eqps": 1, "opening": 1}
        self.friction_angle, self.dilation_angle, self.cohesion = friction_angle, dilation_angle, cohesion
        self.tan_beta = math.tan(math.radians(friction_angle))
        self.tan_psi = math.tan(math.radians(dilation_angle))
        # ε̄_p beyond which ψ = 0 (inf: never)
        self.eqps_critical = max_dilation / self.tan_psi if max_dilation > 0.0 and self.tan_psi > 0.0 else math.inf
        # tension cut-off through the apex, only where the cone admits tension (tan β > 3/2)
        self.tension_cutoff = cohesion / self.tan_beta if self.tan_beta > 1.5 else math.inf

    noncoaxial = 0.0  # 4G²/(H_nc + 2G): zero for the coaxial law (see non_coaxial.py)

    def update(self, sig, deps, state_old, sig_new, state_new, dV, dt=None) -> float:
        return float(_update(sig, deps, self.state_pair(state_old), self.parameters, sig_new,
                             self.state_pair(state_new), dV))

    @property
    def strength(self) -> tuple[float, float]:
        return (float(self.tan_beta), float(self.cohesion))

    def mobilised_strength(self, sig: np.ndarray, out: np.ndarray) -> np.ndarray:
        """q / (p tan β + d) (:meth:`Material.mobilised_strength`)."""
        _cone_mobilised(sig, self.tan_beta, self.cohesion, out)
        return out

    @functools.cached_property
    def parameters(self) -> tuple[float, ...]:
        """The law's constants as its kernel reads them (K, G, tan β, tan ψ, d, c_nc, ε̄_p,c, T,
        recompaction 1/0); built once, at the first update (after any subclass has set its constants)."""
        return tuple(map(float, (self.K, self.G, self.tan_beta, self.tan_psi, self.cohesion, self.noncoaxial,
                                 self.eqps_critical, self.tension_cutoff, self.recompaction)))

    def yield_function(self, sig: np.ndarray) -> np.ndarray:
        """F(σ) for an (n, 4) array (≤ 0 admissible)."""
        out = np.empty(sig.shape[0])
        for i in range(sig.shape[0]):
            p, q, *_ = invariants(sig[i])
            out[i] = q - p * self.tan_beta - self.cohesion
        return out


@numba.njit(cache=True)
def _cone_mobilised(sig, tanb, d, out):
    """out = q / (p tan β + d), NaN where that strength is not positive (at or beyond the apex)."""
    for i in range(sig.shape[0]):
        q, p = deviator_q_p(sig[i, 0], sig[i, 1], sig[i, 2], sig[i, 3])[3:]
        strength = p * tanb + d
        out[i] = q / strength if strength > 0.0 else np.nan


@numba.njit(cache=True, inline="always")
def _trial_yield(t0, t1, t2, t3, tanb, d):
    """Deviator (normal components), q, p and F of a stress given by its 4 components."""
    d0, d1, d2, q, p = deviator_q_p(t0, t1, t2, t3)
    return d0, d1, d2, q, p, q - p * tanb - d


@numba.njit(cache=True, inline="always")
def _principal_cap(s0, s1, s2, s3, T, lam, two_g):
    """Rankine return of an axisymmetric stress (rr, zz, θθ, rz) to σ_i ≤ T (tension +) with
    associated flow in principal space; returns the new components."""
    a, b, k, cs, sn, hoop = principal(s0, s1, s2, s3)  # a ≥ b ≥ k
    e = lam + two_g
    da = a - T
    x_a, x_b = da / e, 0.0
    if b - lam * x_a > T:  # two active planes: their corner
        db = b - T
        det = e * e - lam * lam
        x_a, x_b = (e * da - lam * db) / det, (e * db - lam * da) / det
    a_n = a - e * x_a - lam * x_b
    b_n = b - lam * x_a - e * x_b
    k_n = k - lam * (x_a + x_b)
    if k_n > T:  # all three: the apex
        a_n = b_n = k_n = T
    return from_principal(a_n, b_n, k_n, cs, sn, hoop)  # same principal axes


@numba.njit(cache=True, inline="always")
def _max_principal(s0, s1, s2, s3):
    h = 0.5 * (s0 - s1)
    return max(0.5 * (s0 + s1) + math.sqrt(h * h + s3 * s3), s2)


@numba.njit(cache=True, fastmath={"contract", "arcp", "reassoc", "nsz", "afn"})
def _update(sig, deps, old, law, sig_new, new, dV):
    """The return map (module docstring) over all points, written out in scalars (the hot
    loop of a plastic step); also the plastic dissipation σ_mid : Δε_p and ε̄_p.

    law = (K, G, tan β, tan ψ, d, c_nc, eqps_c, T, recompaction) (:attr:`DruckerPrager.parameters`);
    old, new = (ε̄_p, opening) arrays (without recompaction the opening is not read or written).
    c_nc = 4G²/(H_nc + 2G) > 0 adds the yield-vertex non-coaxial plastic strain (eq. 8-11)
    at points that load plastically: the trial deviator loses c_nc Δe_t, Δe_t the part of
    the deviatoric strain increment tangential to the current deviator s (s : Δe_t = 0).
    Points with ε̄_p ≥ eqps_c flow at constant volume (ψ = 0: the critical state).
    T < inf: the tension cut-off (module docstring), checked at every point."""
    K, G, tanb, tanpsi0, d, c_nc, eqps_c, T, recompact = law
    eqps, opening = old
    eqps_new, opening_new = new
    diss = 0.0
    lam = K - 2.0 * G / 3.0
    two_g = 2.0 * G
    c = lam / (3.0 * lam + 2.0 * G)
    cutoff = T < math.inf
    for i in range(sig.shape[0]):
        e0, e1, e2, e3 = deps[i, 0], deps[i, 1], deps[i, 2], deps[i, 3]
        tr = e0 + e1 + e2
        op = 0.0
        if recompact > 0.0:
            e0, e1, e2, tr, op, closing = close_opening(e0, e1, e2, opening[i])
            if closing > 0.0:  # against the start's mean stress (an opened point is at the apex, ~d/tan β)
                diss += 0.5 * dV[i] * closing_work(closing, sig[i], sig[i, 0], sig[i, 1], sig[i, 2])
            opening_new[i] = op
        t0 = sig[i, 0] + lam * tr + two_g * e0
        t1 = sig[i, 1] + lam * tr + two_g * e1
        t2 = sig[i, 2] + lam * tr + two_g * e2
        t3 = sig[i, 3] + G * e3
        d0, d1, d2, q, p, f = _trial_yield(t0, t1, t2, t3, tanb, d)
        if f <= 0.0 and not (cutoff and _max_principal(t0, t1, t2, t3) > T):
            sig_new[i, 0], sig_new[i, 1], sig_new[i, 2], sig_new[i, 3] = t0, t1, t2, t3
            eqps_new[i] = eqps[i]
            continue
        # elastic trial kept for the plastic strain; the non-coaxial part modifies the trial
        e0t, e1t, e2t, e3t = t0, t1, t2, t3
        if c_nc > 0.0:
            sm = (sig[i, 0] + sig[i, 1] + sig[i, 2]) * (1.0 / 3.0)
            s0, s1, s2, s3 = sig[i, 0] - sm, sig[i, 1] - sm, sig[i, 2] - sm, sig[i, 3]
            ss = s0 * s0 + s1 * s1 + s2 * s2 + 2.0 * s3 * s3
            if ss > 0.0:
                em = tr * (1.0 / 3.0)
                de0, de1, de2, de3 = e0 - em, e1 - em, e2 - em, 0.5 * e3  # tensor deviatoric strain
                proj = (s0 * de0 + s1 * de1 + s2 * de2 + 2.0 * s3 * de3) / ss
                t0 -= c_nc * (de0 - proj * s0)
                t1 -= c_nc * (de1 - proj * s1)
                t2 -= c_nc * (de2 - proj * s2)
                t3 -= c_nc * (de3 - proj * s3)
                d0, d1, d2, q, p, f = _trial_yield(t0, t1, t2, t3, tanb, d)
                if f <= 0.0 and not (cutoff and _max_principal(t0, t1, t2, t3) > T):
                    sig_new[i, 0], sig_new[i, 1], sig_new[i, 2], sig_new[i, 3] = t0, t1, t2, t3
                    w2 = plastic_strain_and_work(sig[i], (e0t, e1t, e2t, e3t), (t0, t1, t2, t3), c, G)[0]
                    diss += 0.5 * dV[i] * w2
                    eqps_new[i] = eqps[i]
                    continue
        tanpsi = tanpsi0 if eqps[i] < eqps_c else 0.0
        dlam = max(f, 0.0) / (3.0 * G + K * tanb * tanpsi)  # f ≤ 0: inside the cone, beyond the cut-off
        if 3.0 * G * dlam <= q:  # return to the cone
            qn = q - 3.0 * G * dlam
            pn = p + K * tanpsi * dlam
            k = qn / q if q > 0.0 else 0.0
            s0, s1, s2, s3 = k * d0 - pn, k * d1 - pn, k * d2 - pn, k * t3
            eqps_new[i] = eqps[i] + dlam
            apex = False
        else:  # return to the apex p = −d/tan β, q = 0
            pa = -d / tanb
            s0, s1, s2, s3 = -pa, -pa, -pa, 0.0
            apex = True
        if cutoff and not apex and _max_principal(s0, s1, s2, s3) > T:
            s0, s1, s2, s3 = _principal_cap(s0, s1, s2, s3, T, lam, two_g)
        sig_new[i, 0], sig_new[i, 1], sig_new[i, 2], sig_new[i, 3] = s0, s1, s2, s3
        # plastic strain Δε_p = C⁻¹ (σ_trial,elastic − σ_new) (coaxial + non-coaxial) and its
        # dissipation σ_mid : Δε_p, so that work = Δ(elastic energy) + dissipation holds to second
        # order in Δt (σ_new : Δε_p left 1.8 % of the work in a discharge on the compression-
        # matched cone at time_step_scale 0.8)
        w2, p0, p1, p2, p3 = plastic_strain_and_work(sig[i], (e0t, e1t, e2t, e3t), (s0, s1, s2, s3), c, G)
        diss += 0.5 * dV[i] * w2
        if apex:
            eqps_new[i] = eqps[i] + equivalent_strain(p0, p1, p2, p3)
            if recompact > 0.0:  # pulled apart: remember the opening
                opening_new[i] = op + max(p0 + p1 + p2, 0.0)
    return diss
