"""Return mapping of the materials, point by point (no mesh): on the yield surface to 1e-10,
flow consistent with ψ, exact apex return, elastic states untouched, the q/p limit, and the
same answer on every rank."""

import math

import numpy as np
import pytest
from mpi4py import MPI

from silo_dolfinx import theory
from silo_dolfinx.materials import DruckerPrager, Elastic
from silo_dolfinx.materials.base import invariants

E, NU, RHO = 5.5e5, 0.3, 1000.0


def dp(beta=30.0, psi=10.0, d=1.0):
    return DruckerPrager(E, NU, RHO, beta, psi, d)


def pq(sig):
    return np.array([invariants(s)[:2] for s in sig])


def random_states(n, seed=0, scale=2e4):
    """Admissible compressive stress states and random strain increments that yield most."""
    rng = np.random.default_rng(seed)
    sig = np.zeros((n, 4))
    p = rng.uniform(1e3, 3e4, n)
    sig[:, :3] = -p[:, None]
    de = rng.normal(0.0, 1.0, (n, 4)) * scale / E
    return sig, de


def run(mat, sig, de):
    out = np.zeros_like(sig)
    st_old = {k: np.zeros(sig.shape[0]) for k in mat.state_fields}
    st_new = {k: np.zeros(sig.shape[0]) for k in mat.state_fields}
    diss = mat.update(sig, de, st_old, out, st_new, np.ones(sig.shape[0]))
    return out, st_new, diss


def trial(mat, sig, de):
    lam = mat.K - 2 * mat.G / 3
    tr = de[:, :3].sum(axis=1)
    t = sig.copy()
    t[:, :3] += lam * tr[:, None] + 2 * mat.G * de[:, :3]
    t[:, 3] += mat.G * de[:, 3]
    return t


def dissipations(mat, sig, de, out):
    """(σ_new : Δε_p, σ_mid : Δε_p) summed over the points (unit volumes), with the plastic
    strain Δε_p = Δε − C⁻¹(σ_new − σ_old): the return map's own dissipation (≥ 0 for ψ ≤ β) and
    the one the solver books (the trapezoidal partner of its internal work)."""
    ds = out - sig
    lam = mat.K - 2 * mat.G / 3
    c = lam / (3 * lam + 2 * mat.G)
    dee = np.empty_like(ds)
    dee[:, :3] = (ds[:, :3] - c * ds[:, :3].sum(axis=1)[:, None]) / (2 * mat.G)
    dee[:, 3] = ds[:, 3] / mat.G
    dep = de - dee
    return float((out * dep).sum()), float((0.5 * (sig + out) * dep).sum())


def test_returned_stress_lies_on_the_yield_surface():
    mat = dp()
    sig, de = random_states(4000)
    out, st, diss = run(mat, sig, de)
    f_trial = mat.yield_function(trial(mat, sig, de))
    f_new = mat.yield_function(out)
    plastic = f_trial > 0
    assert plastic.sum() > 1000  # the sample exercises the return map
    p, q = pq(out).T
    scale = np.maximum(np.abs(p), 1.0) * mat.tan_beta + mat.cohesion
    assert np.all(np.abs(f_new[plastic]) <= 1e-10 * scale[plastic])  # relative 1e-10
    assert np.all(f_new <= 1e-10 * scale)
    end, mid = dissipations(mat, sig, de, out)
    assert end >= 0.0  # ψ ≤ β: the return map dissipates
    assert diss == pytest.approx(mid, rel=1e-9)  # what update reports: σ_mid : Δε_p


def test_elastic_states_are_untouched():
    mat = dp()
    sig, de = random_states(500, seed=3, scale=10.0)  # tiny increments stay elastic
    out, st, _ = run(mat, sig, de)
    assert np.all(mat.yield_function(trial(mat, sig, de)) <= 0)
    assert np.allclose(out, trial(mat, sig, de), rtol=1e-14, atol=1e-12)  # round-off only
    assert np.all(st["eqps"] == 0.0)


