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


def shear_wave_speed(youngs_modulus: float, poisson_ratio: float, density: float) -> float:
    """Speed (m/s) of a shear wave, √(G/ρ) with G = E/(2(1+ν)); elastic, small amplitude."""
    _positive(youngs_modulus=youngs_modulus, density=density)
    _poisson(poisson_ratio)
    return math.sqrt(youngs_modulus / (2.0 * (1.0 + poisson_ratio)) / density)


def longitudinal_frequency(youngs_modulus: float, poisson_ratio: float, density: float, height: float) -> float:
    """Eq. 4-12: f_n = √(E(1−ν)/(ρ(1+ν)(1−2ν))) / (2 h_f)  (Hz), elastic bar with free ends.

    The thesis' ch. 4 hopper (E 5.5e5 Pa, ν 0.3, ρ 1000 kg/m³, h_f 2.64 m) gives 5.2 Hz.
    """
    _positive(height=height)
    return confined_wave_speed(youngs_modulus, poisson_ratio, density) / (2.0 * height)


J1_FIRST_ROOT = 3.8317059702075125  # the first positive zero of the Bessel function J1


def radial_frequency(youngs_modulus: float, poisson_ratio: float, density: float, radius: float) -> float:
    """Fundamental radial (breathing) frequency (Hz) of a long elastic column inside a rigid
    cylindrical wall of radius R: axisymmetric motion u_r(r) with no axial part is
    dilatational, u_r ∝ J1(ω r/c), c = √(M/ρ), and the wall holds u_r(R) = 0, so
    ω R/c = j_1,1 = 3.8317 and f = 3.8317 c/(2πR). The ch. 6 silo (R 0.35 m, c 43.0 m/s):
    75.0 Hz. Independent of the wall's friction (the motion has no shear on the wall)."""
    _positive(radius=radius)
    return J1_FIRST_ROOT * confined_wave_speed(youngs_modulus, poisson_ratio, density) / (2.0 * math.pi * radius)


J0_FIRST_ROOT = 2.404825557695773  # the first positive zero of the Bessel function J0


def axial_shear_frequency(youngs_modulus: float, poisson_ratio: float, density: float, radius: float,
                          wall: str = "slip") -> float:
    """Fundamental frequency (Hz) of the vertical shear mode of a long elastic column inside a
    cylindrical wall of radius R: axisymmetric motion u_z(r) with no radial part is a shear
    wave, u_z ∝ J0(ω r/c_s), c_s = √(G/ρ), and the wall sets the root. ``wall="slip"``: a wall
    that slides with an unchanged shear traction (Coulomb sliding, τ = μ p_n, under a motion
    that leaves p_n alone), σ_rz(R) = 0, so J0'(kR) = −J1(kR) = 0, j_1,1 = 3.8317 - a mode that
    moves no net momentum (∫ J0(kr) r dr = R J1(kR)/k = 0), the axis against the wall with a
    node at r = 0.628 R. ``wall="stick"``: u_z(R) = 0, j_0,1 = 2.4048. f = j c_s/(2πR). The ch.
    7 bin (R 0.35 m, E 2 MPa, ν 0.3, ρ 1529 kg/m³, c_s 22.4 m/s): 39.1 Hz sliding, 24.5 Hz stuck."""
    _positive(radius=radius)
    roots = {"slip": J1_FIRST_ROOT, "stick": J0_FIRST_ROOT}
    if wall not in roots:
        raise ValueError(f"wall = {wall!r}: say 'slip' (a sliding wall) or 'stick' (a stuck one)")
    return roots[wall] * shear_wave_speed(youngs_modulus, poisson_ratio, density) / (2.0 * math.pi * radius)


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


# ---------------------------------------------------------------------------- silo pressures
def _nonneg_array(name, x):
    import numpy as np

    a = np.asarray(x, float)
    if np.any(~np.isfinite(a)) or np.any(a < 0):
        raise ValueError(f"{name}: values must be finite and ≥ 0")
    return a


def janssen(depth, radius: float, mu: float, k: float, unit_weight: float, surcharge: float = 0.0):
    """Janssen (1895) in the EN 1991-4 form for a circular silo (Pa).

    depth z below the equivalent surface (m, ≥ 0); radius R (m); wall friction μ; lateral
    pressure ratio K; unit weight γ (N/m³); top surcharge q (Pa). With the Janssen depth
    z0 = R/(2 K μ) (eq. 5-1's X0 with D = 2R):

        p_v = γ z0 (1 − e^{−z/z0}) + q e^{−z/z0},   p_h = K p_v,   p_w = μ p_h.

    Returns (p_h, p_w, p_v). Valid for a parallel-walled (cylindrical) silo.
    """
    _positive(radius=radius, mu=mu, k=k, unit_weight=unit_weight)
    if surcharge < 0:
        raise ValueError(f"surcharge = {surcharge!r}: must be ≥ 0")
    import numpy as np

    z = _nonneg_array("depth", depth)
    z0 = janssen_depth(radius, mu, k)
    e = np.exp(-z / z0)
    pv = unit_weight * z0 * (1.0 - e) + surcharge * e
    return k * pv, mu * k * pv, pv


