"""The Mohr–Coulomb return map, point by point (no mesh): exact at every Lode angle (triaxial
compression and extension limits in closed form), the closest point in the energy norm for
associated flow (against a constrained minimisation), the flow rule for ψ < φ on faces and
edges, no tension without cohesion, non-negative dissipation, and the critical state."""

import math

import numpy as np
import pytest
from scipy.optimize import minimize

from silo_dolfinx import theory
from silo_dolfinx.materials import DruckerPrager, MohrCoulomb, NonCoaxial
from silo_dolfinx.theory import drucker_prager_cone
from test_materials import E, NU, RHO, dissipations, plastic_volume_in_simple_shear, random_states, run, trial

PHI, PSI = 35.0, 10.0


def mc(phi=PHI, psi=PSI, c=0.0, max_dilation=0.0):
    return MohrCoulomb(E, NU, RHO, phi, psi, c, max_dilation)


def principal_values(sig):
    """(n, 3) principal stresses, descending (tension +)."""
    c, h = 0.5 * (sig[:, 0] + sig[:, 1]), 0.5 * (sig[:, 0] - sig[:, 1])
    r = np.hypot(h, sig[:, 3])
    return -np.sort(-np.stack([c + r, c - r, sig[:, 2]], axis=1), axis=1)


def plastic_principal(mat, sig, de, out):
    """The plastic strain of each return in the trial's principal axes (which the return keeps),
    in the order of the trial's principal stresses: C⁻¹(σ_trial − σ_new)."""
    t = trial(mat, sig, de)
    ds = principal_values(t) - principal_values(out)
    lam = mat.K - 2 * mat.G / 3
    c = lam / (3 * lam + 2 * mat.G)
    return (ds - c * ds.sum(axis=1)[:, None]) / (2 * mat.G)


def test_returned_stress_lies_on_the_surface():
    """Every trial beyond F = 0 comes back to F = 0 (to round-off of the stress level) and every
    admissible trial is untouched, over random increments that reach faces, edges and apex."""
    for c in (0.0, 500.0):
        mat = mc(c=c)
        sig, de = random_states(20000, seed=3, scale=5e4)
        out, _, _ = run(mat, sig, de)
        t = trial(mat, sig, de)
        tol = 1e-10 * np.abs(sig).max()
        f_t, f = mat.yield_function(t), mat.yield_function(out)
        assert np.all(f <= tol)
        assert np.all(np.abs(f[f_t > 0]) <= tol)
        inside = f_t <= 0
        assert inside.sum() > 500 and np.allclose(out[inside], t[inside], rtol=1e-14, atol=1e-9)


@pytest.mark.parametrize("phi", [20.0, 35.0, 50.0])
def test_limits_in_triaxial_compression_and_extension(phi):
    """The strength is φ's at every Lode angle: a trial far beyond the surface on the
    compression meridian (σ_zz the most compressive, σ_rr = σ_θθ) returns to q/p = 6 sin φ/(3 −
    sin φ) - the compression-matched cone's slope - and one on the extension meridian (σ_zz the
    least compressive) to 6 sin φ/(3 + sin φ), the extension-matched cone's (closed forms, to
    round-off; the returns use the edges of the pyramid)."""
    mat = mc(phi, 10.0)
    p0, dz = 2e4, 4e4
    sig = np.array([[-p0, -p0, -p0, 0.0], [-p0, -p0, -p0, 0.0]])
    de = np.zeros((2, 4))
    x = dz / E  # isochoric: the mean pressure changes only by dilation
    de[0, :] = [x, -2 * x, x, 0.0]  # axial compression, σ_zz the most compressive
    de[1, :] = [-x, 2 * x, -x, 0.0]  # axial extension, σ_zz the least compressive
    out, _, _ = run(mat, sig, de)
    p = -out[:, :3].mean(axis=1)
    pv = principal_values(out)
    q = pv[:, 0] - pv[:, 2]  # two principal stresses equal: q = σ1 − σ3
    for (i, cone) in ((0, "compression"), (1, "extension")):
        tan_beta = math.tan(math.radians(theory.drucker_prager_cone(phi, 0.0, cone)[0]))
        assert q[i] / p[i] == pytest.approx(tan_beta, rel=1e-10)
    assert np.allclose(out[:, 0], out[:, 2], rtol=1e-12)  # the lateral stresses stay equal


