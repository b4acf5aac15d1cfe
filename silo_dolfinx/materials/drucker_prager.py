"""Elastic-perfectly plastic Drucker-Prager, non-associated, in the thesis' convention.

Yield      F = q − p tan β − d ≤ 0          (q = √(3 J2), p = −tr σ/3, compression +)
Potential  G = q − p tan ψ                  (ψ ≤ β; ψ = β is associated)

Return mapping (exact for this linear cone; de Souza Neto, Perić & Owen 2008, §8.3):
with the elastic trial (p*, q*, s*), the flow ∂G/∂σ = (3/2) s/q + (tan ψ/3) I gives

    q = q* − 3G Δλ,   p = p* + K tan ψ Δλ,   Δλ = F* / (3G + K tan β tan ψ),

valid while q ≥ 0. Otherwise the trial lies beyond the apex and the stress returns to the
apex p = −d/tan β, q = 0. Δλ is also the equivalent (deviatoric) plastic strain increment;
the plastic volume change is tan ψ Δλ (dilation for ψ > 0).

Critical state (optional): with ``max_dilation`` ε_c > 0 a point stops dilating once its
plastic volume change tan ψ · ε̄_p reaches ε_c (ψ → 0 from then on), as a sheared granular
solid does at its critical state. Without it the density near an outlet keeps falling.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from silo_dolfinx.materials.base import Material, elastic_trial, invariants


class DruckerPrager(Material):
    name = "drucker_prager"
    plastic = True
    state_fields = {"eqps": 1}  # equivalent plastic strain

    def __init__(self, youngs_modulus, poisson_ratio, density, friction_angle, dilation_angle, cohesion,
                 max_dilation: float = 0.0):
        super().__init__(youngs_modulus, poisson_ratio, density)
        self.friction_angle, self.dilation_angle, self.cohesion = friction_angle, dilation_angle, cohesion
        self.tan_beta = math.tan(math.radians(friction_angle))
        self.tan_psi = math.tan(math.radians(dilation_angle))
        # ε̄_p beyond which ψ = 0 (inf: never)
        self.eqps_critical = max_dilation / self.tan_psi if max_dilation > 0.0 and self.tan_psi > 0.0 else math.inf

    noncoaxial = 0.0  # 4G²/(H_nc + 2G): zero for the coaxial law (see non_coaxial.py)

    def update(self, sig, deps, state_old, sig_new, state_new, dV) -> float:
        return float(_update(sig, deps, state_old["eqps"], self.K, self.G, self.tan_beta, self.tan_psi,
                             self.cohesion, self.noncoaxial, self.eqps_critical, sig_new, state_new["eqps"], dV))

    def yield_function(self, sig: np.ndarray) -> np.ndarray:
        """F(σ) for an (n, 4) array (≤ 0 admissible)."""
        out = np.empty(sig.shape[0])
        for i in range(sig.shape[0]):
            p, q, *_ = invariants(sig[i])
            out[i] = q - p * self.tan_beta - self.cohesion
        return out


@numba.njit(cache=True)
def return_map(s_trial, K, G, tanb, tanpsi, d, out):
    """Return one trial stress to the yield surface; returns (Δλ, apex?)."""
    p, q, d0, d1, d2, d3 = invariants(s_trial)
    f = q - p * tanb - d
    if f <= 0.0:
        out[:] = s_trial
        return 0.0, False
    dlam = f / (3.0 * G + K * tanb * tanpsi)
    if 3.0 * G * dlam <= q:
        qn = q - 3.0 * G * dlam
        pn = p + K * tanpsi * dlam
        k = qn / q
        out[0] = k * d0 - pn
        out[1] = k * d1 - pn
        out[2] = k * d2 - pn
        out[3] = k * d3
        return dlam, False
    # apex: q = 0 on the yield surface (tan β > 0 here, else the cone return is always valid)
    pa = -d / tanb
    out[0] = -pa
    out[1] = -pa
    out[2] = -pa
    out[3] = 0.0
    return dlam, True


@numba.njit(cache=True, inline="always")
def _trial_yield(t0, t1, t2, t3, tanb, d):
    """Deviator (normal components), q, p and F of a stress given by its 4 components."""
    m = (t0 + t1 + t2) * (1.0 / 3.0)
    d0, d1, d2 = t0 - m, t1 - m, t2 - m
    q = math.sqrt(1.5 * (d0 * d0 + d1 * d1 + d2 * d2) + 3.0 * t3 * t3)
    return d0, d1, d2, q, -m, q - (-m) * tanb - d


@numba.njit(cache=True, fastmath={"contract", "arcp", "reassoc", "nsz", "afn"})
def _update(sig, deps, eqps, K, G, tanb, tanpsi0, d, c_nc, eqps_c, sig_new, eqps_new, dV):
    """The return map of :func:`return_map` over all points, written out in scalars (the
    hot loop of a plastic step); also the plastic dissipation σ : Δε_p and ε̄_p.

    c_nc = 4G²/(H_nc + 2G) > 0 adds the yield-vertex non-coaxial plastic strain (eq. 8-11)
    at points that load plastically: the trial deviator loses c_nc Δe_t, Δe_t the part of
    the deviatoric strain increment tangential to the current deviator s (s : Δe_t = 0).
    Points with ε̄_p ≥ eqps_c flow at constant volume (ψ = 0: the critical state)."""
    diss = 0.0
    lam = K - 2.0 * G / 3.0
    two_g = 2.0 * G
    c = lam / (3.0 * lam + 2.0 * G)
    for i in range(sig.shape[0]):
        e0, e1, e2, e3 = deps[i, 0], deps[i, 1], deps[i, 2], deps[i, 3]
        tr = e0 + e1 + e2
        t0 = sig[i, 0] + lam * tr + two_g * e0
        t1 = sig[i, 1] + lam * tr + two_g * e1
        t2 = sig[i, 2] + lam * tr + two_g * e2
        t3 = sig[i, 3] + G * e3
        d0, d1, d2, q, p, f = _trial_yield(t0, t1, t2, t3, tanb, d)
        if f <= 0.0:
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
                if f <= 0.0:
                    s0n, s1n, s2n, s3n = t0, t1, t2, t3
                    sig_new[i, 0], sig_new[i, 1], sig_new[i, 2], sig_new[i, 3] = s0n, s1n, s2n, s3n
                    r0, r1, r2, r3 = e0t - s0n, e1t - s1n, e2t - s2n, e3t - s3n
                    rt = r0 + r1 + r2
                    diss += dV[i] * (s0n * (r0 - c * rt) + s1n * (r1 - c * rt) + s2n * (r2 - c * rt)) / two_g \
                        + dV[i] * s3n * r3 / G
                    eqps_new[i] = eqps[i]
                    continue
        tanpsi = tanpsi0 if eqps[i] < eqps_c else 0.0
        dlam = f / (3.0 * G + K * tanb * tanpsi)
        if 3.0 * G * dlam <= q:  # return to the cone
            qn = q - 3.0 * G * dlam
            pn = p + K * tanpsi * dlam
            k = qn / q
            s0, s1, s2, s3 = k * d0 - pn, k * d1 - pn, k * d2 - pn, k * t3
            eqps_new[i] = eqps[i] + dlam
            apex = False
        else:  # return to the apex p = −d/tan β, q = 0
            pa = -d / tanb
            s0, s1, s2, s3 = -pa, -pa, -pa, 0.0
            apex = True
        sig_new[i, 0], sig_new[i, 1], sig_new[i, 2], sig_new[i, 3] = s0, s1, s2, s3
        # plastic strain Δε_p = C⁻¹ (σ_trial,elastic − σ_new) (coaxial + non-coaxial) and its
        # dissipation σ_new : Δε_p
        r0, r1, r2, r3 = e0t - s0, e1t - s1, e2t - s2, e3t - s3
        rt = r0 + r1 + r2
        p0 = (r0 - c * rt) / two_g
        p1 = (r1 - c * rt) / two_g
        p2 = (r2 - c * rt) / two_g
        p3 = r3 / G
        diss += dV[i] * (s0 * p0 + s1 * p1 + s2 * p2 + s3 * p3)
        if apex:
            pm = (p0 + p1 + p2) * (1.0 / 3.0)
            eqps_new[i] = eqps[i] + math.sqrt(2.0 / 3.0 * ((p0 - pm) ** 2 + (p1 - pm) ** 2 + (p2 - pm) ** 2
                                                           + 0.5 * p3 * p3))
    return diss
