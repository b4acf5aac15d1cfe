"""Closed forms against numbers worked out by hand from the thesis, and against independent
numerical integration."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from silo_dolfinx import theory

# ch. 4 hopper
H, RT, R0 = 2.64, 1.2, 0.1
ALPHA = math.degrees(math.atan((RT - R0) / H))


def test_eq_4_12_gives_5_2_hz():
    # thesis: √(550000·0.7/(1000·1.3·0.4)) / (2·2.64) ≅ 5.2 Hz
    f = theory.longitudinal_frequency(5.5e5, 0.3, 1000.0, 2.64)
    assert abs(f - 5.15341) < 1e-4 and round(f, 1) == 5.2


def test_beverloo_for_the_ch4_outlet():
    # C 0.58, D0 0.2 m, λ 1.5, d 0: W = 0.58·1000·√9.81·0.2^2.5 = 32.497 kg/s; F(22.6°, 67.4°) = 1
    w = theory.beverloo(1000.0, 0.2)
    assert abs(w - 32.4966) < 1e-3
    assert theory.rose_tanaka_factor(22.6, 67.4) == 1.0
    assert abs(theory.rose_tanaka_factor(10.0, 60.0) - (math.tan(math.radians(10)) * math.tan(math.radians(60))) ** -0.35) < 1e-14


@pytest.mark.parametrize("D,mu,k,X0,fe", [(1, 0.3, 0.55, 1.51, 0.30), (1, 0.5, 0.7, 0.71, 0.53),
                                          (1, 0.3, 0.32, 2.61, 0.16), (1, 0.3, 0.4, 2.08, 0.22),
                                          (0.5, 0.3, 0.65, 0.64, 0.70)])
def test_table_5_2_exponents_follow_one_over_2x0(D, mu, k, X0, fe):
    """Our 1/(2X0) from D, μ, k matches the table's X0 column (given to 2-3 digits: 1 %)."""
    assert abs(theory.janssen_depth(D / 2, mu, k) - X0) / X0 < 0.01
    assert abs(theory.wensrich_exponent(D, mu, k) - 1 / (2 * X0)) / (1 / (2 * X0)) < 0.01
    # and the thesis' FE exponents lie within 25 % of the theory (its own finding, Fig. 5-9)
    assert abs(fe - 1 / (2 * X0)) / (1 / (2 * X0)) < 0.25


@pytest.mark.parametrize("sign", [1, -1])
def test_tapered_growth_tends_to_the_parallel_column(sign):
    x = np.linspace(0.0, 4.0, 9)
    parallel = theory.wave_growth(x, 1.0, 0.3, 0.55)
    tapered = theory.wave_growth(x, 1.0, 0.3, 0.55, half_angle=sign * 1e-7)
    assert np.allclose(tapered, parallel, rtol=1e-6)


def test_diverging_grows_faster_than_converging_far_up():
    x = 4.0
    div = theory.wave_growth(x, 1.0, 0.3, 0.55, -3.0)
    par = theory.wave_growth(x, 1.0, 0.3, 0.55, 0.0)
    con = theory.wave_growth(x, 1.0, 0.3, 0.55, 3.0)
    assert div > par > con  # ch. 5.2.4: diverging enhances, converging reduces the growth


def test_walker_matches_numerical_slice_integration():
    """Eq. 4-2 against integrating the slice equilibrium dσ/dh' = m σ/h' − γ downwards from
    σ(h_a) = Q0, for Walker's m (κ = ±1) and McLean's m, with and without surcharge."""
    gamma = 9810.0
    h0 = R0 / math.tan(math.radians(ALPHA))
    ha = H + h0
    z = np.linspace(0.0, H, 41)
    for m in (theory.walker_parameters(30.0, 0.267, ALPHA, -1)[1], theory.walker_parameters(30.0, 0.267, ALPHA, 1)[1],
              theory.mclean_m(0.267, ALPHA), 1.0):
        for q0 in (0.0, 5e3):
            sol = solve_ivp(lambda h, s: m * s / h - gamma, (ha, h0), [q0], t_eval=(z + h0)[::-1], rtol=1e-12,
                            atol=1e-9)
            num = sol.y[0][::-1]
            closed = theory.hopper_vertical_stress(z, m, ALPHA, R0, H, gamma, q0)
            assert np.allclose(closed, num, rtol=1e-6, atol=1e-6 * gamma * H)