def _closest_point(mat, s_trial):
    """The associated return computed independently: the stress minimising the complementary
    energy of σ_trial − σ over the six planes of the pyramid (all principal orders), in the
    trial's principal axes (scaled to order one for the optimiser)."""
    lam, G = mat.K - 2 * mat.G / 3, mat.G
    c = lam / (3 * lam + 2 * G)
    s, c2 = mat.sin_phi, mat.parameters[4]
    L = np.abs(s_trial).max()
    y_t = s_trial / L
    pairs = [(i, j) for i in range(3) for j in range(3) if i != j]

    def energy(y):  # ∝ (σ_t − σ) : C⁻¹ : (σ_t − σ), with its gradient
        d = y_t - y
        w = d - c * d.sum()
        return float(w @ d), -2.0 * w

    cons = [{"type": "ineq", "fun": (lambda y, i=i, j=j: -((y[i] - y[j]) + (y[i] + y[j]) * s - c2 / L))}
            for i, j in pairs]
    res = minimize(energy, x0=np.full(3, y_t.mean() - 1.0), jac=True, constraints=cons, method="SLSQP",
                   options={"ftol": 1e-16, "maxiter": 1000})
    return res.x * L


def test_associated_return_is_the_closest_point():
    """ψ = φ: the return map is the closest-point projection in the complementary-energy norm
    (Koiter; the principle of maximum dissipation), so an optimiser that knows nothing of faces,
    edges or apex must find the same principal stresses. Tolerance 1e-5 of the stress level:
    SLSQP's own convergence (the kernel is exact to round-off)."""
    mat = mc(PHI, PHI, c=200.0)
    sig, de = random_states(300, seed=5, scale=5e4)
    out, _, _ = run(mat, sig, de)
    t = trial(mat, sig, de)
    plastic = mat.yield_function(t) > 0
    assert plastic.sum() > 100
    pv_t, pv = principal_values(t[plastic]), principal_values(out[plastic])
    branch = {"face": 0, "edge": 0, "apex": 0}
    for s_t, s_k in zip(pv_t, pv):
        ref = np.sort(_closest_point(mat, s_t))[::-1]
        assert np.abs(s_k - ref).max() <= 1e-5 * np.abs(s_t).max()
        gaps = np.diff(-s_k) > 1e-8 * np.abs(s_t).max()
        branch["face" if gaps.all() else "edge" if gaps.any() else "apex"] += 1
    assert min(branch.values()) > 0, branch  # every branch was exercised


def test_flow_follows_the_dilation_angle():
    """ψ < φ: on a face the plastic strain is along (1 + sin ψ, 0, −(1 − sin ψ)) in the
    principal order; on an edge it is a non-negative sum of the two faces' flows; its volume
    change is 2 sin ψ Σ Δγ in both (relative error 1e-9)."""
    mat = mc(PHI, PSI, c=0.0)
    sp = mat.sin_psi
    sig, de = random_states(4000, seed=9, scale=5e4)
    out, _, _ = run(mat, sig, de)
    t = trial(mat, sig, de)
    plastic = mat.yield_function(t) > 0
    pv, ep = principal_values(out[plastic]), plastic_principal(mat, sig[plastic], de[plastic], out[plastic])
    scale = np.abs(sig).max()
    gap_hi, gap_lo = pv[:, 0] - pv[:, 1] > 1e-8 * scale, pv[:, 1] - pv[:, 2] > 1e-8 * scale
    n13, n23, n12 = np.array([1 + sp, 0, -(1 - sp)]), np.array([0, 1 + sp, -(1 - sp)]), np.array([1 + sp, -(1 - sp), 0])
    face, comp, ext = gap_hi & gap_lo, ~gap_hi & gap_lo, gap_hi & ~gap_lo
    assert face.sum() > 50 and comp.sum() > 20 and ext.sum() > 20
    for mask, flows in ((face, (n13,)), (comp, (n13, n23)), (ext, (n13, n12))):
        A = np.stack(flows, axis=1)
        for e in ep[mask]:
            g, *_ = np.linalg.lstsq(A, e, rcond=None)
            assert np.abs(A @ g - e).max() <= 1e-9 * np.abs(e).max()
            assert np.all(g >= -1e-9 * g.max())
            assert e.sum() == pytest.approx(2 * sp * g.sum(), rel=1e-9)