def test_flow_direction_follows_the_dilation_angle():
    """Plastic volumetric strain / equivalent deviatoric plastic strain = tan ψ, and the
    deviatoric plastic strain is parallel to the stress deviator (coaxial flow)."""
    for psi in (0.0, 10.0, 30.0):
        mat = dp(30.0, psi)
        sig, de = random_states(2000, seed=1)
        out, st, _ = run(mat, sig, de)
        t = trial(mat, sig, de)
        cone = (mat.yield_function(t) > 0) & (pq(out)[:, 1] > 1.0)
        # ε_p = Δε − C⁻¹(σ_new − σ_old) = C⁻¹(σ_trial − σ_new)
        ds = t - out
        c = (mat.K - 2 * mat.G / 3) / (3 * (mat.K - 2 * mat.G / 3) + 2 * mat.G)
        ep = np.empty_like(ds)
        tr = ds[:, :3].sum(axis=1)
        ep[:, :3] = (ds[:, :3] - c * tr[:, None]) / (2 * mat.G)
        ep[:, 3] = ds[:, 3] / mat.G
        vol = ep[:, :3].sum(axis=1)
        assert np.allclose(vol[cone], math.tan(math.radians(psi)) * st["eqps"][cone], rtol=1e-9, atol=1e-16)
        # deviatoric parallelism with the final deviator: e_dev = (3/2) Δλ s/q
        m = out[cone, :3].mean(axis=1)
        s_dev = out[cone].copy()
        s_dev[:, :3] -= m[:, None]
        q = pq(out[cone])[:, 1]
        e_dev = ep[cone].copy()
        e_dev[:, :3] -= (vol[cone] / 3)[:, None]
        e_dev[:, 3] *= 0.5  # tensor shear component
        expect = 1.5 * st["eqps"][cone, None] * s_dev / q[:, None]
        assert np.allclose(e_dev, expect, rtol=1e-8, atol=1e-14)


def test_apex_return_is_exact():
    mat = dp(30.0, 10.0, d=100.0)
    sig = np.zeros((3, 4))
    de = np.array([[1e-2, 1e-2, 1e-2, 0.0], [3e-2, 1e-2, 2e-2, 1e-3], [5e-2, 5e-2, 5e-2, 2e-2]])  # tension
    out, st, diss = run(mat, sig, de)
    p_apex = -mat.cohesion / mat.tan_beta
    assert np.allclose(out[:, :3], -p_apex, rtol=1e-14)
    assert np.allclose(out[:, 3], 0.0)
    assert np.all(st["eqps"] >= 0.0)


def test_limit_stress_ratio_in_shear():
    """Monotonic shear under constant mean stress drives q/p to tan β (+ d/p)."""
    for beta in (20.0, 30.0, 40.0):
        mat = dp(beta, 0.0, d=1.0)
        sig = np.array([[-1e4, -1e4, -1e4, 0.0]])
        step = np.array([[0.0, 0.0, 0.0, 1e-4]])
        for _ in range(300):
            sig, _, _ = run(mat, sig, step)
        p, q = pq(sig)[0]
        assert abs(q / p - (theory.drucker_prager_limit_ratio(beta) + mat.cohesion / p)) < 1e-10


def test_beta_zero_is_von_mises():
    mat = dp(0.0, 0.0, d=2e3)
    sig, de = random_states(500, seed=5)
    out, _, _ = run(mat, sig, de)
    q = pq(out)[:, 1]
    assert np.all(q <= 2e3 * (1 + 1e-12))


def test_elastic_law_is_linear_isotropic():
    mat = Elastic(E, NU, RHO)
    de = np.array([[1e-4, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 2e-4]])
    out, _, diss = run(mat, np.zeros((2, 4)), de)
    lam, mu = mat.K - 2 * mat.G / 3, mat.G
    assert np.allclose(out[0], [(lam + 2 * mu) * 1e-4, lam * 1e-4, lam * 1e-4, 0.0], rtol=1e-14)
    assert np.allclose(out[1], [0.0, 0.0, 0.0, mu * 2e-4], rtol=1e-14) and diss == 0.0


def test_same_on_every_rank():
    """Pointwise kernels: the same inputs give bit-identical outputs on every rank."""
    comm = MPI.COMM_WORLD
    sig, de = random_states(1000, seed=11)
    out, _, _ = run(dp(), sig, de)
    ref = comm.bcast(out, root=0)
    assert np.array_equal(out, ref)


@pytest.mark.parametrize("beta", [0.0, 35.0])
def test_yield_function_matches_invariants(beta):
    mat = dp(beta, 0.0, d=5.0)
    s = np.array([[-2e3, -1e3, -1.5e3, 300.0]])
    p, q = pq(s)[0]
    assert abs(mat.yield_function(s)[0] - (q - p * math.tan(math.radians(beta)) - 5.0)) < 1e-9