def janssen_depth(radius: float, mu: float, k: float) -> float:
    """Janssen's characteristic depth z0 = R/(2 K μ) = D/(4 μ k) (m) (X0 of eq. 5-1)."""
    _positive(radius=radius, mu=mu, k=k)
    return radius / (2.0 * k * mu)


def _hopper_geometry(half_angle, outlet_radius, height):
    a = math.radians(half_angle)
    if not 0.0 < half_angle < 90.0:
        raise ValueError(f"half_angle = {half_angle!r}: must be in (0, 90) degrees")
    _positive(height=height)
    if outlet_radius < 0:
        raise ValueError(f"outlet_radius = {outlet_radius!r}: must be ≥ 0")
    h0 = outlet_radius / math.tan(a)  # apex to outlet
    return a, h0, h0 + height


def walker_parameters(friction_angle: float, wall_friction: float, half_angle: float, kappa: int = -1):
    """Walker's (1966) wall-stress ratio F and exponent m for a conical hopper (eqs. 4-1, 4-3).

    sin ω = sin φ_w / sin φ locates the wall stress on the Mohr circle. κ = +1 is the passive
    (discharge) state, κ = −1 the active (filling) state; with κ applied to F as to m,

        F = (1 + κ sin φ cos(ω + κφ_w)) / (1 − κ sin φ cos(ω + κφ_w + 2κα))     (eq. 4-1 at κ = +1)
        m = 2 sin φ sin(ω + κφ_w + 2κα) / (tan α [1 − κ sin φ cos(ω + κφ_w + 2κα)])   (eq. 4-3)

    which satisfy the slice equilibrium m ≈ 2[F(1 + μ cot α) − 1]. Angles in degrees; the
    wall friction angle φ_w = atan μ must not exceed φ. Returns (F, m).
    """
    if kappa not in (-1, 1):
        raise ValueError(f"kappa = {kappa!r}: must be -1 (filling, active) or +1 (discharge, passive)")
    if not 0.0 < friction_angle < 90.0:
        raise ValueError(f"friction_angle = {friction_angle!r}: must be in (0, 90) degrees")
    if not 0.0 <= wall_friction < math.tan(math.radians(friction_angle)):
        raise ValueError(f"wall_friction = {wall_friction!r}: must be in [0, tan φ)")
    a = math.radians(half_angle)
    if not 0.0 < half_angle < 90.0:
        raise ValueError(f"half_angle = {half_angle!r}: must be in (0, 90) degrees")
    phi, phiw = math.radians(friction_angle), math.atan(wall_friction)
    s = math.sin(phi)
    om = math.asin(math.sin(phiw) / s)
    ang = om + kappa * phiw + 2 * kappa * a
    F = (1 + kappa * s * math.cos(om + kappa * phiw)) / (1 - kappa * s * math.cos(ang))
    m = 2 * s * math.sin(ang) / (math.tan(a) * (1 - kappa * s * math.cos(ang)))
    return F, m


def mclean_m(wall_friction: float, half_angle: float) -> float:
    """McLean's (1985) exponent m = 2 μ_w / tan α (eq. 4-4), to use in eq. 4-2."""
    if wall_friction < 0:
        raise ValueError(f"wall_friction = {wall_friction!r}: must be ≥ 0")
    if not 0.0 < half_angle < 90.0:
        raise ValueError(f"half_angle = {half_angle!r}: must be in (0, 90) degrees")
    return 2.0 * wall_friction / math.tan(math.radians(half_angle))


def hopper_vertical_stress(z, m: float, half_angle: float, outlet_radius: float, height: float,
                           unit_weight: float, surcharge: float = 0.0):
    """Eq. 4-2: the mean vertical stress (Pa) at height z above the outlet of a truncated cone
    of the given height, with h' measured from the apex and h_a its top value:

        σ = γ h'/(m − 1) [1 − (h'/h_a)^{m−1}] + Q0 (h'/h_a)^m      (m = 1: −γ h' ln(h'/h_a) + Q0 h'/h_a)

    Valid for 0 ≤ z ≤ height."""
    import numpy as np

    _positive(unit_weight=unit_weight)
    a, h0, ha = _hopper_geometry(half_angle, outlet_radius, height)
    z = np.asarray(z, float)
    if np.any(z < -1e-12) or np.any(z > height * (1 + 1e-12)):
        raise ValueError("z: heights must lie in [0, height]")
    hp = np.maximum(z + h0, 1e-300)
    x = hp / ha
    if abs(m - 1.0) < 1e-12:
        sv = -unit_weight * hp * np.log(x)
    else:
        sv = unit_weight * hp / (m - 1.0) * (1.0 - x ** (m - 1.0))
    return sv + surcharge * x**m


