"""The rezoning transfer (silo_dolfinx.ale.rezone): overlaps of quadrilaterals of revolution,
and the state carried from one mesh to another - conservative, bounded, exact where it must be.
Serial and on 2 ranks (the old state is gathered, the new cells are each rank's own)."""

import math

import numpy as np
import pytest
from mpi4py import MPI

from silo_dolfinx.ale import rezone as rz
from silo_dolfinx.geometry.cells import cell_corners, cycle_nodes

ROUND_OFF = 1e-12  # sums of ~10³ terms of O(1): 10⁻¹³ is the round-off; 10⁻¹² leaves room


def _rect_mesh(comm, n, m, jiggle, top=2.0):
    """A quadrilateral mesh of [0.1, 1.1] × [0, top] with its interior nodes moved by ``jiggle``
    of a cell (smoothly: the cells stay convex), ghosted as the silo mesher's."""
    from dolfinx import mesh as dm

    msh = dm.create_rectangle(comm, [[0.1, 0.0], [1.1, top]], [n, m], dm.CellType.quadrilateral,
                              ghost_mode=dm.GhostMode.shared_facet)
    x = msh.geometry.x
    inner = (x[:, 0] > 0.1 + 1e-9) & (x[:, 0] < 1.1 - 1e-9) & (x[:, 1] > 1e-9) & (x[:, 1] < top - 1e-9)
    dx, dy = jiggle * np.sin(7 * x[inner, 1]) / n, jiggle * np.cos(5 * x[inner, 0]) * top / m
    x[inner, 0] += dx
    x[inner, 1] += dy
    return msh


def _owned(msh):
    return msh.topology.index_map(2).size_local


def _old_state(comm, msh, rho_fn, q_fn, v_fn):
    """Gathered old state with cell values from functions of the cell centre and nodal
    velocities from a function of the node position."""
    n = _owned(msh)
    corners = cell_corners(msh)
    cen = corners.mean(axis=1)
    v = v_fn(msh.geometry.x[cycle_nodes(msh, n), :2])
    return rz.gather(comm, corners, rho_fn(cen), q_fn(cen), v)


def _totals(comm, vol, rho, q):
    m = comm.allreduce(float(np.sum(rho * vol)))
    return m, np.array([comm.allreduce(float(np.sum(rho * vol * q[:, j]))) for j in range(q.shape[1])])


RHO = lambda c: 1000.0 + 150.0 * c[:, 0] - 80.0 * c[:, 1]  # noqa: E731
Q = lambda c: np.column_stack([np.sin(3 * c[:, 1]), -c[:, 0] ** 2, np.ones(len(c))])  # noqa: E731


def test_overlap_moments_closed_form():
    """∫ r dA of the common region of two quadrilaterals against closed forms: two overlapping
    rectangles ((r1² − r0²)/2 × height), a square inside a diamond (the whole square), disjoint
    squares (0); either orientation of the input gives the same."""
    a, b = np.empty((16, 2)), np.empty((16, 2))

    def sq(r0, z0, r1, z1):
        return np.array([r0, r1, r1, r0], float), np.array([z0, z0, z1, z1], float)

    p, q = sq(0.2, 0.0, 1.0, 1.0), sq(0.5, 0.5, 1.5, 2.0)
    assert rz._clip_r_moment(*p, *q, a, b) == pytest.approx((1.0 ** 2 - 0.5 ** 2) / 2 * 0.5, rel=1e-14)
    diamond = (np.array([1.0, 2.0, 1.0, 0.0]), np.array([-1.0, 0.0, 1.0, 0.0]))
    inner = sq(0.6, -0.3, 1.3, 0.3)
    assert rz._clip_r_moment(*inner, *diamond, a, b) == pytest.approx((1.3 ** 2 - 0.6 ** 2) / 2 * 0.6, rel=1e-14)
    assert rz._clip_r_moment(*diamond, *inner, a, b) == pytest.approx((1.3 ** 2 - 0.6 ** 2) / 2 * 0.6, rel=1e-14)
    assert rz._clip_r_moment(*sq(0, 0, 1, 1), *sq(1.5, 0, 2, 1), a, b) == 0.0
    cw = np.array([[[0.2, 0.0], [0.2, 1.0], [1.0, 1.0], [1.0, 0.0]]])  # clockwise
    ccw, perm = rz.counter_clockwise(cw)
    assert rz._r_moment(ccw[0, :, 0], ccw[0, :, 1]) == pytest.approx((1.0 - 0.04) / 2, rel=1e-14)
    assert np.array_equal(ccw[0], cw[0][perm[0]])