def test_walker_parameters_are_consistent_with_slice_equilibrium():
    """F and m of eqs. 4-1/4-3 satisfy m ≈ 2[F(1 + μ cot α) − 1] (the slice balance with the
    wall stress ratio F; Walker's distribution factor makes it approximate: 2 %)."""
    mu = 0.267
    for kappa in (-1, 1):
        F, m = theory.walker_parameters(30.0, mu, ALPHA, kappa)
        slice_m = 2 * (F * (1 + mu / math.tan(math.radians(ALPHA))) - 1)
        assert abs(m - slice_m) < 0.02 * max(1.0, abs(m))


def test_janssen_limits():
    ph, pw, pv = theory.janssen(np.array([0.0, 1e-6, 100.0]), 0.35, 0.63, 0.38, 14270.0)
    z0 = 0.35 / (2 * 0.38 * 0.63)
    assert ph[0] == 0.0
    assert abs(pv[1] - 14270.0 * 1e-6) < 1e-5 * 14270.0 * 1e-6  # hydrostatic at the surface (+ O(z/z0))
    assert abs(pv[2] - 14270.0 * z0) < 1e-9 and abs(pw[2] - 0.63 * ph[2]) < 1e-12  # asymptote γ z0
    # a surcharge equal to the asymptote keeps the stress uniform (the ch. 5 initial state)
    _, _, pv = theory.janssen(np.linspace(0, 5, 6), 0.5, 0.3, 0.55, 1500 * 9.81, surcharge=1500 * 9.81 * 1.0 / (4 * 0.3 * 0.55))
    assert np.allclose(pv, pv[0], rtol=1e-12)


@pytest.mark.parametrize("beta", [20.0, 30.0, 35.0, 45.0])
def test_drucker_prager_compression_angle(beta):
    """The matched Mohr–Coulomb φ has the Drucker–Prager limit in axisymmetric compression:
    a Mohr–Coulomb state σ1 = σv, σ2 = σ3 = K_a σv (K_a = (1 − sin φ)/(1 + sin φ)) lies on the
    cone q = p tan β, and K_a is the Drucker–Prager active ratio (round-off)."""
    phi = math.radians(theory.drucker_prager_compression_angle(beta))
    ka = (1 - math.sin(phi)) / (1 + math.sin(phi))
    q, p = 1 - ka, (1 + 2 * ka) / 3
    assert abs(q / p - math.tan(math.radians(beta))) < 1e-12
    assert abs(ka - theory.drucker_prager_active_k(beta)) < 1e-12
    assert abs(theory.drucker_prager_compression_angle(30.0) - 15.27) < 0.01  # the ch. 4 solid


@pytest.mark.parametrize("phi", [15.0, 30.0, 35.0, 40.0])
def test_drucker_prager_cone_for_mohr_coulomb(phi):
    """The cone matched to a Mohr–Coulomb φ: the active Mohr–Coulomb state lies on it, and it
    inverts drucker_prager_compression_angle (round-off); φ = 30° → 50.19°, 35° → 54.81°."""
    beta = theory.drucker_prager_cone_for_mohr_coulomb(phi)
    ka = (1 - math.sin(math.radians(phi))) / (1 + math.sin(math.radians(phi)))
    assert abs(3 * (1 - ka) / (1 + 2 * ka) - math.tan(math.radians(beta))) < 1e-12
    assert abs(theory.drucker_prager_compression_angle(beta) - phi) < 1e-10
    assert abs(theory.drucker_prager_cone_for_mohr_coulomb(30.0) - 50.19) < 0.01