def plastic_volume_in_simple_shear(mat, dgam, n):
    """The plastic volume change of a point at p = 10 kPa sheared in n increments of engineering
    shear strain dgam (the stress level held by the yield surface): Σ tr C⁻¹(σ_trial − σ_new)."""
    sig = np.array([[-1e4, -1e4, -1e4, 0.0]])
    eqps = np.zeros(1)
    vol_p = 0.0
    lam = mat.K - 2 * mat.G / 3
    c = lam / (3 * lam + 2 * mat.G)
    for _ in range(n):
        de = np.array([[0.0, 0.0, 0.0, dgam]])
        out = np.zeros_like(sig)
        new = {"eqps": np.zeros(1)}
        mat.update(sig, de, {"eqps": eqps}, out, new, np.ones(1))
        ds = trial(mat, sig, de) - out
        vol_p += float((ds[0, :3] - c * ds[0, :3].sum()).sum() / (2 * mat.G))
        sig, eqps = out, new["eqps"]
    return vol_p


def test_dilation_stops_at_the_critical_state():
    """With max_dilation ε_c the plastic volume change of a point sheared at constant stress
    level grows as tan ψ · ε̄_p until it reaches ε_c, then stays there (ψ → 0); overshoot at
    most one increment's tan ψ Δλ. Without the cap it keeps growing."""
    eps_c = 0.01
    for cap, expect_stop in ((eps_c, True), (0.0, False)):
        mat = DruckerPrager(E, NU, RHO, 30.0, 10.0, 1.0, max_dilation=cap)
        dgam = 1e-3
        vol_p = plastic_volume_in_simple_shear(mat, dgam, 600)  # γ = 0.6: ε̄_p ≈ 0.35, tan ψ ε̄_p ≈ 0.06 > ε_c
        step = math.tan(math.radians(10.0)) * dgam  # the most one increment can add
        if expect_stop:
            assert eps_c - 1e-12 <= vol_p <= eps_c + step
        else:
            assert vol_p > 3 * eps_c


def _principal(sig):
    """Largest principal stress (tension +) of (n, 4) axisymmetric stresses."""
    c, h = 0.5 * (sig[:, 0] + sig[:, 1]), 0.5 * (sig[:, 0] - sig[:, 1])
    return np.maximum(c + np.hypot(h, sig[:, 3]), sig[:, 2])


@pytest.mark.parametrize("phi", [40.0, 50.0, 60.0])
def test_tension_cutoff_of_steep_cones(phi):
    """A cone steeper than tan β = 3/2 (Mohr-Coulomb φ > 36.87° matched in compression) admits
    tensile principal stresses; after a return none exceeds the cut-off T = d/tan β (≤ the
    cohesion), to round-off of the stress level; every state stays inside the cone; the
    dissipation is non-negative; states already admissible are untouched. Without the
    cut-off the same increments leave principal tensions of the order of the stresses."""
    beta, psi = theory.drucker_prager_cone(phi, 10.0)
    mat = DruckerPrager(E, NU, RHO, beta, psi, 1.0)
    assert mat.tan_beta > 1.5 and 0.0 < mat.tension_cutoff <= mat.cohesion
    sig, de = random_states(20000, seed=7, scale=5e4)
    out, st, diss = run(mat, sig, de)
    tol = 1e-10 * np.abs(sig).max()
    assert np.all(_principal(out) <= mat.tension_cutoff + tol)
    assert np.all(mat.yield_function(out) <= 1e-10 * np.abs(sig).max())
    end, mid = dissipations(mat, sig, de, out)
    assert end >= 0.0 and diss == pytest.approx(mid, rel=1e-9)
    t = trial(mat, sig, de)
    fine = (mat.yield_function(t) <= 0) & (_principal(t) <= mat.tension_cutoff)
    assert fine.sum() > 100 and np.allclose(out[fine], t[fine], rtol=1e-14, atol=1e-9)
    cut = (mat.yield_function(t) <= 0) & (_principal(t) > mat.tension_cutoff)
    assert cut.sum() > 20  # elastic trials beyond the cut-off are returned too
    no_cut = DruckerPrager(E, NU, RHO, beta, psi, 1.0)
    no_cut.tension_cutoff = math.inf
    out2, _, _ = run(no_cut, sig, de)
    assert _principal(out2).max() > 1e3  # Pa: what the cut-off removes