def walker_hopper(z, friction_angle: float, wall_friction: float, half_angle: float, outlet_radius: float,
                  height: float, unit_weight: float, kappa: int = -1, surcharge: float = 0.0, m: float | None = None):
    """Walker's hopper wall pressures (eqs. 4-1 to 4-3): p_n = F σ(z), p_s = μ p_n (Pa).

    ``m`` overrides eq. 4-3 (e.g. McLean's eq. 4-4). Returns (p_n, p_s)."""
    F, m_w = walker_parameters(friction_angle, wall_friction, half_angle, kappa)
    sv = hopper_vertical_stress(z, m_w if m is None else m, half_angle, outlet_radius, height, unit_weight,
                                surcharge)
    return F * sv, wall_friction * F * sv


def en1991_hopper(z, wall_friction: float, half_angle: float, outlet_radius: float, height: float,
                  unit_weight: float, surcharge: float = 0.0, discharge: bool = False,
                  friction_angle: float | None = None, b: float = 0.2):
    """EN 1991-4 (2006) conical hopper pressures (thesis ch. 7.4.2), Pa; returns (p_n, p_s).

    Filling: F_f = 1 − b/(1 + tan α/μ) = (1 + 0.8 μ cot α)/(1 + μ cot α) (b = 0.2).
    Discharge: F_e = (1 + sin φ cos ε)/(1 − sin φ cos(2α + ε)), ε = φ_w + asin(sin φ_w/sin φ).
    Then n = 2 (F μ cot α + F) − 2 and the vertical stress is eq. 4-2 with m = n; the
    surcharge is the vertical stress at the transition (the bin's Janssen load, or 0)."""
    a = math.radians(half_angle)
    mu = wall_friction
    if discharge:
        if friction_angle is None:
            raise ValueError("friction_angle: needed for the discharge ratio F_e")
        phi, phiw = math.radians(friction_angle), math.atan(mu)
        if phiw >= phi:
            raise ValueError("wall_friction: atan(μ) must be below the friction angle")
        eps = phiw + math.asin(math.sin(phiw) / math.sin(phi))
        F = (1 + math.sin(phi) * math.cos(eps)) / (1 - math.sin(phi) * math.cos(2 * a + eps))
    else:
        F = 1.0 - b / (1.0 + math.tan(a) / mu)
    n = 2.0 * (F * mu / math.tan(a) + F) - 2.0
    sv = hopper_vertical_stress(z, n, half_angle, outlet_radius, height, unit_weight, surcharge)
    return F * sv, mu * F * sv


# ---------------------------------------------------------------------------- flow rate
def beverloo(density: float, outlet_diameter: float, c: float = 0.58, lam: float = 1.5,
             particle_size: float = 0.0, gravity: float = 9.81) -> float:
    """Beverloo et al. (1961), eq. 4-6: W = C ρ √g (D0 − λ d)^{5/2}  (kg/s).

    C ≈ 0.58 (0.64 for very smooth particles), λ ≈ 1.5; valid for D0 > λ d. For the ch. 4
    hopper (ρ 1000, D0 0.2 m, d 0) it gives 32.5 kg/s."""
    _positive(density=density, outlet_diameter=outlet_diameter, c=c, gravity=gravity)
    if particle_size < 0 or lam < 0:
        raise ValueError("particle_size and lam must be ≥ 0")
    eff = outlet_diameter - lam * particle_size
    if eff <= 0:
        raise ValueError(f"outlet_diameter = {outlet_diameter!r}: must exceed lam × particle_size = {lam * particle_size!r}")
    return c * density * math.sqrt(gravity) * eff**2.5