def test_en1991_filling_ratio_is_the_thesis_form():
    mu, a = 0.67, 20.0
    F_thesis = (1 + 0.8 * mu / math.tan(math.radians(a))) / (1 + mu / math.tan(math.radians(a)))
    pn, pt = theory.en1991_hopper(np.array([0.3]), mu, a, 0.1, 0.687, 15000.0)
    sv = theory.hopper_vertical_stress(np.array([0.3]), 2 * (F_thesis * mu / math.tan(math.radians(a)) + F_thesis) - 2,
                                       a, 0.1, 0.687, 15000.0)
    assert np.allclose(pn, F_thesis * sv, rtol=1e-13) and np.allclose(pt, mu * pn, rtol=1e-13)


def test_en1991_vertical_wall_is_janssen_with_the_code_k_and_its_discharge_magnifiers():
    """EN 1991-4 §5.2 on a slender silo (R 0.35 m, μ 0.63, φ 35°, γ 15 kN/m³): filling is Janssen
    with K = 1.1 (1 − sin 35°) = 0.469, so at one Janssen depth z0 = R/(2Kμ) p_h = (1 − 1/e) γR/(2μ)
    and deep down γR/(2μ) (K cancels); the fixed discharge load is C_h = 1.15 times p_h and
    C_w = 1.10 times p_w. §5.3's profile (below h_c/d_c 2) has no top surcharge: refused, naming
    why."""
    R, mu, phi, g = 0.35, 0.63, 35.0, 15000.0
    k = 1.1 * (1 - math.sin(math.radians(phi)))
    z0 = R / (2 * k * mu)
    depth = np.array([0.0, z0, 60 * z0])
    ph, pw, pv = theory.en1991_vertical_wall(depth, R, mu, phi, g, slenderness=5.7)
    top = g * R / (2 * mu)
    assert ph == pytest.approx([0.0, (1 - math.exp(-1)) * top, top], rel=1e-12, abs=1e-9)
    assert pw == pytest.approx(mu * ph, rel=1e-12) and pv == pytest.approx(ph / k, rel=1e-12)
    phe, pwe, pve = theory.en1991_vertical_wall(depth, R, mu, phi, g, slenderness=5.7, discharge=True)
    assert phe == pytest.approx(1.15 * ph, rel=1e-12) and pwe == pytest.approx(1.10 * pw, rel=1e-12)
    assert pve == pytest.approx(pv, rel=1e-12)
    with pytest.raises(ValueError, match=r"surcharge = 500.0: .*\(§5.3, h_c/d_c = 1.5\) has no top surcharge"):
        theory.en1991_vertical_wall(depth, R, mu, phi, g, slenderness=1.5, surcharge=500.0)