def test_same_mesh_is_the_identity(comm):
    """Onto an identical mesh every cell overlaps only itself and every corner region only its
    own: densities, means and even a non-uniform velocity come back to round-off."""
    msh = _rect_mesh(comm, 6, 9, 0.2)
    vfn = lambda x: np.stack([np.sin(x[..., 1]), x[..., 0] * x[..., 1]], axis=-1)  # noqa: E731
    old = _old_state(comm, msh, RHO, Q, vfn)
    n = _owned(msh)
    tr = rz.Transfer(comm, old, cell_corners(msh))
    rho, q = tr.cells()
    cen = cell_corners(msh).mean(axis=1)
    assert np.allclose(rho, RHO(cen), rtol=ROUND_OFF, atol=0)
    assert np.allclose(q, Q(cen), rtol=0, atol=ROUND_OFF)
    m, p = tr.corner_velocities()
    v = rz.node_velocities(msh.geometry.index_map(), cycle_nodes(msh, n), m, p)
    assert np.allclose(v, vfn(msh.geometry.x[:, :2]), rtol=0, atol=ROUND_OFF)
    assert tr.uncovered_mass == 0.0


def test_conservative_and_bounded_between_different_meshes(comm):
    """7 × 11 → 9 × 13 cells, both distorted differently: every new cell is tiled by its overlaps
    and every old cell by its own (to round-off); mass and each ∫ ρ Q dV are conserved to
    round-off; each new Q lies within the old range; a uniform velocity is exact; a linear
    density comes over within its own variation across the overlapping cells."""
    old_mesh, new_mesh = _rect_mesh(comm, 7, 11, 0.2), _rect_mesh(comm, 9, 13, 0.25)
    vel = np.array([0.3, -0.7])
    old = _old_state(comm, old_mesh, RHO, Q, lambda x: np.broadcast_to(vel, x.shape).copy())
    n = _owned(new_mesh)
    tr = rz.Transfer(comm, old, cell_corners(new_mesh))
    assert np.allclose(np.bincount(tr.pair_new, weights=tr.w, minlength=n), tr.new_volumes, rtol=ROUND_OFF, atol=0)
    assert np.allclose(tr.covered, old.volumes, rtol=ROUND_OFF, atol=0)
    assert np.allclose(tr.wsub.sum(axis=(1, 2)), tr.w, rtol=ROUND_OFF, atol=0)
    rho, q = tr.cells()
    m0, mq0 = _totals(MPI.COMM_SELF, old.volumes, old.rho, old.means)
    m1, mq1 = _totals(comm, tr.new_volumes, rho, q)
    assert m1 == pytest.approx(m0, rel=ROUND_OFF)
    assert np.allclose(mq1, mq0, rtol=ROUND_OFF, atol=ROUND_OFF * m0)
    assert np.all(q >= old.means.min(axis=0) - ROUND_OFF) and np.all(q <= old.means.max(axis=0) + ROUND_OFF)
    assert np.allclose(q[:, 2], 1.0, rtol=0, atol=ROUND_OFF)  # a constant stays exactly constant
    # ρ = 1000 + 150 r − 80 z sampled at old centres: a new cell's mean lies within the field's
    # variation over the old cells it overlaps (|∇ρ| × (its diameter + two old diameters))
    cen = cell_corners(new_mesh).mean(axis=1)
    h_new, h_old = math.hypot(1 / 9, 2 / 13) * 1.5, math.hypot(1 / 7, 2 / 11) * 1.5
    assert np.abs(rho - RHO(cen)).max() <= math.hypot(150.0, 80.0) * (h_new + 2 * h_old)
    mm, p = tr.corner_velocities()
    v = rz.node_velocities(new_mesh.geometry.index_map(), cycle_nodes(new_mesh, n), mm, p)
    assert np.allclose(v, vel, rtol=0, atol=ROUND_OFF)