def hourglass_discharge(friction_angle: float, half_angle: float, outlet_radius: float, height: float,
                        density: float = 1.0, gravity: float = 9.81) -> dict:
    """Free discharge of a smooth-walled conical hopper by the hourglass theory (Savage 1965;
    Davidson & Nedderman 1973; Nedderman 1992 ch. 10) for a Drucker–Prager solid.

    Steady incompressible radial flow u_r = −A/r² towards the apex (r: spherical radius);
    radial stress field with the hoop stresses the major ones at yield, σ_θ = σ_φ = k σ_r
    (converging flow), which for q = p tan β gives k = (3 + tan β)/(3 − 2 tan β). Radial
    momentum ρ u_r ∂u_r/∂r = −dσ_r/dr + 2(k − 1)σ_r/r − ρg, with σ_r = 0 on the outlet sphere
    r0 = R0/sin α and on the top sphere r1 = H + R0/tan α (the fill's height above the
    apex on the axis), gives, with n = 2(k − 1),

        u0² = g r0 (n + 4)/(2(n − 1)) · (1 − (r0/r1)^{n−1}) / (1 − (r0/r1)^{n+4}).

    Returns u0 (radial speed on the outlet sphere), ``mean_outlet_velocity`` (the flux over
    the flat outlet disc: 2 u0/(1 + cos α)), ``mass_flow`` ρ u0 2π r0²(1 − cos α) (kg/s) and
    k, n. Idealisations: smooth wall (μ_w = 0), no dilation, p uniform over each sphere, the
    axial gravity component g (not g cos θ). β = 30°, the ch. 4 hopper: u0 2.74 m/s, mean
    2.85 m/s. Valid for 0 < tan β < 1.5 and α in (0, 90)°."""
    _positive(outlet_radius=outlet_radius, height=height, density=density, gravity=gravity)
    if not 0.0 < half_angle < 90.0:
        raise ValueError(f"half_angle = {half_angle!r}: must be in (0, 90) degrees")
    t = drucker_prager_limit_ratio(friction_angle)
    if not 0.0 < t < 1.5:
        raise ValueError(f"friction_angle = {friction_angle!r}: tan β must be in (0, 1.5)")
    k = (3.0 + t) / (3.0 - 2.0 * t)
    n = 2.0 * (k - 1.0)
    a = math.radians(half_angle)
    r0 = outlet_radius / math.sin(a)
    r1 = height + outlet_radius / math.tan(a)
    q = r0 / r1
    if abs(n - 1.0) < 1e-9:  # the limit (1 − q^{n−1})/(n − 1) → −ln q
        ratio = -math.log(q)
    else:
        ratio = (1.0 - q ** (n - 1.0)) / (n - 1.0)
    u0 = math.sqrt(gravity * r0 * 0.5 * (n + 4.0) * ratio / (1.0 - q ** (n + 4.0)))
    return {"u0": u0, "mean_outlet_velocity": 2.0 * u0 / (1.0 + math.cos(a)),
            "mass_flow": density * u0 * 2.0 * math.pi * r0**2 * (1.0 - math.cos(a)), "k": k, "n": n}


def rose_tanaka_factor(half_angle: float, stagnant_angle: float) -> float:
    """Rose & Tanaka (1956), eq. 4-8: F = (tan α tan φ_d)^{−0.35} for α < 90° − φ_d, else 1.

    α: hopper half-angle; φ_d: angle of the stagnant zone boundary to the horizontal (deg)."""
    for name, v in (("half_angle", half_angle), ("stagnant_angle", stagnant_angle)):
        if not 0.0 < v < 90.0:
            raise ValueError(f"{name} = {v!r}: must be in (0, 90) degrees")
    if half_angle < 90.0 - stagnant_angle:
        return (math.tan(math.radians(half_angle)) * math.tan(math.radians(stagnant_angle))) ** -0.35
    return 1.0


# ---------------------------------------------------------------------------- waves
def wensrich_exponent(diameter: float, mu: float, k: float) -> float:
    """Growth exponent 1/(2 X0) (1/m) of a rarefaction wave in a parallel column,
    X0 = D/(4 μ k) (eq. 5-1): σ⁺/σ⁺0 = exp(x/(2 X0))."""
    _positive(diameter=diameter, mu=mu, k=k)
    return 2.0 * mu * k / diameter


def _wave_inputs(x, diameter: float, mu: float, k: float, half_angle: float):
    """The ch. 5 growth laws' checked inputs: (x as an array, eq. 5-1's σ⁺/σ⁺0 if α = 0 else None)."""
    import numpy as np

    _positive(diameter=diameter, mu=mu, k=k)
    x = _nonneg_array("x", x)
    if half_angle == 0.0:
        return x, np.exp(x * wensrich_exponent(diameter, mu, k))
    if not -45.0 < half_angle < 45.0:
        raise ValueError(f"half_angle = {half_angle!r}: must be in (-45, 45) degrees (small-angle theory)")
    return x, None


def wave_growth(x, diameter: float, mu: float, k: float, half_angle: float = 0.0):
    """σ⁺/σ⁺0 of a small rarefaction wave after travelling x (m) up a column of base
    diameter D with wall friction μ and lateral ratio k (ch. 5):

        α = 0: exp(x/(2X0))                                      (eq. 5-1)
        α > 0 (converging, widening upwards): (1 + 2x sin α/D)^{k(1 + μ/tan α)}   (eq. 5-14)
        α < 0 (diverging): (1 − 2x sin|α|/D)^{k(1 − μ/tan|α|)}                   (eq. 5-15)

    Both tend to eq. 5-1 as α → 0. Valid for small |α| (the thesis: |α| < 3°) and, when
    diverging, below the apex (2x sin|α| < D)."""
    import numpy as np

    x, parallel = _wave_inputs(x, diameter, mu, k, half_angle)
    if parallel is not None:
        return parallel
    a = math.radians(abs(half_angle))
    if half_angle > 0:
        return (1.0 + 2.0 * x * math.sin(a) / diameter) ** (k * (1.0 + mu / math.tan(a)))
    base = 1.0 - 2.0 * x * math.sin(a) / diameter
    if np.any(base <= 0):
        raise ValueError("x: beyond the apex of the diverging column (2x sin|α| ≥ D)")
    return base ** (k * (1.0 - mu / math.tan(a)))