def test_tension_cutoff_is_off_for_ordinary_cones():
    """tan β ≤ 3/2: no admissible state has a principal stress beyond the apex tension d/tan β,
    so there is no cut-off to evaluate (inf) and the return is the plain cone's."""
    for beta in (30.0, 50.19, 56.3):
        assert DruckerPrager(E, NU, RHO, beta, 10.0, 1.0).tension_cutoff == math.inf
    mat = dp(50.19, 20.0)
    sig, de = random_states(5000, seed=2)
    out, _, _ = run(mat, sig, de)
    assert np.all(_principal(out) <= mat.cohesion / mat.tan_beta + 1e-10 * np.abs(sig).max())


def test_a_viscoplastic_overstress_in_simple_shear_follows_its_closed_form():
    """Duvaut-Lions around Drucker-Prager (ψ 0, so p stays put and the return only scales the
    shear): from the yield surface, simple shear at a constant rate γ̇ builds the overstress
    x = σ_rz − q_y/√3 as G τ γ̇ (1 − e^(−t/τ)). The update is backward Euler of that ODE,
    x ← (x + G Δγ)/(1 + Δt/τ), which it must match to round-off; against the closed form its
    error is below Δt/(2τ) · max(t/τ e^(−t/τ)) = 0.18 % at Δt = τ/100 (bar 0.3 %), and the
    steady overstress is the closed form's exactly. The dissipation it books is the solver's
    trapezoidal partner, σ_mid : Δε_p."""
    from silo_dolfinx.materials import Viscoplastic

    law = dp(30.0, 0.0, d=1.0)
    tau, rate = 1e-3, 2.0
    mat = Viscoplastic(law, tau)
    assert mat.state_fields == law.state_fields and mat.strength == law.strength
    p = 1e4
    qy = p * law.tan_beta + law.cohesion
    sig = np.array([[-p, -p, -p, qy / math.sqrt(3.0)]])
    dt = tau / 100
    de = np.array([[0.0, 0.0, 0.0, rate * dt]])
    x_discrete, xs, booked, mids = 0.0, [], 0.0, 0.0
    state = {"eqps": np.zeros(1)}
    for _ in range(800):
        out, new = np.zeros((1, 4)), {"eqps": np.zeros(1)}
        booked += mat.update(sig, de, state, out, new, np.ones(1), dt)
        mids += dissipations(law, sig, de, out)[1]
        sig, state = out, new
        x_discrete = (x_discrete + law.G * rate * dt) / (1.0 + dt / tau)
        xs.append((sig[0, 3] - qy / math.sqrt(3.0), x_discrete))
    x, xd = np.array(xs).T
    t = dt * np.arange(1, x.size + 1)
    exact = law.G * tau * rate * (1.0 - np.exp(-t / tau))
    assert np.allclose(x, xd, rtol=1e-9, atol=1e-9 * qy)
    assert np.abs(x - exact).max() < 3e-3 * exact[-1]
    assert x[-1] == pytest.approx(law.G * tau * rate, rel=1e-3)  # 8 τ: e⁻⁸ = 3e-4 short of it
    assert np.allclose(sig[0, :3], -p, rtol=1e-12) and state["eqps"][0] > 0.0
    assert booked == pytest.approx(mids, rel=1e-9) and booked > 0.0


@pytest.mark.parametrize("law", ["drucker_prager", "recompaction", "non_coaxial", "mohr_coulomb"])
def test_a_relaxation_time_between_its_limits(law):
    """τ → 0 is the rate-independent law (to a = 1/(1 + Δt/τ) of the return), τ → ∞ the elastic
    trial; at any τ the booked dissipation is the trapezoidal σ_mid : Δε_p to round-off (the
    blend stays inside the energy balance); no Δt, or an elastic law, is refused."""
    from silo_dolfinx.materials import MohrCoulomb, NonCoaxial, Viscoplastic

    beta, psi = theory.drucker_prager_cone(35.0, 10.0)
    rate_free = {"drucker_prager": DruckerPrager(E, NU, RHO, beta, psi, 1.0),
                 "recompaction": DruckerPrager(E, NU, RHO, beta, psi, 1.0, 0.05, True),
                 "non_coaxial": NonCoaxial(E, NU, RHO, beta, psi, 1.0, 1e5),
                 "mohr_coulomb": MohrCoulomb(E, NU, RHO, 35.0, 10.0, 1.0)}[law]
    sig, de = random_states(2000, seed=3)
    dV, dt = np.ones(len(sig)), 1e-4
    st_old = {k: np.full(len(sig), 0.01) for k in rate_free.state_fields}

    def update(mat):
        out, st = np.zeros_like(sig), {k: np.zeros(len(sig)) for k in rate_free.state_fields}
        return out, st, mat.update(sig, de, st_old, out, st, dV, dt)

    ref, st_ref, _ = update(rate_free)
    t = trial(rate_free, sig, de)
    assert np.abs(t - ref).max() > 1e3  # Pa: most points yield
    for tau, towards, st_towards in ((1e-12, ref, st_ref), (1e6, t, st_old)):
        out, st, diss = update(Viscoplastic(rate_free, tau))
        a = 1.0 / (1.0 + dt / tau)
        gap = min(a, 1.0 - a) * np.abs(t - ref).max()
        assert np.abs(out - towards).max() <= gap + 1e-9 * np.abs(sig).max()
        for k in st:
            assert np.allclose(st[k], st_towards[k], rtol=1e-6, atol=1e-8)  # a · 0.01 of an opening
    for tau in (1e-4, 1e-3):
        out, _, diss = update(Viscoplastic(rate_free, tau))
        assert diss == pytest.approx(dissipations(rate_free, sig, de, out)[1], rel=1e-9)
    with pytest.raises(ValueError, match="Δt"):
        Viscoplastic(rate_free, 1e-3).update(sig, de, st_old, np.zeros_like(sig), dict(st_old), dV)
    with pytest.raises(ValueError, match="no plastic flow"):
        Viscoplastic(Elastic(E, NU, RHO), 1e-3)