def test_a_smaller_new_domain_keeps_the_mass(comm):
    """The new mesh's top 0.03 m lower than the old one's (a re-sampled free surface): the old
    top row's uncovered slivers go to the new cells they overlap, so the mass is conserved
    and nothing is reported lost; with the new top a whole old row lower, that row's mass is
    reported lost exactly."""
    old_mesh = _rect_mesh(comm, 5, 10, 0.0)  # rows 0.2 m high
    old = _old_state(comm, old_mesh, RHO, Q, lambda x: np.zeros(x.shape))
    m0 = float(np.sum(old.rho * old.volumes))
    new_mesh = _rect_mesh(comm, 6, 9, 0.2, top=1.97)
    tr = rz.Transfer(comm, old, cell_corners(new_mesh))
    rho, _ = tr.cells()
    assert tr.uncovered_mass == 0.0
    assert comm.allreduce(float(np.sum(rho * tr.new_volumes))) == pytest.approx(m0, rel=ROUND_OFF)
    lower = _rect_mesh(comm, 6, 9, 0.2, top=1.8)
    tr = rz.Transfer(comm, old, cell_corners(lower))
    rho, _ = tr.cells()
    top_row = old.corners[:, :, 1].min(axis=1) >= 1.8 - 1e-12
    lost = float(np.sum((old.rho * old.volumes)[top_row]))
    assert top_row.sum() == 5 and tr.uncovered_mass == pytest.approx(lost, rel=ROUND_OFF)
    assert comm.allreduce(float(np.sum(rho * tr.new_volumes))) == pytest.approx(m0 - lost, rel=ROUND_OFF)



def test_a_node_over_no_old_material_takes_its_cells_velocity(comm):
    """The new top 0.3 m above the old one, in rows 0.575 m high: the corner regions of the
    new top nodes ([2.0125, 2.3] m) overlap no old material - as a wall corner in a gap the
    material opened, or a spline top above the old polyline (a 2-rank CI run met one) - while
    their cells do. Those nodes take the mass-weighted velocity of their cells: a uniform
    velocity stays exact everywhere; v_z = z comes over within the range of the old nodes the
    top cells overlap (1.6-2.0 m: the top row of new cells reaches down to 1.725 m)."""
    old_mesh = _rect_mesh(comm, 5, 10, 0.0)
    new_mesh = _rect_mesh(comm, 5, 4, 0.0, top=2.3)
    n = _owned(new_mesh)
    vel = np.array([0.3, -0.7])
    for vfn, check in ((lambda x: np.broadcast_to(vel, x.shape).copy(), "uniform"),
                       (lambda x: np.stack([np.zeros(x.shape[:-1]), x[..., 1]], axis=-1), "linear")):
        old = _old_state(comm, old_mesh, RHO, Q, vfn)
        tr = rz.Transfer(comm, old, cell_corners(new_mesh))
        mm, p = tr.corner_velocities()
        assert comm.allreduce(int(np.sum(mm.sum(axis=1) <= 0.0))) == 0  # every cell has some
        cn = cycle_nodes(new_mesh, n)
        v = rz.node_velocities(new_mesh.geometry.index_map(), cn, mm, p)
        top = new_mesh.geometry.x[:, 1] > 2.3 - 1e-9
        assert np.all(mm[top[cn]] == 0.0) and comm.allreduce(int(top[cn].sum())) > 0  # the case is there
        if check == "uniform":
            assert np.allclose(v, vel, rtol=0, atol=ROUND_OFF)
        else:
            assert np.all(np.isfinite(v)) and np.allclose(v[top, 0], 0.0, atol=ROUND_OFF)
            assert np.all((v[top, 1] >= 1.6) & (v[top, 1] <= 2.0))