def taper_wave_growth(x, diameter: float, mu: float, k: float, half_angle: float = 0.0):
    """σ⁺/σ⁺0 of a small rarefaction wave after travelling x (m) up a tapered column, from the
    same 1-D slice model as eqs. 5-14/5-15 but keeping the lateral strain the taper imposes:

        σ⁺/σ⁺0 = G^{k μ / tan α − 1},   G = D(x)/D = 1 + 2x tan α/D   (α > 0 widening upwards)

    Derivation (x up, D(x) = D G, A = π D²/4, s the axial stress relieved, w the downward
    velocity, M the constrained modulus, k the lateral/axial ratio of the increments, the wall
    sliding with τ = μ p_w):

        ρ w_t = −s_x − a s,   a = (1 − k) A'/A − μ k P/A      (slice momentum: the stress on
                                                              its faces, the wall's normal
                                                              reaction k s A', friction)
        s_t  = −M (w_x + b w),  b = k A'/A                     (uniaxial strain plus the radial
                                                              strain w A'/(2A) of a slice that
                                                              slides along the taper)

    A wave front's amplitude obeys S'/S = −(a + b)/2 = 2 μ k/D(x) − A'/(2A): the friction term
    of eq. 5-1 and a horn's A^{−1/2}; integrated, the power above. It tends to eq. 5-1 as
    α → 0; eqs. 5-14/5-15 have the exponent k(1 + μ/tan α) instead (their area term +k where
    this has −1). Small |α|; diverging (α < 0) only below the apex (2x tan|α| < D)."""
    import numpy as np

    x, parallel = _wave_inputs(x, diameter, mu, k, half_angle)
    if parallel is not None:
        return parallel
    t = math.tan(math.radians(half_angle))
    G = 1.0 + 2.0 * x * t / diameter
    if np.any(G <= 0):
        raise ValueError("x: beyond the apex of the diverging column (2x tan|α| ≥ D)")
    return G ** (k * mu / t - 1.0)


# ---------------------------------------------------------------------------- wall friction
def dynamic_friction(slip_speed, mu_static: float, mu_kinetic: float, decay: float):
    """Eq. 7-1: μ_d = μ_k + (μ_s − μ_k) exp(−ϖ |v_slip|), ϖ in s/m; needs μ_k ≤ μ_s."""
    import numpy as np

    if not 0.0 <= mu_kinetic <= mu_static:
        raise ValueError("need 0 ≤ mu_kinetic ≤ mu_static")
    if decay < 0:
        raise ValueError(f"decay = {decay!r}: must be ≥ 0")
    return mu_kinetic + (mu_static - mu_kinetic) * np.exp(-decay * np.abs(np.asarray(slip_speed, float)))


# ---------------------------------------------------------------------------- Drucker-Prager at a wall
def drucker_prager_active_k(friction_angle: float) -> float:
    """Lateral pressure ratio K = σ_h/σ_v of a cohesionless Drucker-Prager solid at yield in
    axisymmetric compression (σ_rr = σ_θθ = K σ_zz, the active state of a settling fill):
    q = p tan β gives K = (3 − tan β)/(3 + 2 tan β). β = 35° gives 0.523; the thesis' Janssen
    K = 0.38 would need tan β = 1.06 (β ≈ 47°). Valid for 0 ≤ tan β < 3."""
    t = drucker_prager_limit_ratio(friction_angle)
    if t >= 3.0:
        raise ValueError(f"friction_angle = {friction_angle!r}: tan β must be below 3")
    return (3.0 - t) / (3.0 + 2.0 * t)


def drucker_prager_compression_angle(friction_angle: float) -> float:
    """Mohr–Coulomb friction angle φ (degrees) with the same limit as a cohesionless
    Drucker–Prager solid in axisymmetric compression (σ_rr = σ_θθ, the state of a fill):
    sin φ = 3 tan β/(6 + tan β). Its active ratio (1 − sin φ)/(1 + sin φ) is
    :func:`drucker_prager_active_k`. The φ to put into Walker's or Jenike's theories when they
    are compared with this model: β = 30° gives 15.3°, β = 35° 18.3° (not β itself). Valid for
    0 ≤ tan β < 3. (:func:`mohr_coulomb_angle` with the compression rule.)"""
    if drucker_prager_limit_ratio(friction_angle) >= 3.0:
        raise ValueError(f"friction_angle = {friction_angle!r}: tan β must be below 3")
    return mohr_coulomb_angle(friction_angle, "compression")


