"""Wall contact and wall pressures: the friction laws on a sliding block, Janssen in the
flat-bottomed silo, hopper filling, the abrupt transition, Δt and rank independence."""

import math
import glob

import numpy as np
import pytest
from mpi4py import MPI

from silo_dolfinx import analysis, theory
from silo_dolfinx.contact import COULOMB, VELOCITY, FrictionLaw, FrictionMemory, WallContact
from silo_dolfinx.geometry import hopper_half_angle
from silo_dolfinx.geometry.mesher import mesh_scene
from silo_dolfinx.geometry.wall import Segment, Wall
from silo_dolfinx.materials import Elastic
from silo_dolfinx.output import read_csv
from silo_dolfinx.scene import load_scene
from silo_dolfinx.simulation import SiloModel, run, smooth_step
from silo_dolfinx.solver import ExplicitSolver, Numerics

from conftest import SCENES


def read_profile(path):
    return read_csv(path)  # the package's reader, typed by the schema


# ------------------------------------------------------------------ the sliding block (Figs. 3-13/3-14)
def sliding_block(comm, law, push_max, t_end=0.4):
    """A ring block 0.05 × 0.4 m pressed on a vertical wall (radial body force 10 m/s² × mass)
    and pushed down along it by a body force ramped from t = 0.1 s to push_max × 10 m/s²."""
    from dolfinx import mesh as dmesh

    msh = dmesh.create_rectangle(comm, [[1.95, 1.0], [2.0, 1.4]], [2, 8], dmesh.CellType.quadrilateral)
    s = ExplicitSolver(msh, Elastic(1e7, 0.3, 1000.0), Numerics(time_step_scale=0.9))
    x = msh.geometry.x
    nodes = np.nonzero(np.abs(x[:, 0] - 2.0) < 1e-12)[0]
    nodes = nodes[s.node_dof[nodes] < s.n_owned]
    c = WallContact(Wall([Segment((2.0, -5.0), (2.0, 5.0))]), nodes, s.node_dof[nodes], [law])
    s.contacts.append(c)
    press = np.zeros((s.n_nodes, 2))
    press[:, 0] = 10.0 * s.mass
    push = np.zeros((s.n_nodes, 2))
    push[:, 1] = -10.0 * s.mass
    ramp = lambda t: push_max * max(0.0, (t - 0.1) / (t_end - 0.1))  # noqa: E731
    s.add_nodal_force(press, lambda t: smooth_step(t / 0.05), "press")
    s.add_nodal_force(push, ramp, "push")
    mass = comm.allreduce(float(s.mass[:s.n_owned].sum()), op=MPI.SUM)
    hist, nodal = [], []
    while s.t < t_end:
        s.step()
        N = comm.allreduce(float(c.normal_force.sum()), op=MPI.SUM)
        T = comm.allreduce(float(c.shear_force.sum()), op=MPI.SUM)
        vz = comm.allreduce(float((s.v[:s.n_owned, 1] * s.mass[:s.n_owned]).sum()), op=MPI.SUM) / mass
        hist.append((s.t, N, T, vz, ramp(s.t - 0.5 * s.dt_prev) * 10.0 * mass))
        sl = c.in_contact & (np.abs(c.slip_velocity) > 1e-9)
        nodal += list(zip(np.abs(c.slip_velocity[sl]), np.abs(c.shear_force[sl]) / c.normal_force[sl]))
    return np.array(hist), np.array(nodal).reshape(-1, 2)


def test_wall_history_samples_are_interval_means_of_the_contact_forces(comm):
    """What the wall history samples (output.history_sampling = "mean"): each node's forces and
    slip averaged over the accepted steps since the previous sample, weighted by their Δt - to
    round-off against the step-by-step record; with no step since, the last step's values. And
    what that buys: the block pressed suddenly on the wall by 10 m/s² × its mass rings (its
    nodes' forces step by step scatter about the load); the mean over an interval of 40 steps
    carries the load (impulse balance: the block's momentum hardly changes over an interval)."""
    from dolfinx import mesh as dmesh

    msh = dmesh.create_rectangle(comm, [[1.95, 1.0], [2.0, 1.4]], [2, 8], dmesh.CellType.quadrilateral)
    s = ExplicitSolver(msh, Elastic(1e7, 0.3, 1000.0), Numerics(time_step_scale=0.9))
    x = msh.geometry.x
    nodes = np.nonzero(np.abs(x[:, 0] - 2.0) < 1e-12)[0]
    nodes = nodes[s.node_dof[nodes] < s.n_owned]
    c = WallContact(Wall([Segment((2.0, -5.0), (2.0, 5.0))]), nodes, s.node_dof[nodes], [FrictionLaw(COULOMB, mu=0.3)])
    s.contacts.append(c)
    press = np.zeros((s.n_nodes, 2))
    press[:, 0] = 10.0 * s.mass
    s.add_nodal_force(press, lambda t: 1.0, "press")  # suddenly: the block rings against the wall
    load = comm.allreduce(float(press[:s.n_owned, 0].sum()), op=MPI.SUM)
    s.step()
    c.interval_means()  # start an interval here
    instants, means = [], []
    for _ in range(20):
        rec = []
        for _ in range(40):
            dt = s.step()
            rec.append((dt, c.normal_force.copy(), c.shear_force.copy(), c.slip_velocity.copy()))
        dts = np.array([r[0] for r in rec])
        for j, got in enumerate(c.interval_means()):
            want = sum(r[0] * r[1 + j] for r in rec) / dts.sum()
            assert np.allclose(got, want, rtol=1e-12, atol=1e-12 * (np.abs(want).max() + 1.0))
            if j == 0:
                means.append(comm.allreduce(float(got.sum()), op=MPI.SUM))
        instants += [comm.allreduce(float(r[1].sum()), op=MPI.SUM) for r in rec]
    again = c.interval_means()  # no step since: the last step's values
    assert np.array_equal(again[0], c.normal_force) and np.array_equal(again[2], c.slip_velocity)
    dev_instant, dev_mean = (np.abs(np.array(a) / load - 1.0).max() for a in (instants, means))
    # measured: the instants swing to ±67 % (a ~13-step radial ringing), the 40-step means stay
    # within 1.5 % (0.5 % of it the ring's hoop stress, which carries part of a radial load: the
    # wall takes 1.005 × the load in the mean from the first interval on; the rest a part-period
    # of ringing at each end of an interval); 2 % and 30 % sit well clear of both
    assert dev_mean < 0.02 and dev_instant > 0.3