def test_en1991_squat_and_intermediate_walls_section_5_3():
    """EN 1991-4 §5.3.1.1 (R 0.35 m, μ 0.63, φ 35° → K 0.469, γ 15 kN/m³), checked against what
    the profile must satisfy rather than against itself: no wall pressure above the highest
    wall contact h_o; at one z_o below a levelled surface p_h = (1 − 2^n) p_ho with n = −(1 +
    tan φ_r); deep down Janssen's asymptote γR/(2μ) (algebraically: 1e8 z_o); p_v continuous at h_o and in equilibrium
    with the wall's friction slice by slice, dp_v/dz = γ − 2μ p_h/R (central differences of a
    smooth profile on 1e-5 z_o steps: round-off 1e-8 of γ, so 1e-6); the n = −1 limit (a flat
    repose, h_o 0: the logarithm) joins its neighbours. Through the function the report uses
    (φ_r = φ, h_o = 0), an intermediate silo's discharge load is C_h = 1 + 0.15 (h_c/d_c − 1)
    times it, a squat one's equal to it; the magnifiers meet §5.2's 1.15/1.10 at h_c/d_c = 2."""
    R, mu, phi, g = 0.35, 0.63, 35.0, 15000.0
    k = theory.janssen_k_en1991(phi)
    z0, top = R / (2 * k * mu), g * R / (2 * mu)
    n = -(1 + math.tan(math.radians(phi)))
    ph, pw, pv = theory.en1991_squat_wall(np.array([0.0, z0, 1e8 * z0]), R, mu, k, g, phi)
    assert ph == pytest.approx([0.0, (1 - 2**n) * top, top], rel=1e-9, abs=1e-9)
    assert pw == pytest.approx(mu * ph, rel=1e-12) and pv[0] == 0.0
    for h0 in (0.0, 0.2 * z0):
        z = np.linspace(h0 + 0.01 * z0, 4 * z0, 7)
        dz = 1e-5 * z0
        ph, _, _ = theory.en1991_squat_wall(z, R, mu, k, g, 30.0, pile_depth=h0)
        up, lo = (theory.en1991_squat_wall(z + s, R, mu, k, g, 30.0, pile_depth=h0)[2] for s in (dz, -dz))
        assert (up - lo) / (2 * dz) == pytest.approx(g - 2 * mu * ph / R, abs=1e-6 * g)
    above = np.array([0.0, 0.1 * z0, 0.2 * z0 * (1 - 1e-12), 0.2 * z0 * (1 + 1e-9)])
    ph, _, pv = theory.en1991_squat_wall(above, R, mu, k, g, 30.0, pile_depth=0.2 * z0)
    assert np.all(ph[:3] == 0.0) and pv == pytest.approx(g * above, rel=1e-6)
    z = np.array([0.3 * z0, 2 * z0])
    flat = theory.en1991_squat_wall(z, R, mu, k, g, 0.0)
    near = theory.en1991_squat_wall(z, R, mu, k, g, 1e-6)
    assert flat[0] == pytest.approx(top * z / (z + z0), rel=1e-12)  # n = −1: p_h = p_ho z/(z + z_o)
    assert flat[2] == pytest.approx(near[2], rel=1e-6) and flat[0] == pytest.approx(near[0], rel=1e-6)
    depth = np.array([0.5, 1.0])
    fill, _, _ = theory.en1991_squat_wall(depth, R, mu, k, g, phi)
    for s, c_h in ((0.7, 1.0), (1.5, 1.075), (1.9, 1.135)):
        assert theory.en1991_vertical_wall(depth, R, mu, phi, g, s)[0] == pytest.approx(fill, rel=1e-12)
        assert theory.en1991_vertical_wall(depth, R, mu, phi, g, s, discharge=True)[0] == pytest.approx(
            c_h * fill, rel=1e-12)
    assert theory.en1991_discharge_factors(2.0) == pytest.approx((1.15, 1.10), rel=1e-12)
    assert theory.en1991_discharge_factors(1.999999) == pytest.approx((1.15, 1.10), rel=1e-6)
    assert theory.en1991_discharge_factors(0.5) == (1.0, 1.0) and theory.en1991_discharge_factors(9.0) == (1.15, 1.1)


def test_dynamic_friction_eq_7_1():
    mu = theory.dynamic_friction(np.array([0.0, 0.08, 0.2, 1e3]), 0.67, 0.3, 2.0)
    assert mu[0] == 0.67 and abs(mu[-1] - 0.3) < 1e-12
    # ch. 7: the thesis reports an effective μ of 0.62 -> 0.54 for slip 0.08 -> 0.2 m/s;
    # eq. 7-1 gives 0.3 + 0.37 e^{-0.16} = 0.6153 and 0.3 + 0.37 e^{-0.4} = 0.5480
    assert abs(mu[1] - 0.6153) < 1e-4 and abs(mu[2] - 0.5480) < 1e-4
    assert round(mu[1], 2) == 0.62 and round(mu[2], 2) == 0.55