# ---------------------------------------------------------------------------- the mesher and the run
def test_a_surface_outline_meshes_the_material_under_it(comm):
    """The ch. 4 hopper cut at a flat surface 1.3 m up given as a polyline of 7 points (a
    spline through collinear points is their line): the mesh holds exactly the hopper's volume
    below 1.3 m, its top facets lie on the surface and its wall facets on the wall."""
    from silo_dolfinx.ale.rezone import remesh
    from silo_dolfinx.scene import load_scene

    from conftest import SCENES

    sc = load_scene(SCENES / "hopper_ch4.toml", ["geometry.element_size=0.08"])
    r_wall = float(sc.outline.wall.radius_at(1.3)[0])
    surface = np.column_stack([np.linspace(0.0, r_wall, 7), np.full(7, 1.3)])
    sm = remesh(sc, surface, comm)
    assert sm.volume_of_revolution() == pytest.approx(sc.outline.volume(1.3), rel=1e-9)
    x = sm.mesh.geometry.x
    top, wall = sm.nodes_on("top"), sm.nodes_on("wall")
    assert comm.allreduce(top.size) > 0 and np.allclose(x[top, 1], 1.3, atol=1e-9)
    assert np.allclose(x[wall, 0], sc.outline.wall.radius_at(x[wall, 1]), atol=1e-9)


def test_a_rezoned_discharge_goes_on_where_its_mesh_ended(shared_tmp, comm):
    """The ch. 4 hopper at h 0.06 m (497 cells, two across the outlet radius), K0 start: without
    rezoning its discharge ends at 0.56 s, a cell at the outlet distorted below the quality floor
    (measured: 0.093 < 0.1). With ``ale.rezone_min_quality = 0.3`` it is meshed again when the
    worst cell passes 0.3 and runs the whole 1.2 s, and every rezone carries the state over as
    the transfer promises: the mass to round-off, nothing uncovered, the kinetic energy within
    10 % (first order on two cells across the outlet: measured 2.4 %), the tracers all accounted
    for, each where it was or (cut off by the new free surface) moved by under a cell; the run keeps the hard-case bounds (energy < 1 %, mass < 0.5 %, no cell below 0.1) and
    its outputs go on through it. (The first checkpoint after a rezone is not written, said so.)"""
    from silo_dolfinx.analysis import run_health
    from silo_dolfinx.output import read_csv
    from silo_dolfinx.scene import load_scene
    from silo_dolfinx.simulation import run

    from conftest import SCENES

    out = shared_tmp / "rezoned"
    sc = load_scene(SCENES / "hopper_ch4.toml", ["geometry.element_size=0.06", 'fill.method="k0"', "store.duration=0.3",
                                                  "discharge.duration=1.2", "ale.rezone_min_quality=0.3",
                                                  "output.checkpoint_interval=1e-6", "output.field_interval=0.25"])
    summary = run(sc, out, comm, progress_every=1e9)
    comm.barrier()
    h = run_health(out)
    assert h["status"] == "completed" and h["simulated_time"] == pytest.approx(1.5, rel=1e-9)
    assert h["energy_error_max"] < 0.01 and h["mass_error_max"] < 5e-3 and h["finite"]
    assert h["min_scaled_jacobian"] > 0.1
    stage = summary["stages"][-1]
    assert len(stage["rezones"]) >= 1
    for r in stage["rezones"]:
        assert r["mass_after"] == pytest.approx(r["mass_before"], rel=ROUND_OFF) and r["uncovered_mass"] == 0.0
        assert abs(r["kinetic_after"] / r["kinetic_before"] - 1.0) < 0.1
        assert r["tracer_shift"] < 0.06  # a tracer the new mesh cuts off moves under a cell (read off the old mesh)
    tr = stage["tracers"]
    assert tr["inside"] + tr["discharged"] == tr["seeded"]
    o = read_csv(out / "outlet.csv")
    assert np.all(np.diff(o["t"]) > 0) and o["t"][-1] == pytest.approx(1.5, rel=1e-3)
    assert any("checkpoints stopped at the first rezone" in w for w in summary["warnings"])