def test_coulomb_sticks_below_mu_n_and_saturates_at_it(comm):
    mu = 0.3
    h, nodal = sliding_block(comm, FrictionLaw(COULOMB, mu=mu), push_max=1.0)
    t, N, T, vz, push = h.T
    N0 = np.median(N[(t > 0.06) & (t < 0.1)])  # the wall force before the push
    stick = (t > 0.15) & (push < 0.9 * mu * N0)
    slide = push > 1.1 * mu * N0
    assert stick.sum() > 100 and slide.sum() > 100
    # below μN: the block holds (no slip of the block as a whole) and the wall carries the push
    assert np.abs(vz[stick]).max() < 1e-4
    assert np.allclose(T[stick], push[stick], rtol=0.01)
    # beyond: every slipping node carries exactly μN (round-off; the bar is 1 %), no
    # node ever more, and the block accelerates. (The total T/N dips below μ at moments: the
    # sliding elastic block chatters, some nodes re-sticking, as the thesis' slip-stick.)
    nodal = np.concatenate(comm.allgather(nodal))
    assert len(nodal) > 100 and np.allclose(nodal[:, 1], mu, rtol=1e-12)
    assert np.all(T <= mu * N * (1 + 1e-12))
    assert np.mean(T[slide] / N[slide]) > 0.95 * mu
    assert vz[-1] < -0.3


def test_velocity_dependent_law_follows_eq_7_1_along_a_slip_ramp(comm):
    law = FrictionLaw(VELOCITY, mu_static=0.67, mu_kinetic=0.3, decay=2.0)
    h, nodal = sliding_block(comm, law, push_max=2.0, t_end=0.5)
    nodal = np.concatenate(comm.allgather(nodal))
    slipping = nodal[nodal[:, 0] > 1e-3]
    assert slipping[:, 0].max() > 0.5  # the ramp reaches fast sliding
    mu = theory.dynamic_friction(slipping[:, 0], 0.67, 0.3, 2.0)
    assert np.allclose(slipping[:, 1], mu, rtol=0.01)  # issue bar 1 %; measured: round-off
    assert np.allclose(slipping[:, 1], mu, rtol=1e-9)
    # and the block starts to move only when the push exceeds μs N
    t, N, T, vz, push = h.T
    N0 = np.median(N[(t > 0.06) & (t < 0.1)])
    assert np.abs(vz[(t > 0.15) & (push < 0.9 * 0.67 * N0)]).max() < 1e-4


# ------------------------------------------------------------------ the friction limit's memory
def pressed_nodes(memory, law=FrictionLaw(COULOMB, mu=0.5), n=3):
    """``n`` free nodes of 1 kg on the wall r = 2 (no mesh: the contact kernel alone)."""
    x = np.column_stack([np.full(n, 2.0), np.linspace(0.0, 1.0, n)])
    return WallContact(Wall([Segment((2.0, -5.0), (2.0, 5.0))]), np.arange(n), np.arange(n), [law], memory), x


def press_and_slide(c, x, N, trial_slip, dt=1e-4):
    """One contact step of nodes pressed into the wall with the force ``N`` (newton: a trial
    normal velocity N Δt̄/M into it) and a trial tangential velocity ``trial_slip``; returns |T|."""
    v = np.column_stack([np.full(len(x), N * dt), np.full(len(x), -trial_slip)])
    c.apply(x, v, np.ones(len(x)), dt, dt)
    return np.abs(c.shear_force.copy())