def test_hourglass_discharge_solves_its_radial_momentum_equation():
    """Hourglass theory, independently: integrate dσ/dr − (n/r)σ = ρ(2A²/r⁵ − g) from the
    outlet sphere (σ = 0) and shoot A so that σ also vanishes on the top sphere; the speed
    A/r0² must be the closed form's u0 (to the integrator's tolerance). Then the ch. 4
    numbers: k = 1.939 for β = 30° and a 2.85 m/s mean outlet velocity."""
    from scipy.optimize import brentq

    beta, alpha, R0, H, rho, g = 30.0, 22.62, 0.1, 2.64, 1000.0, 9.81
    d = theory.hourglass_discharge(beta, alpha, R0, H, rho, g)
    n = d["n"]
    a = math.radians(alpha)
    r0, r1 = R0 / math.sin(a), H + R0 / math.tan(a)

    def top_stress(A):
        sol = solve_ivp(lambda r, s: [n / r * s[0] + rho * (2 * A * A / r**5 - g)], (r0, r1), [0.0],
                        rtol=1e-11, atol=1e-9)
        return sol.y[0, -1]

    A = brentq(top_stress, 0.05, 1.0, xtol=1e-13)
    assert abs(A / r0**2 - d["u0"]) < 1e-6 * d["u0"]
    assert abs(d["k"] - 1.9386) < 1e-4
    assert abs(d["mean_outlet_velocity"] - 2.8496) < 1e-3
    # the flux through the sphere cap is the flux through the flat disc
    assert abs(d["mass_flow"] - rho * d["mean_outlet_velocity"] * math.pi * R0**2) < 1e-9 * d["mass_flow"]
    # steeper hoppers (as eq. 4-8's factor says) and weaker solids discharge faster
    assert theory.hourglass_discharge(beta, 30.0, R0, H, rho)["mass_flow"] < d["mass_flow"] < \
        theory.hourglass_discharge(beta, 15.0, R0, H, rho)["mass_flow"]
    assert theory.hourglass_discharge(35.0, alpha, R0, H)["u0"] < d["u0"]


@pytest.mark.parametrize("call", [
    lambda: theory.beverloo(-1.0, 0.2),
    lambda: theory.beverloo(1000.0, 0.01, particle_size=0.01),
    lambda: theory.longitudinal_frequency(5.5e5, 0.5, 1000, 2.64),
    lambda: theory.walker_parameters(30.0, 0.7, 20.0),  # atan μ > φ
    lambda: theory.walker_parameters(30.0, 0.2, 20.0, kappa=0),
    lambda: theory.wave_growth(3.0, 1.0, 0.3, 0.55, -10.0),  # beyond the apex
    lambda: theory.janssen(-1.0, 0.35, 0.6, 0.4, 1e4),
    lambda: theory.dynamic_friction(0.1, 0.3, 0.6, 2.0),
    lambda: theory.thick_cylinder_limit_pressure(1e4, 1.0, 0.5),
    lambda: theory.hourglass_discharge(60.0, 22.6, 0.1, 2.64),  # tan β ≥ 1.5
])
def test_inputs_outside_the_validity_range_are_refused(call):
    with pytest.raises(ValueError):
        call()


# ---------------------------------------------------------------------------- the cone of a Mohr-Coulomb angle
def _dp_ratio(s1, s2, s3):
    """q/p of principal stresses (compression +)."""
    p = (s1 + s2 + s3) / 3
    q = math.sqrt(0.5 * ((s1 - s2) ** 2 + (s2 - s3) ** 2 + (s3 - s1) ** 2))
    return q / p


@pytest.mark.parametrize("cone", ["compression", "extension", "plane_strain", "plane_strain_zero_dilation", "beta"])
@pytest.mark.parametrize("phi, psi", [(20.0, 0.0), (30.0, 10.0), (35.0, 35.0), (40.0, 10.0), (55.0, 20.0)])
def test_cone_mapping_round_trips(cone, phi, psi):
    """drucker_prager_cone and mohr_coulomb_angle are inverse to round-off, for φ and for ψ
    (ψ is mapped by the same rule; plane strain by its associated formula); ψ ≤ φ stays
    ψ_DP ≤ β; beta is the identity."""
    beta, psi_dp = theory.drucker_prager_cone(phi, psi, cone)
    associated = psi == phi
    if cone == "plane_strain" and associated and phi > 40.0:
        return  # tan β → 1.5 as φ → 90: no inverse needed beyond the range of real solids
    assert abs(theory.mohr_coulomb_angle(beta, cone, associated) - phi) < 1e-10
    if psi > 0:
        assert abs(theory.mohr_coulomb_angle(psi_dp, cone, True) - psi) < 1e-10
    assert 0.0 <= psi_dp <= beta + 1e-12
    if cone == "beta":
        assert (beta, psi_dp) == (phi, psi)


