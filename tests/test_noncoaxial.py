"""Non-coaxial (yield-vertex) Drucker-Prager and the simple-shear driver (thesis ch. 8)."""

import math

import numpy as np
import pytest

from silo_dolfinx.materials import DruckerPrager, NonCoaxial
from silo_dolfinx.materials.base import invariants
from silo_dolfinx.materials.driver import case_materials, simple_shear

PHI = 30.0
S2 = math.sin(math.radians(PHI)) ** 2


@pytest.fixture(scope="module")
def paths():
    out = {}
    for case in (1, 2, 3, 4, 5, 6, 7, 8):
        co, nc, k = case_materials(case)
        out[case] = (simple_shear(co, k=k, gamma_max=0.1, steps=2000), simple_shear(nc, k=k, gamma_max=0.1, steps=2000))
    return out


def test_ultimate_states_against_closed_form(paths):
    """Plane-strain-matched Drucker-Prager: associated flow ends at σx/σy = (1+sin²φ)/(1−sin²φ)
    = 1.667, τ/σy = tan φ = 0.577 within 1 %; ψ = 0 at σx = σy, τ/σy = sin φ = 0.5 within 3 %
    — coaxial and non-coaxial alike (non-coaxiality changes the path, not the end)."""
    for co_or_nc in (0, 1):
        a = paths[2][co_or_nc]
        assert abs(a.sx_over_sy[-1] / ((1 + S2) / (1 - S2)) - 1) < 0.01
        assert abs(a.stress_ratio[-1] / math.tan(math.radians(PHI)) - 1) < 0.01
        b = paths[1][co_or_nc]
        assert abs(b.sx_over_sy[-1] - 1.0) < 0.03
        assert abs(b.stress_ratio[-1] / math.sin(math.radians(PHI)) - 1) < 0.03


def test_the_thesis_parameter_choice_gives_its_1_8_and_0_6():
    """With tan β = √3 sin φ for both flow rules (the thesis' apparent choice) the associated
    case ends at σx/σy = 1.75, τ/σy = 0.612 — the thesis reports 1.8 and 0.6 (3 %, 2 %)."""
    co, _, k = case_materials(2, "thesis")
    a = simple_shear(co, k=k, gamma_max=0.1, steps=2000)
    t = co.tan_beta
    assert a.sx_over_sy[-1] == pytest.approx((1 + 2 * t * t / 9) / (1 - 4 * t * t / 9), rel=1e-3)
    assert abs(a.sx_over_sy[-1] / 1.8 - 1) < 0.03 and abs(a.stress_ratio[-1] / 0.6 - 1) < 0.025


def test_principal_stress_rotation(paths):
    """ψ = 0 ends with the major principal stress at 45° from the vertical — exactly, since
    σx = σy there — which is 5.0° from the thesis' 'near 50°' (its bar: within 5°); the
    associated rule rotates 15° further (thesis: 30° vs 15°, within 5°)."""
    a1, a2 = paths[1][0], paths[2][0]
    assert abs(a1.stress_angle[-1] - 45.0) < 1e-9
    assert abs(a1.stress_angle[-1] - 50.0) <= 5.0 + 1e-9
    assert abs((a2.stress_angle[-1] - a1.stress_angle[-1]) - 15.0) <= 5.0
    # coaxial: plastic strain rate and stress share principal axes; non-coaxial: the rate leads
    plastic = ~np.isnan(a1.strain_rate_angle)
    assert np.allclose(a1.strain_rate_angle[plastic][10:], a1.stress_angle[plastic][10:], atol=1e-6)
    b1 = paths[1][1]
    lead = b1.strain_rate_angle - b1.stress_angle
    assert np.nanmax(lead) > 5.0


def test_peak_difference_and_its_trends(paths):
    """Peak coaxial − non-coaxial τ/σy: ≈ 0.28 (ψ = 0) and ≈ 0.36 (associated) in the thesis
    (15 %: its Drucker-Prager parameters are not given; measured 0.316 and 0.377); larger for
    associated flow; grows with E (cases 3, 4, 1, 5); vanishes at k = 1; changes sign for k > 1."""
    def peak(case):
        a, b = paths[case]
        d = a.stress_ratio - b.stress_ratio
        return d[np.argmax(np.abs(d))]

    assert abs(peak(1) / 0.28 - 1) < 0.15 and abs(peak(2) / 0.36 - 1) < 0.15
    assert peak(2) > peak(1)
    assert peak(3) < peak(4) < peak(1) < peak(5)
    assert abs(peak(7)) < 1e-3
    assert peak(6) < -0.05 and 0 < peak(8) < peak(1)


def test_reduces_to_coaxial_as_the_modulus_grows():
    co = DruckerPrager(1e8, 0.316, 1500.0, 40.0, 0.0, 1.0)
    nc = NonCoaxial(1e8, 0.316, 1500.0, 40.0, 0.0, 1.0, noncoaxial_modulus=1e30)
    a = simple_shear(co, k=0.4, gamma_max=0.02, steps=400)
    b = simple_shear(nc, k=0.4, gamma_max=0.02, steps=400)
    assert np.allclose(a.sigma, b.sigma, rtol=1e-12, atol=1e-9)


def point_on_the_surface(mat):
    """A stress on the yield surface (q = p tan β + d) with a shear component."""
    p = 5e4
    s = np.array([-0.5, 0.8, -0.3, 0.4])
    s[:3] -= s[:3].mean()
    q = math.sqrt(1.5 * (s[:3] ** 2).sum() + 3 * s[3] ** 2)
    s *= (p * mat.tan_beta + mat.cohesion) / q
    return (s - np.array([p, p, p, 0.0]))[None, :]