def test_no_tension_without_cohesion():
    """c = 0: the pyramid's apex is the origin - no principal stress is tensile after any return
    (the compression-matched cone needs a tension cut-off for φ > 36.87°; this surface does not)."""
    for phi in (30.0, 40.0, 55.0):
        sig, de = random_states(20000, seed=7, scale=8e4)
        out, _, _ = run(mc(phi, 10.0), sig, de)
        assert principal_values(out)[:, 0].max() <= 1e-10 * np.abs(sig).max()


def test_dissipation_is_non_negative_and_booked_at_the_mid_point():
    mat = mc(PHI, PSI, c=100.0)
    sig, de = random_states(20000, seed=1, scale=5e4)
    out, st, diss = run(mat, sig, de)
    end, mid = dissipations(mat, sig, de, out)
    assert end >= 0.0 and diss == pytest.approx(mid, rel=1e-9)
    assert np.all(st["eqps"] >= 0.0) and st["eqps"].max() > 0.0


def test_dilation_stops_at_the_critical_state():
    """Simple shear at constant stress level: the plastic volume change grows with ε̄_p until it
    reaches max_dilation, then stops (ψ → 0); overshoot at most one increment's. Without the
    cap it keeps growing."""
    eps_c = 0.01
    for cap, expect_stop in ((eps_c, True), (0.0, False)):
        mat = mc(PHI, PSI, max_dilation=cap)
        dgam = 1e-3
        vol_p = plastic_volume_in_simple_shear(mat, dgam, 600)
        if expect_stop:
            assert eps_c - 1e-12 <= vol_p <= eps_c + 2 * mat.sin_psi * dgam
        else:
            assert vol_p > 3 * eps_c


def _cohesionless(law, recompact):
    """The law ``law`` for this file's solid, cohesionless, with or without recompaction (the
    cone laws on the compression-matched cone)."""
    if law == "mohr_coulomb":
        return MohrCoulomb(E, NU, RHO, PHI, PSI, 0.0, 0.05, recompact)
    beta, psi = drucker_prager_cone(PHI, PSI, "compression")
    if law == "drucker_prager":
        return DruckerPrager(E, NU, RHO, beta, psi, 0.0, 0.05, recompact)
    return NonCoaxial(E, NU, RHO, beta, psi, 0.0, 0.3 * E, max_dilation=0.05, recompaction=recompact)


@pytest.mark.parametrize("law", ["mohr_coulomb", "drucker_prager", "non_coaxial"])
def test_recompaction_closes_the_opening_without_stress(law):
    """A cohesionless point at rest pulled apart (volumetric stretch 1e-3) returns to the apex
    (σ = 0) and opens 1e-3 of volume. Squeezed back by the same amount: with recompaction the
    opening closes and it stays stress-free (its grains only come back into contact); without,
    the squeeze is elastic and it carries p = K·1e-3 while keeping the opened volume. A further
    squeeze beyond the closed opening is elastic in both (p = K·(the excess), exact to 1e-9).
    The same for the pyramid and the cone laws (one helper closes the opening for all)."""
    stretch = np.array([[1e-3 / 3, 1e-3 / 3, 1e-3 / 3, 0.0]])
    for recompact in (True, False):
        mat = _cohesionless(law, recompact)
        st = {k: np.zeros(1) for k in mat.state_fields}
        sig = np.zeros((1, 4))
        for de in (stretch, -stretch, -0.5 * stretch):
            new = {k: np.zeros(1) for k in mat.state_fields}
            out = np.zeros_like(sig)
            mat.update(sig, de, st, out, new, np.ones(1))
            if recompact and de is stretch:
                assert new["opening"][0] == pytest.approx(1e-3, rel=1e-9) and np.abs(out).max() < 1e-9
            if de is not stretch and de[0, 0] == -stretch[0, 0]:  # squeezed back by the stretch
                p = -out[0, :3].mean()
                assert p == (pytest.approx(0.0, abs=1e-6) if recompact else pytest.approx(mat.K * 1e-3, rel=1e-9))
            sig, st = out, new
        p = -sig[0, :3].mean()
        assert p == pytest.approx(mat.K * (0.5e-3 if recompact else 1.5e-3), rel=1e-9)
        assert ("opening" in mat.state_fields) == recompact