@pytest.mark.parametrize("phi", [15.0, 30.0, 35.0, 40.0, 50.0])
def test_matched_mohr_coulomb_states_lie_on_the_cone(phi):
    """A Mohr-Coulomb limit state (σ1 = σ3 (1 + sin φ)/(1 − sin φ), compression +) lies on the
    mapped Drucker-Prager cone q = p tan β in the state its rule matches (round-off):
    compression σ2 = σ3; extension σ2 = σ1; plane strain with ψ = 0 σ2 = (σ1 + σ3)/2 (no
    out-of-plane plastic strain for a deviatoric flow); plane strain, associated, σ2 where the
    associated Drucker-Prager flow has no out-of-plane component, s2 = 2 q tan β/9."""
    from scipy.optimize import brentq

    s = math.sin(math.radians(phi))
    s3 = 1.0
    s1 = s3 * (1 + s) / (1 - s)
    tan = {c: math.tan(math.radians(theory.drucker_prager_cone(phi, 0.0, c)[0]))
           for c in ("compression", "extension", "plane_strain_zero_dilation")}
    assert abs(_dp_ratio(s1, s3, s3) - tan["compression"]) < 1e-12
    assert abs(_dp_ratio(s1, s1, s3) - tan["extension"]) < 1e-12
    assert abs(_dp_ratio(s1, 0.5 * (s1 + s3), s3) - tan["plane_strain_zero_dilation"]) < 1e-12
    assert theory.drucker_prager_cone(phi, 0.0, "plane_strain") == theory.drucker_prager_cone(
        phi, 0.0, "plane_strain_zero_dilation")[:1] + (0.0,)
    t = math.tan(math.radians(theory.drucker_prager_cone(phi, phi, "plane_strain")[0]))

    def no_out_of_plane_flow(s2):
        m = (s1 + s2 + s3) / 3
        return (s2 - m) - 2.0 * _dp_ratio(s1, s2, s3) * m * t / 9.0

    s2 = brentq(no_out_of_plane_flow, s3, s1)
    assert abs(_dp_ratio(s1, s2, s3) - t) < 1e-10


def test_cone_values_and_errors():
    """The numbers the scenes quote; bad input names its argument."""
    assert [round(theory.drucker_prager_cone(p, 0.0)[0], 2) for p in (30.0, 35.0, 40.0)] == [50.19, 54.81, 58.57]
    assert abs(theory.drucker_prager_cone(30.0, 10.0)[1] - 20.24) < 0.01  # ψ 10° → ψ_DP 20.24°
    assert abs(theory.janssen_k_en1991(35.0) - 1.1 * (1 - math.sin(math.radians(35.0)))) < 1e-15
    with pytest.raises(ValueError, match="cone"):
        theory.drucker_prager_cone(30.0, 0.0, "drucker_prager")
    with pytest.raises(ValueError, match="ψ"):
        theory.drucker_prager_cone(30.0, 31.0)


def test_wall_yield_k_against_its_limits_and_walker_jenike():
    """K beside a vertical wall at yield: Rankine's active ratio on a smooth wall, (1 − sin²φ)/
    (1 + sin²φ) (0.6 at 30°) on a wall as rough as the solid and on any rougher one (the solid
    yields on the wall's plane), and in between the closed form of the same Mohr circle written
    as Walker's/Jenike's K = [1 + sin²φ − 2√(sin²φ − μ² cos²φ)] / (4μ² + cos²φ) to round-off."""
    for phi in (20.0, 30.0, 40.0):
        s, c = math.sin(math.radians(phi)), math.cos(math.radians(phi))
        assert abs(theory.wall_yield_k(phi, 0.0) - (1 - s) / (1 + s)) < 1e-14
        rough = (1 - s * s) / (1 + s * s)
        assert abs(theory.wall_yield_k(phi, s / c) - rough) < 1e-7  # asin at 1: round-off amplified
        assert abs(theory.wall_yield_k(phi, 2.0) - rough) < 1e-14
        for mu in np.linspace(0.0, 0.999 * s / c, 7):
            jenike = (1 + s * s - 2 * math.sqrt(s * s - mu * mu * c * c)) / (4 * mu * mu + c * c)
            assert abs(theory.wall_yield_k(phi, mu) - jenike) < 1e-12, (phi, mu)
    assert abs(theory.wall_yield_k(30.0, 0.67) - 0.6) < 1e-12
    with pytest.raises(ValueError):
        theory.wall_yield_k(30.0, -0.1)