def test_noncoaxial_strain_is_tangential_and_dissipates_nothing():
    """At a point on the yield surface, a deviatoric strain increment tangential to the
    deviator: the non-coaxial law turns 2G/(H+2G) of it into plastic strain that is deviatoric
    and orthogonal to s (first order), and the stress increment shrinks by H/(H+2G)."""
    H = 2e7
    nc = NonCoaxial(1e8, 0.3, 1500.0, 35.0, 10.0, 1.0, H)
    co = DruckerPrager(1e8, 0.3, 1500.0, 35.0, 10.0, 1.0)
    sig = point_on_the_surface(nc)
    m = sig[0, :3].mean()
    s = np.array([*(sig[0, :3] - m), sig[0, 3]])
    # a deviatoric increment orthogonal to s (tensor product, shear counted twice)
    e = np.array([0.3, -0.1, -0.2, 0.25])
    e[:3] -= e[:3].mean()
    dot = lambda a, b: a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + 2 * a[3] * b[3]  # noqa: E731
    e -= dot(s, e) / dot(s, s) * s
    de = 1e-7 * np.array([e[0], e[1], e[2], 2 * e[3]])[None, :]  # engineering shear
    out_nc, out_co = np.zeros((1, 4)), np.zeros((1, 4))
    st = {"eqps": np.zeros(1)}
    diss = nc.update(sig, de, {"eqps": np.zeros(1)}, out_nc, st, np.ones(1))
    co.update(sig, de, {"eqps": np.zeros(1)}, out_co, {"eqps": np.zeros(1)}, np.ones(1))
    ds_nc, ds_co = out_nc[0] - sig[0], out_co[0] - sig[0]
    # first order in the increment (the return's rescaling of the deviator is second order)
    assert np.allclose(ds_nc, H / (H + 2 * nc.G) * ds_co, rtol=1e-3, atol=1e-6 * np.abs(ds_co).max())
    # the plastic strain C⁻¹(Δσ_elastic − Δσ): deviatoric, orthogonal to s, dissipation ~ 0
    lam = nc.K - 2 * nc.G / 3
    c = lam / (3 * lam + 2 * nc.G)
    r = ds_co - ds_nc
    ep = np.array([*(r[:3] - c * r[:3].sum()) / (2 * nc.G), r[3] / nc.G])
    assert abs(ep[:3].sum()) < 1e-4 * np.abs(ep).max()  # first order: 1e-5 measured
    ep_t = np.array([ep[0], ep[1], ep[2], 0.5 * ep[3]])
    assert abs(dot(s, ep_t)) < 1e-4 * math.sqrt(dot(s, s) * dot(ep_t, ep_t))
    # its work σ : Δεp vanishes to first order against |s| |Δεp| (measured 2.4e-5 of it)
    assert abs(diss) < 1e-3 * math.sqrt(dot(s, s) * dot(ep_t, ep_t))


def test_dissipation_is_non_negative_along_shear():
    _, nc, k = case_materials(2)
    sig = np.array([[-k * 1e5, -1e5, -k * 1e5, 0.0]])
    st, st2, out = {"eqps": np.zeros(1)}, {"eqps": np.zeros(1)}, np.zeros((1, 4))
    total = 0.0
    for _ in range(500):
        d = nc.update(sig, np.array([[0.0, -2e-6, 0.0, 2e-4]]), st, out, st2, np.ones(1))
        assert d >= -1e-12 * abs(sig).max()
        total += d
        sig = out.copy()
        st, st2 = st2, st
    assert total > 0
    p, q = invariants(sig[0])[:2]
    assert q <= p * nc.tan_beta + nc.cohesion + 1e-6 * p


@pytest.mark.parametrize("silo", ["steep_hopper_ch8", "flat_bottom_ch8"])
def test_noncoaxiality_leaves_filling_pressures_unchanged(shared_tmp, comm, silo):
    """Ch. 8.4's two silos (the steep hopper of TARGETS' dimensions, the flat-bottomed silo of
    docs/validation/ch8.md), filled by a damped gravity ramp on a coarse mesh: wall pressures
    with and without the non-coaxial term agree within 2 % over the middle 80 % of the wall
    at every wall node (measured, worst node: hopper 0.002 %, flat bottom 0.012 %; the full demo
    runs, finer and on slower ramps, 0.01 % and 1.09 % in the mean): plastic flow during
    filling is small and nearly proportional, and the non-coaxial term acts only at yield."""
    from silo_dolfinx.output import read_csv

    from conftest import SCENES

    from silo_dolfinx.scene import load_scene
    from silo_dolfinx.simulation import run

    prof = {}
    for name in ("coaxial", "noncoaxial"):
        sc = load_scene(SCENES / f"{silo}_{name}.toml",
                        ["geometry.element_size=0.05" if silo.startswith("flat") else "geometry.element_size=0.04",
                         'geometry.mesh="unstructured"', 'discharge.mode="none"',
                         "fill.damping=0.3", "fill.duration=2.0", "store.duration=0.5", "output.field_interval=100"])
        run(sc, shared_tmp / f"{silo}_{name}", comm, progress_every=1e9)
        comm.barrier()
        w = read_csv(shared_tmp / f"{silo}_{name}" / "wall_profile_store.csv")
        prof[name] = np.column_stack([w["z"], w["p_n"]])
    a, b = prof["coaxial"], prof["noncoaxial"]
    height = sc.outline.fill_height
    assert np.allclose(a[:, 0], b[:, 0], atol=1e-3 * height)  # the same wall nodes, deformed slightly differently
    mid = (a[:, 0] > 0.1 * height) & (a[:, 0] < 0.9 * height)
    worst = np.abs(b[mid, 1] / a[mid, 1] - 1).max()
    assert worst < 0.02, worst
