"""Closed-form solutions the simulations are judged against (SI units, angles in degrees).

Each function states its source (thesis equation number where there is one), its units
and its validity range, and refuses inputs outside that range with a ValueError naming
the argument.
"""

from __future__ import annotations

import math


def _positive(**kw):
    for k, v in kw.items():
        if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
            raise ValueError(f"{k} = {v!r}: must be a positive finite number")


def _poisson(nu):
    if not -1.0 < nu < 0.5:
        raise ValueError(f"poisson_ratio = {nu!r}: must be in (-1, 0.5)")


def constrained_modulus(youngs_modulus: float, poisson_ratio: float) -> float:
    """P-wave modulus M = E(1−ν)/((1+ν)(1−2ν)) (Pa) of uniaxial strain."""
    _positive(youngs_modulus=youngs_modulus)
    _poisson(poisson_ratio)
    E, nu = youngs_modulus, poisson_ratio
    return E * (1 - nu) / ((1 + nu) * (1 - 2 * nu))


def confined_wave_speed(youngs_modulus: float, poisson_ratio: float, density: float) -> float:
    """Speed (m/s) of a longitudinal wave in a laterally confined column, √(M/ρ).

    The numerator of eq. 4-12; valid for small-amplitude elastic waves.
    """
    _positive(density=density)
    return math.sqrt(constrained_modulus(youngs_modulus, poisson_ratio) / density)


def longitudinal_frequency(youngs_modulus: float, poisson_ratio: float, density: float, height: float) -> float:
    """Eq. 4-12: f_n = √(E(1−ν)/(ρ(1+ν)(1−2ν))) / (2 h_f)  (Hz), elastic bar with free ends.

    The thesis' ch. 4 hopper (E 5.5e5 Pa, ν 0.3, ρ 1000 kg/m³, h_f 2.64 m) gives 5.2 Hz.
    """
    _positive(height=height)
    return confined_wave_speed(youngs_modulus, poisson_ratio, density) / (2.0 * height)


def fixed_free_frequency(youngs_modulus: float, poisson_ratio: float, density: float, height: float) -> float:
    """Fundamental frequency (Hz) of a laterally confined column fixed at the base, free on top:
    f_1 = c/(4 H), c the confined wave speed."""
    _positive(height=height)
    return confined_wave_speed(youngs_modulus, poisson_ratio, density) / (4.0 * height)


def geostatic_stress(density: float, gravity: float, height: float, z, poisson_ratio: float | None = None,
                     k0: float | None = None):
    """Stress (σ_rr, σ_zz, σ_θθ) in Pa (tension +) at height z of a column of height H at rest
    under gravity between frictionless walls: σ_zz = −ρ g (H − z), σ_rr = σ_θθ = K0 σ_zz with
    K0 = ν/(1−ν) for an elastic solid (or the given k0). Valid for 0 ≤ z ≤ H."""
    import numpy as np

    _positive(density=density, gravity=gravity, height=height)
    z = np.asarray(z, float)
    if np.any(z < -1e-12 * height) or np.any(z > height * (1 + 1e-12)):
        raise ValueError("z: heights must lie in [0, height]")
    if k0 is None:
        if poisson_ratio is None:
            raise ValueError("give poisson_ratio or k0")
        _poisson(poisson_ratio)
        k0 = poisson_ratio / (1.0 - poisson_ratio)
    szz = -density * gravity * (height - z)
    return k0 * szz, szz, k0 * szz


def thick_cylinder_limit_pressure(yield_stress: float, inner_radius: float, outer_radius: float) -> float:
    """Hill (1950): limit internal pressure (Pa) of a thick-walled cylinder in plane strain,
    von Mises (q = √(3 J2) = yield_stress): p = (2 σ_y/√3) ln(b/a). Requires b > a > 0."""
    _positive(yield_stress=yield_stress, inner_radius=inner_radius, outer_radius=outer_radius)
    if outer_radius <= inner_radius:
        raise ValueError(f"outer_radius = {outer_radius!r}: must exceed inner_radius = {inner_radius!r}")
    return 2.0 * yield_stress / math.sqrt(3.0) * math.log(outer_radius / inner_radius)


def drucker_prager_limit_ratio(friction_angle: float) -> float:
    """Limit stress ratio q/p = tan β of the thesis' Drucker-Prager (eq. 4-11), cohesionless.
    β = 30° gives 0.5773 (ch. 4.5). Valid for 0 ≤ β < 90°."""
    if not 0.0 <= friction_angle < 90.0:
        raise ValueError(f"friction_angle = {friction_angle!r}: must be in [0, 90) degrees")
    return math.tan(math.radians(friction_angle))