def test_steep_cones_carry_any_wall_shear():
    """tan β ≥ 1.5 (φ > 36.87° matched in compression, e.g. ch. 7's 40°): the compressive state
    σ1 = σ2, σ3 = 0 lies inside the cone, and its Mohr circle through the origin reaches every
    τ/σ_n, so the limit is unbounded; below 1.5 it is finite and continuous."""
    beta = theory.drucker_prager_cone(40.0, 0.0)[0]
    assert math.tan(math.radians(beta)) > 1.5
    assert _dp_ratio(1.0, 1.0, 0.0) <= math.tan(math.radians(beta))  # admissible, no tension
    assert theory.drucker_prager_wall_shear_limit(beta) == math.inf
    assert abs(theory.drucker_prager_wall_shear_limit(35.0) - 0.457) < 1e-3
    assert theory.drucker_prager_wall_shear_limit(math.degrees(math.atan(1.4999))) > 10.0


def _front_of_1d_taper_model(D, mu, k, alpha, x_probe, u0=0.05, rho=1500.0, M=2.69e6, dx=1e-3):
    """Integrate the 1-D slice model of theory.taper_wave_growth (staggered leapfrog):
    ρ w_t = −s_x − a s, s_t = −M (w_x + b w), the base pulled down over a 1-ms cosine ramp;
    returns σ⁺/σ⁺0 at x_probe as the ramp's end passes (the front's full amplitude; behind
    it the relief relaxes: 4 % lower 2 ms later)."""
    c = math.sqrt(M / rho)
    L = max(x_probe) + 0.2
    n = int(round(L / dx))
    xw = np.arange(n + 1) * dx  # w nodes
    xs = xw[:-1] + 0.5 * dx  # s points
    t = math.tan(math.radians(alpha))

    def coeffs(x):
        Dx = D + 2.0 * x * t
        dA = 4.0 * t / Dx  # A'/A
        return (1.0 - k) * dA - mu * k * 4.0 / Dx, k * dA  # a, b

    a_w, _ = coeffs(xw)
    _, b_s = coeffs(xs)
    w, s = np.zeros(n + 1), np.zeros(n)
    dt = 0.5 * dx / c
    ramp = 1e-3
    probes = {x: int(round(x / dx - 0.5)) for x in x_probe}
    when = {x: x / c + ramp for x in x_probe}  # the ramp's end: the front's full amplitude
    out, time = {}, 0.0
    while len(out) < len(x_probe):
        time += dt
        s_at_w = np.empty(n + 1)
        s_at_w[1:-1] = 0.5 * (s[1:] + s[:-1])
        s_at_w[0], s_at_w[-1] = s[0], s[-1]
        w[1:-1] -= dt / rho * ((s[1:] - s[:-1]) / dx + a_w[1:-1] * s_at_w[1:-1])
        w[0] = u0 * (0.5 * (1.0 - math.cos(math.pi * time / ramp)) if time < ramp else 1.0)
        w[-1] = 0.0
        s -= dt * M * ((w[1:] - w[:-1]) / dx + b_s * 0.5 * (w[1:] + w[:-1]))
        for x, i in probes.items():
            if x not in out and time >= when[x]:
                out[x] = s[i] / (rho * c * u0)
    return np.array([out[x] for x in x_probe])