def test_the_mobilised_strength_is_one_on_every_yield_surface():
    """Material.mobilised_strength (what shear_zones.csv counts as yield): exactly 1 to
    round-off for every stress the return puts on the surface - the cone's (coaxial and
    non-coaxial) and Mohr–Coulomb's pyramid at whatever Lode angle the return lands (its own
    strength there, not the circumscribing cone's: at triaxial extension the cone's ratio would
    read (3 − sin φ)/(3 + sin φ) = 0.72 at φ 35°) - below 1 for every admissible trial left
    untouched, NaN at the apex (no strength), and a viscoplastic overstress above 1."""
    from silo_dolfinx.materials import MohrCoulomb, NonCoaxial, Viscoplastic

    laws = [dp(30.0, 10.0, d=0.0), NonCoaxial(E, NU, RHO, 30.0, 10.0, 0.0, 5.6e4), MohrCoulomb(E, NU, RHO, 35.0, 10.0, 0.0)]
    for mat in laws:
        sig, de = random_states(4000, seed=5, scale=5e4)
        t = trial(mat, sig, de)
        out, state = run(mat, sig, de)[:2]
        mob, mob_t = mat.mobilised_strength(out, np.empty(out.shape[0])), mat.mobilised_strength(t, np.empty(t.shape[0]))
        yielded = mat.yield_function(t) > 0
        returned = state["eqps"] > 0  # the non-coaxial law's lowered trial may end inside: not returned
        apex = ~np.isfinite(mob)  # returned to the apex: p = 0 without cohesion, no strength left
        assert returned.sum() > 1000 and np.all(np.abs(pq(out[apex])) < 1e-6 * np.abs(sig).max())
        assert np.allclose(mob[returned & ~apex], 1.0, rtol=0.0, atol=1e-9), mat.name
        assert np.all(mob[~apex] <= 1.0 + 1e-9), mat.name
        assert np.all(mob_t[~yielded] <= 1.0 + 1e-12) and np.all(mob_t[yielded & np.isfinite(mob_t)] > 1.0)
    # Mohr–Coulomb in triaxial extension (σ1 = σ2 > σ3, compression −): on its surface at 1
    mc = laws[2]
    s = math.sin(math.radians(35.0))
    lo = -1e4
    hi = lo * (1 - s) / (1 + s)  # (hi − lo) = −(hi + lo) sin φ
    ext = np.array([[hi, lo, hi, 0.0]])
    assert mc.mobilised_strength(ext, np.empty(1))[0] == pytest.approx(1.0, abs=1e-12)
    assert mc.yield_function(ext)[0] == pytest.approx(0.0, abs=1e-9)
    # a viscoplastic point held above the surface reads its overstress
    law = dp(30.0, 0.0, d=0.0)
    vp = Viscoplastic(law, 1e-3)
    p = 1e4
    over = np.array([[-p, -p, -p, 1.2 * p * law.tan_beta / math.sqrt(3.0)]])
    assert vp.mobilised_strength(over, np.empty(1))[0] == pytest.approx(1.2, rel=1e-12)
    with pytest.raises(TypeError, match="no yield surface"):
        Elastic(E, NU, RHO).mobilised_strength(over, np.empty(1))