def test_the_friction_limit_follows_a_normal_force_step_with_its_memory():
    """The simplified Prakash-Clifton law dÑ/dt = −(|v| + v*)/L (Ñ − N): a node sliding at
    0.1 m/s whose normal force steps from 1 to 3 N carries T = μ [3 − 2 exp(−(v + v*) t/L)]
    (closed form at constant slip speed; the friction takes μ Ñ Δt/M = 1.5e-4 m/s of the 0.1
    m/s each step, so the speed in the exponent is constant to 0.15 %: tolerance 0.3 %), where
    Coulomb's limit jumps to μ N at once; a sticking node's limit follows at v*/L alone, to
    round-off (its slip is exactly 0); and a memory far shorter than a step is Coulomb's limit
    to round-off."""
    mu, vs, vstar, L, dt = 0.5, 0.1, 0.01, 5.5e-4, 1e-4  # the sliding time scale L/(vs + v*) = 50 steps
    c, x = pressed_nodes(FrictionMemory(L, vstar))
    for _ in range(2000):  # settled under N = 1 N at the slip speed
        press_and_slide(c, x, 1.0, vs)
    assert np.allclose(c.lagged_normal, 1.0, rtol=1e-12)
    n = np.arange(1, 401)  # eight time scales
    T = np.array([press_and_slide(c, x, 3.0, vs) for _ in n])
    slip = vs - mu * 2.0 * dt  # the slip speed midway through the relaxation (Ñ ≈ 2 N)
    expected = mu * (3.0 - 2.0 * np.exp(-(slip + vstar) * n * dt / L))
    assert np.allclose(T, expected[:, None], rtol=3e-3)
    assert T[0, 0] < 0.6 * mu * 3.0 and T[-1, 0] > 0.99 * mu * 3.0  # the limit lags, then catches up
    coulomb, _ = pressed_nodes(None)
    assert np.allclose(press_and_slide(coulomb, x, 3.0, vs), mu * 3.0, rtol=1e-12)

    # sticking (a trial slip far below what μ N stops): Ñ relaxes at v*/L, the node holds
    c, x = pressed_nodes(FrictionMemory(L, vstar))
    c.lagged_normal[:] = 1.0
    for k in range(1, 101):
        press_and_slide(c, x, 3.0, 1e-6)
        assert np.all(c.slip_velocity == 0.0)
        assert np.allclose(c.lagged_normal, 3.0 - 2.0 * math.exp(-vstar * k * dt / L), rtol=1e-12)

    # L → 0: Coulomb's limit, force for force, through stick and slip
    short, _ = pressed_nodes(FrictionMemory(1e-30, vstar))
    coulomb, _ = pressed_nodes(None)
    rng = np.random.default_rng(3)
    for N, trial in zip(rng.uniform(0.1, 3.0, 50), rng.uniform(-0.05, 0.05, 50)):
        assert np.array_equal(press_and_slide(short, x, N, trial), press_and_slide(coulomb, x, N, trial))


# ------------------------------------------------------------------ the flat-bottomed silo (ch. 6)
def fill_flat_bottom(out, comm, mu, scene="flat_bottom_ch6", duration=10.0, extra=()):
    """The ch. 6 silo filled in 10 layers over ``duration`` s on a coarse mesh (0.035 m)."""
    sc = load_scene(SCENES / f"{scene}.toml", ["geometry.element_size=0.035", 'discharge.mode="none"',
                                               "fill.damping=0.3", "store.duration=1.0", f"fill.duration={duration}",
                                               "output.field_interval=100", f"wall.mu={mu}", *extra])
    summary = run(sc, out, comm, progress_every=1e9)
    comm.barrier()
    wall = read_profile(out / "wall_profile_store.csv")
    snap = dict(np.load(sorted(glob.glob(str(out / "fields" / "snapshot_*.npz")))[-1]))
    vertical = wall["r"] > 0.35 * (1 - 1e-9)
    wall = {k: v[vertical] for k, v in wall.items()}
    return sc, summary, wall, snap


@pytest.mark.serial  # the literal cone (a scene option) runs the default cone's kernels, whose fill of this
# silo runs on 2 ranks in the next-but-one test; a partition reorders sums only (test_serial_and_parallel_runs_agree)
def test_janssen_in_the_flat_bottomed_silo(shared_tmp, comm):
    """Ch. 6 silo with the friction angle read literally as β = 35° (cone = "beta"), filled in
    10 layers, wall μ = 0.3 (a wall weaker than the solid, so it slides, as Janssen assumes;
    see the next tests for the thesis' μ = 0.63):

    * p_h(z) within 10 % of Janssen with K measured from the simulation (wall p_h over the
      cross-section mean σ_zz, averaged over the lower half), for depths from z0 to 0.1 m
      above the bottom (measured 3.8 %);
    * the measured K is the Drucker-Prager active ratio (3 − tan β)/(3 + 2 tan β) = 0.523
      within 10 % (measured 0.56) — not the thesis' 0.38, which this β cannot give;
    * p_s/p_n = μ on the sliding wall within 2 % (measured 0.2 %);
    * energy balance error < 1 % through filling;
    * with the friction limit's memory (L 1e-4 m, v* 0.01 m/s: a sticking node's limit follows
      in 10 ms, the fill takes 10 s) the settled wall is Coulomb's: p_n within 2 % of the run
      without it at every node from 0.1 to 3 m (measured 0.11 %: the margin is for the fill's
      slip-stick, which the memory may realise differently), p_s/p_n = μ within 2 % (0.15 %)."""
    mu = 0.3
    sc, summary, wall, snap = fill_flat_bottom(shared_tmp / "janssen", comm, mu, "flat_bottom_ch6_literal_beta")
    H, R = sc.geometry.fill_height, 0.35
    gamma = sc.material.density * sc.loads.gravity
    K = analysis.lateral_pressure_ratio(snap, wall, wall["z"])
    lower = (wall["z"] > 0.1) & (wall["z"] < H / 2)
    K_meas = float(np.mean(K[lower]))
    assert abs(K_meas - theory.drucker_prager_active_k(35.0)) < 0.1 * theory.drucker_prager_active_k(35.0)
    z0 = theory.janssen_depth(R, mu, K_meas)
    sel = (wall["z"] >= 0.1) & (wall["z"] <= H - z0)
    ph, _, _ = theory.janssen(H - wall["z"][sel], R, mu, K_meas, gamma)
    assert np.all(np.abs(wall["p_n"][sel] / ph - 1) < 0.10)
    assert np.all(np.abs(wall["p_s"][sel] / wall["p_n"][sel] - mu) < 0.02 * mu)
    assert summary["energy_balance_error_max"] < 0.01

    _, summary, mem, _ = fill_flat_bottom(shared_tmp / "memory", comm, mu, "flat_bottom_ch6_literal_beta",
                                          extra=("wall.regularisation_length=1e-4", "wall.regularisation_speed=0.01"))
    sel = (mem["z"] >= 0.1) & (mem["z"] <= 3.0)
    assert np.allclose(mem["z"], wall["z"], atol=1e-4) and sel.sum() > 20  # the same nodes (settled a μm apart)
    assert np.all(np.abs(mem["p_n"][sel] / wall["p_n"][sel] - 1) < 0.02)
    assert np.all(np.abs(mem["p_s"][sel] / mem["p_n"][sel] - mu) < 0.02 * mu)
    assert summary["energy_balance_error_max"] < 0.01