@pytest.mark.parametrize("alpha", [-3.0, 0.0, 3.0, 10.0])
def test_taper_wave_growth_is_what_the_1d_slice_model_gives(alpha):
    """The closed form of theory.taper_wave_growth against integrating its 1-D model
    (ρ w_t = −s_x − a s, s_t = −M(w_x + b w)) on a 1-mm grid: the front's σ⁺/σ⁺0 at 1–4 m
    within 2 % (the integration's own error: ≤ 1.2 % on this grid, 0.4 % at α = 0 on a
    0.5-mm one – the 4-cm ramp is not a sharp front). The thesis' eq. 5-14/5-15 differs from the
    same model by its area term (+k for −1): at α = ±3° by more than 10 % at 4 m."""
    x = np.array([1.0, 2.0, 3.0, 4.0])
    D, mu, k = 1.0, 0.3, 0.55
    numeric = _front_of_1d_taper_model(D, mu, k, alpha, x)
    closed = theory.taper_wave_growth(x, D, mu, k, alpha)
    assert np.allclose(numeric, closed, rtol=0.02), (numeric, closed)
    if alpha in (-3.0, 3.0):
        assert abs(theory.wave_growth(4.0, D, mu, k, alpha) / closed[-1] - 1.0) > 0.10


def test_taper_wave_growth_limits():
    """α → 0: eq. 5-1; μ = 0: a horn's A^(−1/2) = 1/G whatever k."""
    x = np.linspace(0.0, 4.0, 9)
    for sign in (1, -1):
        assert np.allclose(theory.taper_wave_growth(x, 1.0, 0.3, 0.55, sign * 1e-7),
                           theory.wave_growth(x, 1.0, 0.3, 0.55), rtol=1e-6)
    G = 1.0 + 2.0 * x * math.tan(math.radians(5.0)) / 1.0
    assert np.allclose(theory.taper_wave_growth(x, 1.0, 1e-300, 0.55, 5.0), 1.0 / G, rtol=1e-12)


@pytest.mark.parametrize("wall, bessel", [("slip", "j1"), ("stick", "j0")])
def test_axial_shear_frequency_is_the_first_zero_of_the_wall_condition(wall, bessel):
    """A long column shearing vertically inside a cylinder: u_z = J0(k r) solves the shear wave
    equation (k = ω/c_s); a sliding wall (no shear traction) asks J0'(kR) = −J1(kR) = 0, a stuck
    one J0(kR) = 0. Checked with scipy's Bessel functions at the returned frequency (zero to
    1e-12), no sign change before it (the fundamental), and the ch. 7 bin's 39.1 / 24.5 Hz."""
    from scipy import special

    E, nu, rho, R = 2e6, 0.3, 1529.1, 0.35
    f = theory.axial_shear_frequency(E, nu, rho, R, wall)
    kR = 2 * math.pi * f * R / theory.shear_wave_speed(E, nu, rho)
    J = getattr(special, bessel)
    assert abs(J(kR)) < 1e-12 and np.all(J(np.linspace(1e-6, kR * (1 - 1e-9), 2000)) > 0)
    assert f == pytest.approx({"slip": 39.08, "stick": 24.53}[wall], abs=0.01)
    with pytest.raises(ValueError, match="wall"):
        theory.axial_shear_frequency(E, nu, rho, R, "rough")


def test_radial_frequency_is_the_first_zero_of_j1_of_a_dilatational_wave():
    """A long column in a rigid cylinder breathing radially: u_r = J1(k r) solves the
    dilatational wave equation (k = ω/√(M/ρ)); u_r(R) = 0 gives the first zero of J1. Checked
    with scipy's J1 at the returned frequency (zero to 1e-12) and no sign change of J1 before it
    (the fundamental); the ch. 6 silo, 75.0 Hz."""
    from scipy.special import j1

    E, nu, rho, R = 2e6, 0.3, 14270 / 9.81, 0.35
    c = theory.confined_wave_speed(E, nu, rho)
    f = theory.radial_frequency(E, nu, rho, R)
    kR = 2 * math.pi * f * R / c
    assert abs(j1(kR)) < 1e-12 and np.all(j1(np.linspace(1e-6, kR * (1 - 1e-9), 2000)) > 0)
    assert f == pytest.approx(75.0, abs=0.05)