def drucker_prager_cone_for_mohr_coulomb(friction_angle: float) -> float:
    """Drucker–Prager slope β (degrees) whose cone meets the Mohr–Coulomb cone of angle φ in
    axisymmetric compression: tan β = 6 sin φ/(3 − sin φ), the inverse of
    :func:`drucker_prager_compression_angle`. φ = 30° gives 50.2°, 35° 54.8°, 40° 58.6°. The
    scenes' default reading of a friction angle (``material.cone = "compression"``)."""
    return drucker_prager_cone(friction_angle, 0.0, "compression")[0]


# How a Mohr–Coulomb angle becomes the slope β of the Drucker–Prager cone (q = p tan β + d,
# q = √(3 J2), p the mean pressure, compression +); the scene key ``material.cone``.
CONES = {
    "compression": "the cones meet in axisymmetric compression (σ2 = σ3, a settling fill): "
                   "tan β = 6 sin φ/(3 − sin φ); the outer cone",
    "extension": "the cones meet in axisymmetric extension (σ1 = σ2): tan β = 6 sin φ/(3 + sin φ); "
                 "the inner cone",
    "plane_strain": "the same plane-strain limit load: associated flow (ψ = φ) tan β = 3√3 tan φ/"
                    "√(9 + 12 tan² φ), otherwise tan β = √3 sin φ (the zero-dilation match); ψ by the "
                    "associated formula",
    "plane_strain_zero_dilation": "tan β = √3 sin φ and tan ψ_DP = √3 sin ψ (the thesis' ch. 8 choice: "
                                  "the plane-strain match for ψ = 0)",
    "beta": "no mapping: the angles are the Drucker–Prager slopes β and ψ themselves (the thesis' "
            "stated convention, ch. 4.5: 30° → q/p = 0.577)",
}


def _cone_tan(angle: float, cone: str, associated: bool) -> float:
    s, t = math.sin(math.radians(angle)), math.tan(math.radians(angle))
    if cone == "compression":
        return 6.0 * s / (3.0 - s)
    if cone == "extension":
        return 6.0 * s / (3.0 + s)
    if cone == "plane_strain" and associated:
        return 3.0 * math.sqrt(3.0) * t / math.sqrt(9.0 + 12.0 * t * t)
    if cone in ("plane_strain", "plane_strain_zero_dilation"):
        return math.sqrt(3.0) * s
    return t  # "beta"


def drucker_prager_cone(friction_angle: float, dilation_angle: float, cone: str = "compression"):
    """(β, ψ_DP) in degrees: the Drucker–Prager friction and dilation slopes for Mohr–Coulomb
    angles φ, ψ under the matching rule ``cone`` (a key of :data:`CONES`). ψ is mapped by the
    same rule (plane strain: by its associated-flow formula, so that ψ = φ gives ψ_DP = β).
    Valid for 0 ≤ ψ ≤ φ < 90° (``"beta"``: the angles are returned as they are)."""
    if cone not in CONES:
        raise ValueError(f"cone = {cone!r}: must be one of {', '.join(CONES)}")
    if not 0.0 <= dilation_angle <= friction_angle < 90.0:
        raise ValueError(f"angles φ = {friction_angle!r}, ψ = {dilation_angle!r}: need 0 ≤ ψ ≤ φ < 90 degrees")
    if cone == "beta":
        return float(friction_angle), float(dilation_angle)
    associated = dilation_angle == friction_angle
    beta = math.degrees(math.atan(_cone_tan(friction_angle, cone, associated)))
    if associated:
        return beta, beta
    psi = math.degrees(math.atan(_cone_tan(dilation_angle, cone, True))) if dilation_angle > 0 else 0.0
    return beta, psi


def mohr_coulomb_angle(beta: float, cone: str = "compression", associated: bool = False) -> float:
    """The Mohr–Coulomb angle φ (degrees) that :func:`drucker_prager_cone` maps to the slope β
    under ``cone`` (its inverse; plane strain needs to know the flow rule). Raises where no φ
    maps to β (e.g. plane strain, associated, needs tan β < 1.5)."""
    if cone not in CONES:
        raise ValueError(f"cone = {cone!r}: must be one of {', '.join(CONES)}")
    t = math.tan(math.radians(beta))
    if cone == "beta":
        return float(beta)
    if cone == "compression":
        s = 3.0 * t / (6.0 + t)
    elif cone == "extension":
        s = 3.0 * t / (6.0 - t) if t < 6.0 else 2.0
    elif cone == "plane_strain" and associated:
        if t >= 1.5:
            raise ValueError(f"beta = {beta!r}: plane strain (associated) needs tan β < 1.5")
        return math.degrees(math.atan(3.0 * t / math.sqrt(27.0 - 12.0 * t * t)))
    else:
        s = t / math.sqrt(3.0)
    if not 0.0 <= s < 1.0:
        raise ValueError(f"beta = {beta!r}: no Mohr–Coulomb angle maps to it under cone = {cone!r}")
    return math.degrees(math.asin(s))