@pytest.mark.serial  # the literal cone (a scene option) runs the default cone's kernels, whose fill of this
# silo runs on 2 ranks in the next test; a partition reorders sums only (test_serial_and_parallel_runs_agree)
def test_a_wall_rougher_than_the_solid_does_not_slide(shared_tmp, comm):
    """With the thesis' μ = 0.63 and its 35° read literally as β, the Drucker-Prager solid
    yields next to the wall before the wall slides: a DP solid carries at most τ/σ_n = 0.457
    on any plane, so the mobilised wall friction settles at that bound (measured 0.437),
    below μ. (Why the scenes read 35° as a Mohr-Coulomb angle: the next test.)"""
    sc, summary, wall, snap = fill_flat_bottom(shared_tmp / "rough", comm, 0.63, "flat_bottom_ch6_literal_beta")
    sel = (wall["z"] >= 0.3) & (wall["z"] <= 2.5)
    ratio = wall["p_s"][sel] / wall["p_n"][sel]
    bound = theory.drucker_prager_wall_shear_limit(35.0)
    assert np.all(ratio < 0.63 - 0.1)
    assert abs(np.mean(ratio) - bound) < 0.06 * bound


def test_a_mohr_coulomb_solid_weaker_than_the_wall_caps_its_friction(shared_tmp, comm):
    """Fig. 7-5's mechanism (docs/validation/ch7.md): Mohr-Coulomb's pyramid of φ 30° carries
    at most τ/σ_n = tan 30° = 0.577 on any plane, so beside the ch. 7 wall (μ 0.67) the layer
    next to the wall yields and the mobilised wall friction settles at that bound (measured
    0.547-0.583, mean 0.567, on this coarse mesh, 1 and 2 ranks; 0.58 on the ch. 7 bin at
    h 0.04 m; the 5 % tolerance is the layer-to-layer ripple), below μ, and the fill's K rises
    well above the elastic ν/(1 − ν) = 0.43 that this silo keeps on the scenes' cone (measured
    0.63 against 0.44 in the next test; the bar 1.3 × 0.43 sits between the two), to the ratio
    of a solid at yield beside a wall as rough as itself, (1 − sin²φ)/(1 + sin²φ) = 0.60
    (theory.wall_yield_k; within 10 %: the yielded layer is one coarse element, and K here is
    the wall's p_h over the section's mean σ_zz, not the wall's own σ_zz)."""
    sc, summary, wall, snap = fill_flat_bottom(shared_tmp / "mc30", comm, 0.67, extra=(
        'material.model="mohr_coulomb"', "material.friction_angle=30"))
    sel = (wall["z"] >= 0.3) & (wall["z"] <= 2.5)
    ratio = wall["p_s"][sel] / wall["p_n"][sel]
    bound = math.tan(math.radians(30.0))
    assert np.all(ratio < 0.67 - 0.05)
    assert abs(np.mean(ratio) / bound - 1) < 0.05, np.mean(ratio)
    nu = sc.material.poisson_ratio
    K = analysis.lateral_pressure_ratio(snap, wall, wall["z"])
    lower = (wall["z"] > 0.1) & (wall["z"] < sc.geometry.fill_height / 2)
    assert np.mean(K[lower]) > 1.3 * nu / (1 - nu), np.mean(K[lower])
    assert abs(np.mean(K[lower]) / theory.wall_yield_k(30.0, 0.67) - 1) < 0.10, np.mean(K[lower])
    assert summary["energy_balance_error_max"] < 0.01