def test_the_rezone_waits_for_the_mesh_not_for_a_dilated_cell():
    """The trigger (rezone_dt_fall 0.2, rezone_min_quality 0.3) on a stand-in model: Δt 30 %
    down with the cell that sets it as long as the shortest cell at the reference - a cell
    dilated at the outlet, which no mesh cures - does not rezone; Δt and that cell's length
    both 30 % down does; Δt 10 % down does not; a worst cell below 0.3 does whatever Δt does;
    and nothing happens between remaps."""
    from types import SimpleNamespace

    from silo_dolfinx.ale.rezone import Rezoner

    cells = SimpleNamespace(L=np.array([0.01, 0.02]))
    limit = {"length": 0.01}
    solver = SimpleNamespace(dt_crit=1e-4, comm=MPI.COMM_SELF, q=SimpleNamespace(cells=cells),
                             limiting_cell=lambda refresh=True: limit)
    ale = SimpleNamespace(due=lambda: True)
    monitor = SimpleNamespace(min_quality=0.6)
    model = SimpleNamespace(scene=SimpleNamespace(ale=SimpleNamespace(rezone_dt_fall=0.2, rezone_min_quality=0.3)),
                            solver=solver, ale=ale, outputs=SimpleNamespace(monitor=monitor))
    rz_ = Rezoner(model)
    assert not rz_.due() and rz_.dt_ref == 1e-4 and rz_.length_ref == 0.01  # the reference, taken at the first remap
    solver.dt_crit = 0.7e-4
    assert not rz_.due()  # Δt down 30 %, its cell not shorter: density
    limit["length"] = 0.007
    assert rz_.due()
    solver.dt_crit = 0.9e-4
    assert not rz_.due()  # Δt down 10 % only
    monitor.min_quality = 0.25
    assert rz_.due()
    rz_.fresh_quality = 0.28  # the last fresh mesh was already below the trigger: no quality rezone
    assert not rz_.due()
    ale.due = lambda: False
    assert not rz_.due()


def test_a_controlled_discharge_rezoned_at_every_remap_keeps_its_drive(shared_tmp, comm):
    """The ch. 4 controlled case (u0/2 = 0.5 m/s by eq. 3-14 over 2 s) at h 0.06 m, made to
    rezone at its first remap (``rezone_min_quality = 0.9``: no mesh is that good) and then not
    again (the fresh mesh is no better: rezoning on would loop, as it did on a nearly empty
    hopper before this guard): the outlet stays driven from the opening time - the
    mean outlet velocity 0.25 s after opening is eq. 3-14's u0/2 (1 − cos(π t/T)) = 0.0190 m/s
    within 5 % (the outlet nodes carry the prescribed velocity exactly; the mean over the outlet
    is of the sampled step, Δt ≈ 5e-4 s of a ramp rising 8 %/step there) - and the balances
    hold (mass 1e-6, energy 1 %)."""
    import math

    from silo_dolfinx.output import read_csv
    from silo_dolfinx.scene import load_scene
    from silo_dolfinx.simulation import run

    from conftest import SCENES

    out = shared_tmp / "controlled"
    sc = load_scene(SCENES / "hopper_ch4_controlled_u0_2.toml", [
        "geometry.element_size=0.06", 'fill.method="k0"', "store.duration=0.3", "discharge.duration=0.3",
        "ale.rezone_min_quality=0.9", "output.field_interval=0"])
    summary = run(sc, out, comm, progress_every=1e9)
    comm.barrier()
    stage = summary["stages"][-1]
    t_open = stage["t_start"]
    assert summary["status"] == "completed" and len(stage["rezones"]) == 1 and stage["rezones"][0]["t"] < t_open + 0.01
    assert summary["energy_balance_error_max"] < 0.01 and stage["mass_balance_error_max"] < 1e-6
    o = read_csv(out / "outlet.csv")
    k = int(np.argmin(np.abs(o["t"] - (t_open + 0.25))))
    u = 0.25 * (1.0 - math.cos(math.pi * (o["t"][k] - t_open) / 2.0))
    assert o["mean_outlet_velocity"][k] == pytest.approx(u, rel=0.05)