def janssen_k_en1991(friction_angle: float) -> float:
    """EN 1991-4 (2006) lateral pressure ratio K = 1.1 (1 − sin φ_i) for a Mohr–Coulomb
    angle of internal friction φ_i (degrees): 30° → 0.55, 35° → 0.47, 40° → 0.39."""
    if not 0.0 < friction_angle < 90.0:
        raise ValueError(f"friction_angle = {friction_angle!r}: must be in (0, 90) degrees")
    return 1.1 * (1.0 - math.sin(math.radians(friction_angle)))


EN1991_SLENDER = 2.0  # h_c/d_c from which EN 1991-4 (2006) §5.2 (slender silos) applies
EN1991_SQUAT = 1.0  # h_c/d_c up to which a silo is squat (§5.3: no discharge magnifier); intermediate above
EN1991_RETAINING = 0.4  # h_c/d_c up to which a flat-bottomed silo is a retaining silo (§5.4)


def en1991_discharge_factors(slenderness: float) -> tuple[float, float]:
    """EN 1991-4 (2006)'s discharge magnifiers (C_h, C_w) of the symmetrical wall load against
    slenderness h_c/d_c: slender silos (≥ 2, §5.2.2.2) 1.15 and 1.10; intermediate ones
    (§5.3.2) 1 + 0.15 C_S and 1 + 0.10 C_S with C_S = h_c/d_c − 1, which joins them; squat
    ones (≤ 1) 1 and 1 - their discharge load is their filling load."""
    c_s = min(max(slenderness, EN1991_SQUAT), EN1991_SLENDER) - 1.0
    return 1.0 + 0.15 * c_s, 1.0 + 0.10 * c_s


def en1991_squat_wall(depth, radius: float, wall_friction: float, k: float, unit_weight: float,
                      repose_angle: float, pile_depth: float = 0.0):
    """EN 1991-4 (2006) §5.3.1.1 symmetrical filling pressures on the vertical wall of a squat or
    intermediate circular silo (h_c/d_c < 2), Pa; returns (p_h, p_w, p_v). With the Janssen
    depth z_o = R/(2Kμ), p_ho = γ K z_o = γ R/(2μ) and h_o the depth of the highest solid-wall
    contact below the equivalent surface (``pile_depth``; R tan φ_r / 3 under a top pile at the
    angle of repose, 0 for a levelled surface):

        p_h = p_ho Y_R,  Y_R = 1 − ((z − h_o)/(z_o − h_o) + 1)^n,  n = −(1 + tan φ_r)(1 − h_o/z_o),
        p_w = μ p_h,     p_v = γ z_V,  z_V = h_o − (z_o − h_o − (z + z_o − 2h_o)^{n+1}/(z_o − h_o)^n)/(n + 1),

    zero wall pressure above h_o, where p_v = γ z. Y_R tends to 1 deep down (Janssen's
    asymptote, K cancels) and p_v satisfies a slice's equilibrium, dp_v/dz = γ − 2μ p_h/R.
    ``repose_angle`` φ_r in degrees."""
    import numpy as np

    _positive(radius=radius, wall_friction=wall_friction, k=k, unit_weight=unit_weight)
    if not 0.0 <= repose_angle < 90.0:
        raise ValueError(f"repose_angle = {repose_angle!r}: must be in [0, 90) degrees")
    z = _nonneg_array("depth", depth)
    z0 = janssen_depth(radius, wall_friction, k)
    h0 = pile_depth
    if not 0.0 <= h0 < z0:
        raise ValueError(f"pile_depth = {h0!r}: must be in [0, z_o = {z0:.4g}) m")
    n = -(1.0 + math.tan(math.radians(repose_angle))) * (1.0 - h0 / z0)
    x = (np.maximum(z, h0) - h0) / (z0 - h0) + 1.0  # (z + z_o − 2h_o)/(z_o − h_o)
    ph = unit_weight * k * z0 * (1.0 - x**n)
    if abs(n + 1.0) < 1e-12:  # the limit n → −1
        zv = h0 + (z0 - h0) * np.log(x)
    else:
        zv = h0 - (z0 - h0) * (1.0 - x ** (n + 1.0)) / (n + 1.0)
    pv = unit_weight * np.where(z > h0, zv, z)
    return ph, wall_friction * ph, pv