def test_janssen_with_the_thesis_K_for_the_mohr_coulomb_cone(shared_tmp, comm):
    """The ch. 6 scene as shipped: the thesis' wall μ = 0.63 and its 35° read as a Mohr-Coulomb
    angle (the default cone: β = 54.81°). The fill stays elastic, so K is the elastic ratio
    ν/(1 − ν) = 0.43 within 10 % (measured 0.44), the wall slides (p_s/p_n = μ within 2 %,
    measured 0.626-0.634, at every node from 0.3 to 2.5 m, and at the friction limit (1 %) over at
    least 80 % of the wall below z0), and p_h is within 15 % of Janssen with the thesis'
    K = 0.38 from z0 = R/(2μK) down to 0.1 m above the bottom on this coarse mesh (measured
    0.98-1.12: 1.10 at z0, where the fill's K 0.44 against 0.38 matters most, 1.02 at depth,
    where Janssen no longer depends on K; the 10 % bar is the full scene's, in the ch. 6
    demo). With β = 35° none of this holds (previous two tests). Filled in 5 s, not the
    scene's 10 (half the steps): measured 0.979-1.115 against Janssen, p_s/p_n within 0.7 %
    of μ, 91 % of the wall below z0 at the 1 % limit (10 s: 0.984-1.116, 0.5 %, 98 %)."""
    sc, summary, wall, snap = fill_flat_bottom(shared_tmp / "janssen_mc", comm, 0.63, "flat_bottom_ch6", 5.0)
    H, R, mu, nu = sc.geometry.fill_height, 0.35, 0.63, sc.material.poisson_ratio
    gamma = sc.material.density * sc.loads.gravity
    K = analysis.lateral_pressure_ratio(snap, wall, wall["z"])
    lower = (wall["z"] > 0.1) & (wall["z"] < H / 2)
    assert abs(np.mean(K[lower]) / (nu / (1 - nu)) - 1) < 0.10
    z0 = theory.janssen_depth(R, mu, 0.38)
    sel = (wall["z"] >= 0.1) & (wall["z"] <= H - z0)
    ph, _, _ = theory.janssen(H - wall["z"][sel], R, mu, 0.38, gamma)
    assert np.all(np.abs(wall["p_n"][sel] / ph - 1) < 0.15)
    slide = (wall["z"] >= 0.3) & (wall["z"] <= 2.5)
    assert np.all(np.abs(wall["p_s"][slide] / wall["p_n"][slide] - mu) < 0.02 * mu)
    below_z0 = (wall["z"] > 0.0) & (wall["z"] <= H - z0)
    assert np.mean(np.abs(wall["p_s"][below_z0] / wall["p_n"][below_z0] - mu) < 0.01 * mu) >= 0.8
    assert summary["energy_balance_error_max"] < 0.01


def test_janssen_on_the_vertical_wall_of_the_ch7_silo(shared_tmp, comm):
    """The ch. 7 cylinder on a hopper (abrupt transition) as shipped: φ = 40° read as a
    Mohr-Coulomb angle gives a steep cone (β = 58.57°, tan β > 1.5: the tension cut-off is on)
    and the thesis' wall μ = 0.67 can slide. Coarse mesh (0.035 m), 10 layers, the bin shortened
    from 4.31 to 2.5 m (3.6 Janssen depths z0 = R/(2μK) = 0.69 m: the asymptote is reached; 920
    cells instead of ~1,400): on the vertical wall from z0 below the surface down to one radius
    above the transition (below that the hopper unloads the wall: 0.59 of Janssen at the
    corner, 0.82 one cell up), p_h within 15 % of Janssen with the thesis' K = 0.38 on this
    coarse mesh (the full scene's bar is 10 %, in demos/janssen_filling.py; measured 1.000-1.105,
    the full bin 0.985-1.10, the upper part above Janssen as the elastic fill's K = ν/(1 − ν) =
    0.43 exceeds 0.38), the wall at the friction limit (1 %) over at least 80 % of that wall
    (measured 100 %), no principal tension beyond the cut-off anywhere, energy < 1 % (0.09 %).
    Filled in 5 s, not the scene's 10 (half the steps; 10 s: 0.996-1.103, 100 %, 0.09 %)."""
    sc = load_scene(SCENES / "bin_hopper_ch7_abrupt.toml", ["geometry.element_size=0.035", 'discharge.mode="none"',
                                                             "geometry.bin_height=2.5", "fill.damping=0.3",
                                                             "fill.duration=5.0",
                                                             "store.duration=1.0", "output.field_interval=100",
                                                             "output.stations=[0.3, 0.687, 1.0, 2.0]"])
    assert math.tan(math.radians(sc.cone["beta"])) > 1.5
    out = shared_tmp / "ch7_fill"
    summary = run(sc, out, comm, progress_every=1e9)
    comm.barrier()
    w = read_profile(out / "wall_profile_store.csv")
    g = sc.geometry
    vertical = w["r"] > g.radius * (1 - 1e-9)
    c = analysis.janssen_comparison(w["z"][vertical], w["p_n"][vertical], w["p_s"][vertical],
                                    fill_height=g.fill_height, radius=g.radius, mu=sc.wall.mu, k=0.38,
                                    unit_weight=sc.material.density * sc.loads.gravity,
                                    z_min=sc.outline.transition_points[0][1] + g.radius)
    assert c["ratio"].size > 10
    assert np.all(np.abs(c["ratio"] - 1) < 0.15), (c["ratio_min"], c["ratio_max"])
    assert c["slip_fraction"] >= 0.8, c["slip_fraction"]
    snap = dict(np.load(sorted(glob.glob(str(out / "fields" / "snapshot_*.npz")))[-1]))
    srr, szz, stt, srz = (snap[f"cell_stress_{k}"] for k in ("rr", "zz", "tt", "rz"))
    top = np.maximum(0.5 * (srr + szz) + np.hypot(0.5 * (srr - szz), srz), stt)
    cutoff = sc.material.cohesion / math.tan(math.radians(sc.cone["beta"]))
    assert top.max() <= cutoff + 1e-9 * np.abs(szz).max()  # cell means of quadrature values inside the cut-off
    assert summary["energy_balance_error_max"] < 0.01