def test_a_mesh_re_meshed_over_and_over_is_warned_about():
    """simulation._rezone_warnings on stand-in stages (ale.frequency 10): ten re-meshes, a median
    of 20 steps apart (two remaps), are warned about, naming the predictor when it is "current";
    ten 200 steps apart (the ch. 4 scene re-meshes 4-5 times in 60 s) or nine 20 apart are not."""
    from types import SimpleNamespace

    from silo_dolfinx.simulation import REZONE_WARNING, _rezone_warnings

    assert REZONE_WARNING == (10, 10)  # the thresholds this test brackets

    def scene(predictor):
        return SimpleNamespace(ale=SimpleNamespace(frequency=10, predictor=predictor))

    def stage(n, apart):
        return {"name": "discharge", "rezones": [{"step": 1000 + apart * k, "seconds": 0.1} for k in range(n)]}

    (w,) = _rezone_warnings(scene("current"), [stage(10, 20)])
    assert "10 times, every 20 steps" in w and 'set ale.predictor = "previous"' in w
    (w,) = _rezone_warnings(scene("previous"), [stage(10, 99)])  # (just under 10 remaps apart)
    assert "ale.frequency smaller" in w
    assert _rezone_warnings(scene("current"), [stage(10, 200), stage(9, 20), {"name": "fill"}]) == []


def test_a_mesh_that_follows_the_material_re_meshes_over_and_over_and_says_so(shared_tmp, comm):
    """The ch. 4 hopper at h 0.04 m from K0 with ale.predictor = "current" (the mesh follows the
    material) and the scene's rezone_min_quality 0.3: after its first re-mesh the outlet cells
    fall below 0.3 again within a few remaps, over and over (measured: 29 re-meshes in 0.4 s, 14×
    the default predictor's wall-clock over 2 s: docs/performance.md) - at least 5 re-meshes in
    0.3 s of discharge, the median 30 steps (3 remaps) apart or less - and the run's summary warns,
    naming the predictor, exactly when the warning's thresholds (10 re-meshes, a median of 10
    remaps apart) are reached; the default predictor's run of the same problem re-meshes not once.
    How many re-meshes is a realisation's: round-off alone (the same code compiled in another
    session, or a kernel refactored) gave 5, 15, 18 and 19 in 0.3 s (2026-12-07: in one the outlet
    cells stopped failing after the fifth), so the count is bounded below, not pinned."""
    from silo_dolfinx.scene import load_scene
    from silo_dolfinx.simulation import REZONE_WARNING, run

    from conftest import SCENES

    sets = ["geometry.element_size=0.04", 'fill.method="k0"', "store.duration=0.3", "discharge.duration=0.2",
            "output.field_interval=0", "output.points=[]"]
    current = sets + ['ale.predictor="current"', "discharge.duration=0.3"]
    summary = run(load_scene(SCENES / "hopper_ch4.toml", current), shared_tmp / "current", comm, progress_every=1e9)
    steps = [r["step"] for r in summary["stages"][-1]["rezones"]]
    assert summary["status"] == "completed" and len(steps) >= 5, steps
    apart = float(np.median(np.diff(steps)))
    assert apart <= 30, steps
    warned = any(w.startswith("[ale] the discharge stage was meshed again") and '"current"' in w
                 for w in summary["warnings"])
    n_min, remaps = REZONE_WARNING
    assert warned == (len(steps) >= n_min and apart < remaps * 10), (steps, summary["warnings"])  # ale.frequency 10
    summary = run(load_scene(SCENES / "hopper_ch4.toml", sets), shared_tmp / "previous", comm, progress_every=1e9)
    assert summary["stages"][-1].get("rezones", []) == [] and not any(w.startswith("[ale]") for w in summary["warnings"])