def en1991_vertical_wall(depth, radius: float, wall_friction: float, friction_angle: float, unit_weight: float,
                         slenderness: float, discharge: bool = False, surcharge: float = 0.0):
    """EN 1991-4 (2006) symmetrical pressures on the vertical wall of a circular silo, with K =
    1.1 (1 − sin φ) and ``depth`` below the surface, levelled (the equivalent surface; h_o = 0),
    Pa; returns (p_h, p_w, p_v).

    Slender silos (h_c/d_c ≥ 2, §5.2.1.1): Janssen, z0 = R/(2Kμ). Squat and intermediate ones
    (§5.3.1.1): :func:`en1991_squat_wall` with the angle of repose φ_r taken as φ (the code's
    Annex E gives φ_r within a few degrees of φ for common solids; a simulation has no other).
    Discharge from below (the fixed load, §5.2.2.2 / §5.3.2): p_he = C_h p_hf, p_we = C_w p_wf
    (:func:`en1991_discharge_factors`); p_v is the filling one. The code's characteristic values
    come from its property factors a_K, a_μ (Annex E); here the solid's own values are used, as
    a simulation has them. The patch load, being unsymmetrical, has no axisymmetric
    counterpart. A top surcharge q (Pa), which the code does not have, enters slender silos as
    in Janssen and is refused for §5.3, whose profile has no such term. (A flat-bottomed silo at
    h_c/d_c ≤ ``EN1991_RETAINING`` is a retaining silo, §5.4, which this does not cover.)"""
    if not slenderness > 0:
        raise ValueError(f"slenderness = {slenderness!r}: must be > 0")
    k = janssen_k_en1991(friction_angle)
    if slenderness >= EN1991_SLENDER:
        ph, pw, pv = janssen(depth, radius, wall_friction, k, unit_weight, surcharge)
    elif surcharge:
        raise ValueError(f"surcharge = {surcharge!r}: EN 1991-4's squat and intermediate profile (§5.3, "
                         f"h_c/d_c = {slenderness:.3g}) has no top surcharge")
    else:
        ph, pw, pv = en1991_squat_wall(depth, radius, wall_friction, k, unit_weight, friction_angle)
    c_h, c_w = en1991_discharge_factors(slenderness) if discharge else (1.0, 1.0)
    return c_h * ph, c_w * pw, pv


def wall_yield_k(friction_angle: float, wall_friction: float) -> float:
    """Lateral pressure ratio σ_h/σ_v beside a vertical wall of a cohesionless Mohr–Coulomb
    solid at yield in the active state (filling: σ_v the major stress), the wall friction
    fully mobilised (Walker 1966, Nedderman 1992 ch. 3). The wall's stress lies on the Mohr
    circle of radius p sin φ at sin ω = sin φ_w / sin φ:

        K = (1 − sin φ cos(ω − φ_w)) / (1 + sin φ cos(ω − φ_w)),

    from Rankine's (1 − sin φ)/(1 + sin φ) on a smooth wall to (1 − sin²φ)/(1 + sin²φ) when the
    wall is as rough as the solid (φ_w = φ; 0.60 at φ 30°). A wall rougher than the solid
    (μ > tan φ) cannot mobilise more than tan φ: the solid beside it yields on the wall's plane
    and K is that of φ_w = φ (thesis Fig. 7-5 with φ 30° and μ 0.67, docs/validation/ch7.md).
    Angles in degrees."""
    if not 0.0 < friction_angle < 90.0:
        raise ValueError(f"friction_angle = {friction_angle!r}: must be in (0, 90) degrees")
    if wall_friction < 0.0:
        raise ValueError(f"wall_friction = {wall_friction!r}: must be ≥ 0")
    phi = math.radians(friction_angle)
    phiw = min(math.atan(wall_friction), phi)
    s = math.sin(phi)
    c = s * math.cos(math.asin(min(math.sin(phiw) / s, 1.0)) - phiw)
    return (1.0 - c) / (1.0 + c)


def drucker_prager_wall_shear_limit(friction_angle: float) -> float:
    """Largest shear-to-normal stress ratio τ/σ_n a cohesionless Drucker-Prager solid can carry
    on a plane (the wall): maximising τ under q = p tan β with the two other normal stresses
    a·σ_n gives a = (9 + 2t²)/(9 − 4t²) and τ/σ_n = √([(1+2a)² t²/9 − (1 − a)²]/3), t = tan β.
    β = 35° gives 0.457: a wall with μ above this never slides; the solid next to it yields.
    A steeper cone (tan β ≥ 1.5, e.g. φ > 36.87° matched in compression) contains compressive
    states with one principal stress zero (σ1 = σ2, σ3 = 0), whose Mohr circles reach every
    ratio: with the tension cut-off of the return map (no tension in a cohesionless solid) the
    limit is then unbounded (returns inf) and any wall friction can slide. Valid for β < 90°."""
    t = drucker_prager_limit_ratio(friction_angle)
    if t >= 1.5:
        return math.inf
    a = (9.0 + 2.0 * t * t) / (9.0 - 4.0 * t * t)
    return math.sqrt(((1 + 2 * a) ** 2 * t * t / 9.0 - (1 - a) ** 2) / 3.0)