# ------------------------------------------------------------------ the ch. 4 hopper
@pytest.mark.parametrize("scene", ["hopper_ch4", "hopper_ch4_literal_beta"])
def test_hopper_filling_pressures(shared_tmp, comm, scene):
    """Ch. 4 hopper filled in 10 layers (coarse mesh): p_wn within 15 % of EN 1991-4's hopper
    filling pressure over the middle 80 % of the wall, the ch. 4 bar, under both readings of
    the friction angle (measured 12 % with φ 30° → β 50.19°, 13 % with β = 30°); wall nodes
    never penetrate by more than 1 % of the element size.

    Walker κ = −1 is drawn, not a bar: with φ = 30° (φw 15°, α 22.6°) its m = −0.81 gives
    pressures rising to the outlet above ρgH, which neither EN 1991-4 nor this simulation
    shows. With β = 30° read literally, the Mohr–Coulomb angle of that Drucker–Prager solid in
    compression (15.3°, theory.drucker_prager_compression_angle) has m = 0.32, and the
    simulation is within 20 % of it above six outlet radii up to 0.9 H (measured 0.89–1.17;
    Walker's slice has uniform stress across it, hence not 15 %); below, the closed base
    carries part of the fill and the simulated pressure falls to 0.6–0.8 of Walker's, which
    has no base."""
    sc = load_scene(SCENES / f"{scene}.toml", ["geometry.element_size=0.06", 'geometry.mesh="unstructured"',
                                               'discharge.mode="none"', "fill.damping=0.3", "store.duration=0.5",
                                               "output.field_interval=100"])
    out = shared_tmp / scene
    summary = run(sc, out, comm, progress_every=1e9)
    comm.barrier()
    w = read_profile(out / "wall_profile_store.csv")
    g = sc.geometry
    alpha = hopper_half_angle(g)
    en, _ = theory.en1991_hopper(w["z"], sc.wall.mu, alpha, g.outlet_radius, g.height,
                                 sc.material.density * sc.loads.gravity)
    mid = (w["z"] > 0.1 * g.height) & (w["z"] < 0.9 * g.height)
    assert np.all(np.abs(w["p_n"][mid] / en[mid] - 1) < 0.15)
    if sc.material.cone == "beta":
        phi = theory.drucker_prager_compression_angle(sc.material.friction_angle)
        walker, _ = theory.walker_hopper(w["z"], phi, sc.wall.mu, alpha, g.outlet_radius, g.height,
                                         sc.material.density * sc.loads.gravity, kappa=-1)
        away = (w["z"] > 6 * g.outlet_radius) & (w["z"] < 0.9 * g.height)
        assert np.all(np.abs(w["p_n"][away] / walker[away] - 1) < 0.20)
    assert summary["energy_balance_error_max"] < 0.01
    # penetration: every wall node on or off the wall, never beyond it by 1 % of h
    d = sc.outline.wall.project(np.column_stack([w["r"], w["z"]])).distance
    assert d.min() > -0.01 * g.element_size


# ------------------------------------------------------------------ the abrupt transition (ch. 7)
def transition_peak(comm, out, h):
    sc = load_scene(SCENES / "bin_hopper_ch7_abrupt.toml", [f"geometry.element_size={h}", "geometry.bin_height=1.0",
                                                             'discharge.mode="none"', 'fill.method="ramp"',
                                                             "fill.duration=1.0", "fill.damping=0.7",
                                                             "store.duration=0.3", "output.field_interval=100",
                                                             "output.stations=[0.3, 0.687, 1.0]"])
    run(sc, out, comm, progress_every=1e9)
    comm.barrier()
    w = read_profile(out / "wall_profile_store.csv")
    zc = sc.outline.transition_points[0][1]
    near = np.abs(w["z"] - zc) < 0.1
    return w["p_n"][np.argmin(np.abs(w["z"] - zc))], w["p_n"][near].max()


@pytest.mark.serial  # a mesh study (three meshes), a property of the discretisation, not the partition; this
# silo's fill runs on 2 ranks in test_janssen_on_the_vertical_wall_of_the_ch7_silo
def test_abrupt_transition_peak_is_finite_and_converges(shared_tmp, comm):
    """Cylinder on a 20° hopper (ch. 7 section, bin shortened to 1 m to keep it quick),
    abrupt corner, three meshes h = 0.035, 0.025, 0.0175 m: the pressure at the corner and
    the peak just below it change by less than 10 % between the two finest (measured 2.0 %
    and 0.9 %)."""
    res = [transition_peak(comm, shared_tmp / f"corner{k}", h) for k, h in enumerate((0.035, 0.025, 0.0175))]
    (c1, p1), (c2, p2), (c3, p3) = res
    assert all(np.isfinite([c1, c2, c3, p1, p2, p3]))
    assert abs(c3 - c2) / c3 < 0.10 and abs(p3 - p2) / p3 < 0.10


def test_nodes_slide_past_the_abrupt_corner(comm):
    """Free discharge of a short cylinder-on-hopper with a wide outlet: wall nodes starting
    just above the corner end below it, sliding, in contact, never beyond the wall."""
    sc = load_scene(SCENES / "bin_hopper_ch7_abrupt.toml", ["geometry.element_size=0.025", "geometry.bin_height=0.6",
                                                             "geometry.outlet_radius=0.25", 'fill.method="k0"',
                                                             "wall.mu=0.3", 'discharge.mode="free"',
                                                             "output.stations=[0.3]",
                                                             # the contact kinematics, not the solid:
                                                             # the weak literal cone flows at once
                                                             'material.cone="beta"'])
    m = SiloModel(sc, mesh_scene(sc, comm))
    s = m.solver
    m.activate(np.arange(s.n_cells_owned, dtype=np.int32), None, 0.0, 0.0, last=True)
    m.set_geostatic_stress(0.4)
    x = s.mesh.geometry.x
    zc = m.outline.transition_points[0][1]
    c = m.contact
    above = c.nodes[(x[c.nodes, 1] > zc + 1e-9) & (x[c.nodes, 1] < zc + 0.06)]
    m.open_outlet()
    c = m.contact
    worst = 0.0
    while s.t < 0.25:
        s.step()
        worst = min(worst, float(m.outline.wall.project(x[above]).distance.min(initial=0.0)))
    k = np.isin(c.nodes, above)
    n = comm.allreduce(int(above.size), op=MPI.SUM)
    passed = comm.allreduce(int(np.sum(x[above, 1] < zc)), op=MPI.SUM)
    assert n >= 1 and passed == n
    assert np.all(c.in_contact[k]) and np.all(c.slip_velocity[k] < -0.1)  # still sliding down
    assert comm.allreduce(worst, op=MPI.MIN) > -0.01 * 0.025  # penetration < 1 % of h



@pytest.mark.parametrize("scene, along", [("flat_bottom_ch6.toml", False), ("hopper_ch4.toml", True)])
def test_the_node_at_the_outlet_edge_is_held_to_the_walls_line(comm, scene, along):
    """The wall node at the outlet edge, dragged by the flow past the wall's end: on a flat
    bottom, pushed down and inwards, it keeps its floor (v_z = 0; the wall's friction may hold
    it, it never speeds it up); a hopper's wall ends at the edge, and its edge node leaves in
    the wall's direction untouched.
    With the wall ending at the edge it fell free as soon as it slid a round-off past it (the
    flow of ch. 6 switched between 0.9 and 2.5 kg/s at a moment set by round-off)."""
    sc = load_scene(SCENES / scene, ["geometry.element_size=0.1"])
    m = SiloModel(sc, mesh_scene(sc, comm))
    s = m.solver
    c = m.contact
    x = s.mesh.geometry.x
    r0 = m.outline.outlet_radius
    k = np.nonzero(np.hypot(x[c.nodes, 0] - r0, x[c.nodes, 1]) < 1e-9)[0]
    assert comm.allreduce(int(k.size), op=MPI.SUM) == 1
    first = c.wall.pieces[0]
    if along:  # a hopper's wall ends at the outlet edge
        assert np.allclose(first.start, (r0, 0.0))
    else:  # a floor continues past it, by a quarter of the outlet's shortest edge
        assert np.allclose(first.end, (r0, 0.0)) and 0.0 < first.length < 0.5 * r0
    past = np.subtract(first.start, first.end) / first.length
    v = np.zeros((s.n_nodes, 2))
    dt = 1e-3
    push = 0.5 * past if along else np.array([-0.05, -1.0])  # along the wall past its end / down through the floor
    v[c.dofs[k]] = push
    c.apply(x, v, s.mass, dt, dt)
    if k.size:
        vk = v[c.dofs[k]][0]
        if along:
            assert np.allclose(vk, push, atol=1e-12)
        else:
            assert abs(vk[1]) < 1e-12 and -0.05 - 1e-12 <= vk[0] <= 0.0
            assert c.in_contact[k][0]


def test_eq_7_1_discharge_slipping_nodes_carry_mu_of_their_slip_speed(shared_tmp, comm):
    """A coarse bin-hopper discharge with eq. 7-1 friction (the ch. 7 dynamic scene: μs 0.67,
    μk 0.3, but ϖ 20 s/m; bin shortened to 1 m, h 0.05, K0 start, 1 m/s controlled outlet ramped
    in 0.2 s; the cone matched in extension, with which the ch. 7 solid flows, docs/validation/ch7.md):
    at the end every wall node in contact that slides carries |p_s| = μ(|v_slip|)·p_n, with μ
    the law's value at its own slip speed (the contact solves μ(v) by fixed-point iteration:
    measured within 1e-12); the slip speeds spread enough that μ spans > 0.05 (measured 0.300 to
    0.658 over 0.06-0.54 m/s: the law, not a constant μ, is what is checked); sticking nodes stay
    within μs. Why ϖ 20: at the scene's 2 this short bin's wall sticks or creeps (≤ 0.03 m/s,
    μ 0.65-0.67), and a check over that span cannot tell the law from a constant. The 0.47 once
    measured there at ϖ 2 was the node beside the outlet's edge, dragged by that node's leak
    into the wall (fixed: effects.OutletDrive)."""
    out = shared_tmp / "eq71"
    sc = load_scene(SCENES / "bin_hopper_ch7_dynamic.toml", [
        "geometry.element_size=0.05", "geometry.bin_height=1.0", 'fill.method="k0"', 'material.cone="extension"',
        "discharge.ramp_time=0.2", "discharge.duration=0.6", "store.duration=0.2", "output.field_interval=100",
        "output.stations=[0.3, 0.687, 1.0]", "wall.decay=20.0"])
    summary = run(sc, out, comm, progress_every=1e9)
    comm.barrier()
    w = read_profile(out / "wall_profile_discharge.csv")
    v = np.abs(w["slip_velocity"])
    touching = (w["in_contact"] > 0) & (w["p_n"] > 0)
    slip = touching & (v > 1e-4)
    mu = theory.dynamic_friction(v[slip], 0.67, 0.3, 20.0)
    assert slip.sum() >= 10
    assert np.abs(np.abs(w["p_s"][slip]) / w["p_n"][slip] - mu).max() < 1e-6
    assert mu.max() - mu.min() > 0.05
    assert np.all(np.abs(w["p_s"][touching]) <= 0.67 * w["p_n"][touching] * (1 + 1e-9))
    assert summary["energy_balance_error_max"] < 0.01

# ------------------------------------------------------------------ Δt and ranks
def test_contact_does_not_shrink_the_time_step(comm):
    """Kinematic contact adds no stiffness: the stable Δt of the filled hopper equals that of
    the same hopper held by bilateral rollers (the thesis' penalty contact: 34 % at ×10)."""
    from silo_dolfinx.solver import VelocityConstraint

    sc = load_scene(SCENES / "hopper_ch4.toml", ["geometry.element_size=0.08", 'fill.method="k0"'])
    dts = []
    for contact in (True, False):
        m = SiloModel(sc, mesh_scene(sc, comm))
        s = m.solver
        if not contact:
            wall = m.sm.nodes_on("wall")
            n = m.outline.wall.project(s.mesh.geometry.x[wall]).normal
            s.contacts.clear()  # rollers: zero the radial component (the wall is straight)
            s.constraints.append(VelocityConstraint(s.node_dof[wall], 0))
            s.constraints.append(VelocityConstraint(m.outlet_dofs_all, 1))
            assert np.allclose(n, n[0]) if len(n) else True
        m.activate(np.arange(s.n_cells_owned, dtype=np.int32), None, 0.0, 0.0, last=True)
        m.set_geostatic_stress(0.4)
        # 0.15 s (~100-150 steps): the rollers' v_r = 0 on the inclined wall crushes the
        # outlet-corner cell until it inverts at 0.198 s, whatever the mesh's Δt
        while s.t < 0.15:
            s.step()
        dts.append(s.dt_crit)
    assert dts[0] >= 0.9 * dts[1]


def test_wall_profiles_are_the_same_on_1_and_2_ranks(shared_tmp, comm):
    sc = load_scene(SCENES / "hopper_ch4.toml", ["geometry.element_size=0.1", 'discharge.mode="none"',
                                                 "fill.layers=3", "fill.duration=0.6", "fill.damping=0.3",
                                                 "store.duration=0.2", "output.field_interval=100"])
    run(sc, shared_tmp / f"one{comm.rank}", MPI.COMM_SELF, progress_every=1e9)
    run(sc, shared_tmp / "all", comm, progress_every=1e9)
    comm.barrier()
    a = read_profile(shared_tmp / f"one{comm.rank}" / "wall_profile_store.csv")
    b = read_profile(shared_tmp / "all" / "wall_profile_store.csv")
    for k in ("s", "r", "z", "p_n", "p_s"):
        scale = np.abs(a[k]).max()
        assert np.allclose(a[k], b[k], rtol=1e-8, atol=1e-8 * scale), k


def test_wall_pressure_near_the_free_surface_is_exact_at_the_material_depth(shared_tmp, comm):
    """Elastic column (H 2.5 m, R 0.5 m, E 5 MPa, ν 0.3) between frictionless walls, ramp-filled
    and stored at rest: p_n = ν/(1 − ν) ρ g d at every wall node, to 1e-3 (measured 2e-5),
    from the base up to d = H/50 below the surface - provided the depth d is the material's
    (Lagrangian) depth H − Z. Measured against the current height z, p_n reads low near the top
    (3 % at a fifth of the height in the issue's report) because the fill has settled by
    u(Z) = (ρg/M)(H Z − Z²/2), 4.6 mm at the top here: the "error" is exactly δ(Z)/d. The base
    corner node (tributary area shared with the base) reads 2 % low; it is excluded."""
    H, R, h, E, nu, rho, g = 2.5, 0.5, 0.1, 5e6, 0.3, 1000.0, 9.81
    sc = load_scene({"geometry": {"shape": "column", "base_radius": R, "height": H, "element_size": h},
                     "material": {"model": "elastic", "density": rho, "youngs_modulus": E, "poisson_ratio": nu},
                     "wall": {"friction": "none"}, "fill": {"method": "ramp", "duration": 2.0, "damping": 0.5},
                     "store": {"duration": 2.0}, "output": {"field_interval": 0.0}})
    run(sc, shared_tmp / "column_at_rest", comm, progress_every=1e9)
    comm.barrier()
    w = read_csv(shared_tmp / "column_at_rest" / "wall_profile_store.csv")
    M, K = theory.constrained_modulus(E, nu), nu / (1 - nu)
    z, a = w["z"], rho * g / M
    Z = z.copy()
    for _ in range(30):  # invert z = Z − a (H Z − Z²/2) for the material height Z
        Z = z + a * (H * Z - Z ** 2 / 2)
    depth = H - Z
    inner = (Z > 0.5 * h) & (depth > H / 50)
    assert inner.sum() >= 20
    assert np.all(np.abs(w["p_n"][inner] / (K * rho * g * depth[inner]) - 1) < 1e-3)
    fifth = np.argmin(np.abs(depth - H / 5))
    settled = a * (H * Z[fifth] - Z[fifth] ** 2 / 2)
    current = w["p_n"][fifth] / (K * rho * g * (H - z[fifth]))
    assert abs(current - (1 - settled / (H - z[fifth]))) < 1e-3  # the current-height reading: low by δ/d
