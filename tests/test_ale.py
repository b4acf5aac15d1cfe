"""The ALE stages, each verified on its own (as Laghos/Remhos do), then together in a discharge.

Remap: a prescribed mesh motion on a rectangle in the (r, z) half-plane; cell means of a
smooth and of a discontinuous field are remapped and compared with their exact means on
the final mesh. Smoothing: boundary rules after a Lagrangian discharge. Discharge: mass
balance, energy balance and mesh quality, ALE against Lagrangian (the Fig. 3-18 analogue).
"""

import math

import numpy as np
import pytest
from conftest import SCENES, scene_dict
from mpi4py import MPI

from silo_dolfinx.geometry import hopper_half_angle
from silo_dolfinx.output import read_csv
from silo_dolfinx.scene import load_scene

# ---------------------------------------------------------------------------- remap alone


def _rectangle(comm, n, r0=0.2, with_outlet=False):
    from dolfinx import mesh as dmesh

    from silo_dolfinx.ale.remap import Remapper

    m = dmesh.create_rectangle(comm, [[r0, 0.0], [r0 + 1.0, 1.0]], [n, n], dmesh.CellType.quadrilateral,
                               ghost_mode=dmesh.GhostMode.shared_facet)
    outlet = None
    if with_outlet:
        m.topology.create_connectivity(1, 2)
        outlet = dmesh.locate_entities_boundary(m, 1, lambda x: np.isclose(x[1], 0.0))
    return m, outlet, Remapper


def _smooth(r, z):
    return 1.0 + 0.5 * np.sin(2 * np.pi * r) * np.cos(2 * np.pi * z)


def _disc(r, z):
    return np.where((r - 0.7) ** 2 + (z - 0.5) ** 2 < 0.3**2, 2.0, 1.0)


def _exact_means(x, cn_t, f, n=6):
    """r-weighted cell means of f by an n×n Gauss rule on the bilinear cells."""
    g, w = np.polynomial.legendre.leggauss(n)
    g, w = 0.5 * (g + 1), 0.5 * w
    xi, eta = np.meshgrid(g, g, indexing="ij")
    W = np.outer(w, w)
    N = np.stack([(1 - xi) * (1 - eta), xi * (1 - eta), (1 - xi) * eta, xi * eta])
    P = x[cn_t][:, :, :2]
    r = np.einsum("kab,ck->cab", N, P[:, :, 0])
    z = np.einsum("kab,ck->cab", N, P[:, :, 1])

    def d(k, j, c):
        return (P[:, k, c] - P[:, j, c])[:, None, None]

    drx = (1 - eta) * d(1, 0, 0) + eta * d(3, 2, 0)
    dzx = (1 - eta) * d(1, 0, 1) + eta * d(3, 2, 1)
    dre = (1 - xi) * d(2, 0, 0) + xi * d(3, 1, 0)
    dze = (1 - xi) * d(2, 0, 1) + xi * d(3, 1, 1)
    wt = W * r * np.abs(drx * dze - dre * dzx)
    return (f(r, z) * wt).sum(axis=(1, 2)) / wt.sum(axis=(1, 2))


def _remap_run(comm, n, order, f, amplitude=0.15):
    """Remap cell means through n steps of a smooth interior motion of total size `amplitude`."""
    m, _, Remapper = _rectangle(comm, n)
    R = Remapper(m, None, order)
    X = m.geometry.x.copy()
    r, z = X[:, 0], X[:, 1]
    bump = np.sin(np.pi * (r - 0.2)) * np.sin(np.pi * z)
    D = np.column_stack([amplitude * bump * np.cos(2 * z), amplitude * bump * np.sin(3 * r)])
    no = R.n_owned
    q = _exact_means(X, R.cn_tensor[:no], f)[:, None].copy()
    rho = np.ones(no)
    v = np.zeros((X.shape[0], 2))

    def totals(x):
        vol = R.volumes(x)[:no]
        return (comm.allreduce(float((rho * vol * q[:, 0]).sum())), comm.allreduce(float((rho * vol).sum())),
                vol)

    tot0, mass0, _ = totals(X)
    lo0, hi0 = comm.allreduce(q.min(), op=MPI.MIN), comm.allreduce(q.max(), op=MPI.MAX)
    xa = X.copy()
    for j in range(n):
        xb = X.copy()
        xb[:, :2] += D * (j + 1) / n
        R.remap(xa, xb, rho, q, v)
        xa = xb
    tot, mass, vol = totals(xa)
    ex = _exact_means(xa, R.cn_tensor[:no], f)
    err = comm.allreduce(float((np.abs(q[:, 0] - ex) * vol).sum())) / comm.allreduce(float(vol.sum()))
    return dict(err=err, conservation=abs(tot - tot0) / abs(tot0), mass=abs(mass - mass0) / mass0,
                overshoot=max(comm.allreduce(q.max(), op=MPI.MAX) - hi0, lo0 - comm.allreduce(q.min(), op=MPI.MIN)),
                rho_dev=comm.allreduce(float(np.abs(rho - 1.0).max()), op=MPI.MAX))


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("field", [_smooth, _disc], ids=["smooth", "discontinuous"])
def test_remap_conserves_and_creates_no_extrema(comm, order, field):
    """Totals to 1e-12 relative, no value outside the initial range (1e-12), and a uniform
    density stays uniform (the mass-weighted transport of an intensive variable). These are
    exact properties of the flux form and the FCT limiter: only round-off remains (measured
    1e-16 … 1e-14 over 32 remaps)."""
    d = _remap_run(comm, 32, order, field)
    assert d["conservation"] < 1e-12 and d["mass"] < 1e-12
    assert d["overshoot"] < 1e-12
    assert d["rho_dev"] < 1e-12


@pytest.mark.parametrize("order", [1, 2])
def test_remap_order_of_accuracy(comm, order):
    """Observed L1 order on smooth data, the motion refined with the mesh (one remap per cell
    width). Second order, h = 1/16 → 1/32 → 1/64: measured 2.41, 2.16; the issue's bound
    ≥ 1.8. Donor cell, h = 1/16 … 1/128: measured 0.89, 0.94, 0.97 (and 0.986 at 1/256),
    first order reached from below as the mesh is refined; asserted: the rate rises and the
    finest pair is within 5 % of 1."""
    sizes = (16, 32, 64, 128) if order == 1 else (16, 32, 64)
    errs = [_remap_run(comm, n, order, _smooth)["err"] for n in sizes]
    rates = [math.log2(errs[i] / errs[i + 1]) for i in range(len(sizes) - 1)]
    if order == 1:
        assert all(b > a for a, b in zip(rates, rates[1:])) and rates[-1] >= 0.95, (errs, rates)
    else:
        assert min(rates) >= 1.8, (errs, rates)


def test_remap_discontinuous_field_first_order_is_more_diffusive(comm):
    """On a step the limiter keeps both schemes bounded; the second-order one must still be
    the more accurate (measured L1 errors: donor cell 2.3x larger at h = 1/32)."""
    e1 = _remap_run(comm, 32, 1, _disc)["err"]
    e2 = _remap_run(comm, 32, 2, _disc)["err"]
    assert e2 < 0.8 * e1


@pytest.mark.parametrize("order", [1, 2])
def test_an_outlet_lets_mass_out_never_in_even_under_a_steep_density_gradient(comm, order):
    """An emptied row at the outlet (ρ 100 under 1000: the free-fall zone over an arch) and the
    outlet row reset after a Lagrangian step: the linear reconstruction of the second-order
    remap extrapolates a negative density onto the outlet face (100 − ½ h · 900/h), so its flux
    there points inwards. Before the fix the FCT limiter let it in - mass created from outside,
    uncounted, while the outflow counted only the outgoing faces (a coarse ch. 3 hopper gained
    1.06 kg/s, a mass-balance error of 0.74 % after 30 s). Now the outlet's mass flux is the
    donor cell's at both orders: the mass lost equals the outflow to round-off, and every
    outlet face lets mass out."""
    m, outlet, Remapper = _rectangle(comm, 8, r0=0.0, with_outlet=True)
    R = Remapper(m, outlet, order)
    X = m.geometry.x.copy()
    no = R.n_owned
    zc = X[R.cn_tensor[:no]][:, :, 1].mean(axis=1)
    rho = np.where(zc < 1.0 / 8, 100.0, 1000.0)
    q = np.zeros((no, 1))
    v = np.zeros((X.shape[0], 2))
    xa = X.copy()
    xa[np.isclose(X[:, 1], 0.0), 1] -= 0.02  # the outlet row moved down with the material
    mass0 = comm.allreduce(float((rho * R.volumes(xa)[:no]).sum()))
    rep = R.remap(xa, X, rho, q, v)
    out = comm.allreduce(rep.outflow_mass)
    mass1 = comm.allreduce(float((rho * R.volumes(X)[:no]).sum()))
    assert out > 0.0
    assert abs(mass0 - mass1 - out) < 1e-12 * mass0, (mass0 - mass1, out)
    assert comm.allreduce(float(rep.outflow_cells.min(initial=0.0)), op=MPI.MIN) >= 0.0
    assert comm.allreduce(float(rho.min()), op=MPI.MIN) > 0.0


@pytest.mark.parametrize("order", [1, 2])
def test_the_wall_edge_at_the_outlets_end_lets_out_what_it_swept_past_the_outlet_plane(comm, order):
    """A flat bottom whose outlet is its inner half, and the flow running down past the
    outlet's edge: the Lagrangian step moves the outlet's nodes - its edge node too - and the
    column of nodes above the edge down by 0.03 (a shear along the cell beside the outlet),
    and the smoothing puts them back. The floor edge beside the outlet swings below the floor
    and back, its top edge swings back up. Before the fix the floor edge carried nothing, so
    that cell kept what it had swept below the floor and took the same volume again from above:
    a uniform density rose by ½ h δ / h² = 12 % in that cell in one remap (in a ch. 6
    discharge ~1 % per remap, to 19× the density). Now a uniform density stays uniform to
    round-off, and the mass lost is the outflow."""
    n = 8
    m, _, Remapper = _rectangle(comm, n, r0=0.0)
    m.topology.create_connectivity(1, 2)
    from dolfinx import mesh as dmesh

    outlet = dmesh.locate_entities_boundary(m, 1, lambda x: np.isclose(x[1], 0.0) & (x[0] < 0.5 + 1e-9))
    R = Remapper(m, outlet, order)
    X = m.geometry.x.copy()
    no = R.n_owned
    rho = np.full(no, 1000.0)
    q = np.zeros((no, 1))
    v = np.zeros((X.shape[0], 2))
    xa = X.copy()
    moved = (np.isclose(X[:, 1], 0.0) & (X[:, 0] < 0.5 + 1e-9)) | (np.isclose(X[:, 0], 0.5) & (X[:, 1] < 0.5))
    xa[moved, 1] -= 0.03 * (1.0 - X[moved, 1] / 0.5)  # the shear dies out 4 cells up
    mass0 = comm.allreduce(float((rho * R.volumes(xa)[:no]).sum()))
    rep = R.remap(xa, X, rho, q, v)
    out = comm.allreduce(rep.outflow_mass)
    mass1 = comm.allreduce(float((rho * R.volumes(X)[:no]).sum()))
    # round-off: the densities are sums of a few fluxes of ρ·δV, each exact to ~1e-16 relative
    assert comm.allreduce(float(np.abs(rho - 1000.0).max()), op=MPI.MAX) < 1e-9
    assert abs(mass0 - mass1 - out) < 1e-12 * mass0, (mass0 - mass1, out)
    # the floor edge's sweep is in the outflow: more than the outlet faces' own (their strip
    # under the outlet, 2π ∫ r δ(r) dr over 0 ≤ r ≤ 0.5 with δ = 0.03 = 0.0236 m³ of ρ 1000)
    assert out > 1000.0 * 2.0 * np.pi * 0.03 * 0.5 ** 2 / 2 * 1.01


def test_velocity_remap_conserves_momentum_including_the_outflow(comm):
    """Nodal momentum before = after + what left through the outlet, to 1e-12 relative,
    with random densities and velocities and an outlet row that the motion resets (as the
    Eulerian outlet does)."""
    m, outlet, Remapper = _rectangle(comm, 24, r0=0.0, with_outlet=True)
    R = Remapper(m, outlet, 2)
    X = m.geometry.x.copy()
    nn, no = R.n_nodes_owned, R.n_owned
    rng = np.random.default_rng(comm.rank)
    rho = 1000.0 * (1.0 + 0.2 * rng.random(no))
    q = rng.random((no, 3))
    gi = m.geometry.index_map().local_to_global(np.arange(X.shape[0], dtype=np.int32))
    v = np.column_stack([np.sin(gi * 0.37), np.cos(gi * 0.11) - 0.5])  # same on every rank for ghosts
    r, z = X[:, 0], X[:, 1]
    b = np.sin(np.pi * r) * np.sin(np.pi * z)
    xb = X.copy()
    xb[:, 0] += 0.01 * b
    xb[:, 1] += 0.01 * b * np.cos(3 * r)
    xa = X.copy()
    xa[np.isclose(X[:, 1], 0.0), 1] -= 0.005  # the material moved below the outlet plane

    def momentum(x):
        M = R.nodal_mass(x, rho)
        return np.array(comm.allreduce((M[:nn, None] * v[:nn]).sum(axis=0)))

    P0 = momentum(xa)
    mass0 = comm.allreduce(float((rho * R.volumes(xa)[:no]).sum()))
    rep = R.remap(xa, xb, rho, q, v)
    out_m = comm.allreduce(rep.outflow_mass)
    out_p = np.array(comm.allreduce(np.array(rep.outflow_momentum)))
    mass1 = comm.allreduce(float((rho * R.volumes(xb)[:no]).sum()))
    assert out_m > 0.0  # something did leave
    assert abs(mass0 - mass1 - out_m) < 1e-12 * mass0
    assert np.abs(P0 - momentum(xb) - out_p).max() < 1e-12 * np.abs(P0).max()
    # a uniform velocity is reproduced exactly (to round-off)
    v[:] = [0.3, -1.2]
    R.remap(xb, X, rho, q, v)
    assert np.abs(v - [0.3, -1.2]).max() < 1e-12


def test_zero_motion_is_the_identity(comm):
    m, _, Remapper = _rectangle(comm, 12)
    R = Remapper(m, None, 2)
    X = m.geometry.x.copy()
    no = R.n_owned
    rng = np.random.default_rng(7 + comm.rank)
    rho = 1.0 + rng.random(no)
    q = rng.random((no, 2))
    v = np.tile([0.1, -0.2], (X.shape[0], 1))
    rho0, q0 = rho.copy(), q.copy()
    rep = R.remap(X, X, rho, q, v)
    # the swept volumes of a null motion are round-off (shoelace of equal points: ~1e-16), and so
    # are the fluxes; relative to a random field's jumps that is at most ~4e-13 (measured)
    assert rep.courant < 1e-14
    assert np.allclose(rho, rho0, rtol=1e-12, atol=0) and np.allclose(q, q0, rtol=1e-12, atol=0)
    assert np.allclose(v, [0.1, -0.2], rtol=1e-12, atol=0)


def test_a_motion_too_large_to_sub_cycle_is_refused_untouched(comm):
    """The remap sub-cycles a motion at Courant 0.5; one that sweeps a cell's volume more than
    MAX_SUBSTEPS × 0.5 times over (here a shear of 40 cells' widths) is refused with its size -
    never sub-cycled for minutes (the hang the hard-case issue found) - and the state is left as
    it was; the ALE stage turns it into an InstabilityError naming ale.frequency. A shear of one
    cell width remaps (it needs 2-3 sub-steps)."""
    from silo_dolfinx.ale.remap import COURANT, MAX_SUBSTEPS, SweptTooFar

    m, _, Remapper = _rectangle(comm, 12)
    R = Remapper(m, None, 2)
    X = m.geometry.x.copy()
    no = R.n_owned
    rho, q, v = np.ones(no), np.ones((no, 1)), np.zeros((X.shape[0], 2))
    inner = (X[:, 0] > 0.2 + 1e-9) & (X[:, 0] < 1.2 - 1e-9) & (X[:, 1] > 1e-9) & (X[:, 1] < 1 - 1e-9)
    for widths, refused in ((40.0, True), (1.0, False)):
        xb = X.copy()
        xb[inner, 1] += widths / 12 * np.sin(np.pi * X[inner, 1]) * np.sin(np.pi * (X[inner, 0] - 0.2))
        if refused:
            with pytest.raises(SweptTooFar, match=f"more than {MAX_SUBSTEPS} sub-steps"):
                R.remap(X, xb, rho, q, v)
            assert np.all(rho == 1.0) and np.all(q == 1.0)
        else:
            rep = R.remap(X, xb, rho, q, v)
            # a shear of one cell width sweeps 0.5-1 cell volumes: 2 sub-steps at Courant 0.5
            # (measured 2; 1 would mean the sub-cycling was bypassed, more a wrong Courant number)
            assert rep.substeps == math.ceil(rep.courant / COURANT) == 2


# ---------------------------------------------------------------------------- smoothing alone

def _smoothed_hopper(comm, predictor: str = "previous"):
    """The ch. 3 hopper after a Lagrangian motion (material sagging towards the outlet, the
    same function of position on every rank), smoothed once: (sm, wall, X, xL, xs, smoother)."""
    from silo_dolfinx.ale import Smoother
    from silo_dolfinx.simulation import SiloModel, mesh_scene

    sc = _ch3_scene(True, 0.1, h=0.08)
    sm = mesh_scene(sc, comm)
    wall = SiloModel(sc, sm).contact_wall_open
    smoother = Smoother(sm, wall, predictor=predictor)
    X = np.ascontiguousarray(sm.mesh.geometry.x[:, :2])
    r, z = X[:, 0], X[:, 1]
    # a few steps' worth (the top drops by a fraction of its row of cells): faster on the axis
    # as in mass flow, and slightly inwards, so that the wall nodes leave their wall positions
    xL = X.copy()
    xL[:, 1] -= 0.004 * (1.0 + z) * (1.0 - 0.5 * (r / wall.radius_at(z)) ** 2)
    xL[:, 0] *= 1.0 - 0.002 * z / z.max()
    on_wall = np.abs(wall.project(X).distance) < 1e-9
    xL[on_wall] = wall.project(xL[on_wall]).closest  # in contact
    return sm, wall, X, xL, smoother.smooth(xL), smoother


@pytest.mark.parametrize("predictor", ["previous", "stretched"])
def test_smoothing_boundary_rules_and_rank_independence(comm, predictor):
    """One smoothing of a sagged hopper: outlet nodes back at their start, axis nodes at
    r = 0, wall nodes on the wall (in contact: distance 0 to round-off), no cell below the
    smoother's quality floor; and on 2 ranks every local node (owned and ghost) where the
    serial smoothing puts it. Ghost rows enter the owned nodes' averages, so a ghost placed
    differently from its owner shows up as an O(motion) = 1e-3 m difference; the tolerance
    1e-12 m is the round-off of the sums taken in another order."""
    sm, wall, X, xL, xs, smoother = _smoothed_hopper(comm, predictor)
    outlet = sm.nodes_on("outlet")
    axis = np.setdiff1d(sm.nodes_on("axis"), outlet)
    on_wall = np.setdiff1d(sm.nodes_on("wall"), np.concatenate([outlet, sm.nodes_on("top")]))
    assert np.array_equal(xs[outlet], X[outlet])
    assert np.all(xs[axis, 0] == 0.0)
    assert np.abs(wall.project(xs[on_wall]).distance).max() < 1e-12
    assert smoother.min_scaled_jacobian(xs) >= 0.05
    assert comm.allreduce(float(np.abs(xs - xL).max()), op=MPI.MAX) > 1e-3  # it did smooth
    if comm.size > 1:
        _, _, X1, _, xs1, _ = _smoothed_hopper(MPI.COMM_SELF, predictor)
        key = {tuple(np.round(p, 9)): i for i, p in enumerate(X1)}
        serial = xs1[[key[tuple(np.round(p, 9))] for p in X]]
        assert np.abs(xs - serial).max() < 1e-12


def _drained(X, wall, H, drop, crater=0.0):
    """Node positions after the fill has drained by ``drop`` × its height in a converging flow:
    every point falls in proportion to its height, ``1 + crater`` times as far on the axis as
    at the wall, and its radius shrinks with the wall's (so the solid stays inside the cone)."""
    r, z = X[:, 0], X[:, 1]
    R0 = wall.radius_at(np.maximum(z, 1e-9))
    x = X.copy()
    x[:, 1] = z - drop * z * (1.0 + crater * (1.0 - (r / R0) ** 2))
    x[:, 0] = r * wall.radius_at(np.maximum(x[:, 1], 1e-9)) / R0
    return x


def _hopper_to_drain(comm):
    """The ch. 3 hopper (h 0.08 m) for :func:`_drained`: (sm, its open wall, the node positions,
    the fill height, the nodes on the wall)."""
    from silo_dolfinx.simulation import SiloModel, mesh_scene

    sc = _ch3_scene(True, 0.1, h=0.08)
    sm = mesh_scene(sc, comm)
    wall = SiloModel(sc, sm).contact_wall_open
    X = np.ascontiguousarray(sm.mesh.geometry.x[:, :2]).copy()
    H = comm.allreduce(float(X[:, 1].max()), op=MPI.MAX)
    return sm, wall, X, H, np.abs(wall.project(X).distance) < 1e-9


def test_stretched_predictor_follows_a_draining_surface(comm):
    """The ``stretched`` predictor keeps every interior and axis node at its fraction of the
    height under the free surface, its radius scaled with the wall's. (1) A homogeneous drain
    of the ch. 3 cone (every point at 0.95 of its height, radius with the wall) is that map
    exactly: the pure predictor (no smoothing weights) lands every node on the Lagrangian
    position to round-off (1e-12 m) - and so do the boundary rules, for the whole mesh -
    where ``previous`` leaves the interior where it was (O(drop × H) = 0.13 m away). (2) Forty drains of 0.4 % through a crater (the axis falling
    1.5 times as fast as the wall, the fill 15 % lower at the end): with ``stretched`` the
    mesh stays good (min scaled Jacobian 0.63 measured; bar 0.5), while with ``previous`` the
    top rows are crushed down to the smoother's floor (0.043 measured; bar < 0.1) - the
    failure the top cells of the long ch. 6 and ch. 7 discharges met."""
    from silo_dolfinx.ale import Smoother

    sm, wall, X, H, on_wall = _hopper_to_drain(comm)
    inner = np.setdiff1d(np.arange(X.shape[0]), np.concatenate([sm.nodes_on(b) for b in ("wall", "top", "outlet")]))

    xL = _drained(X, wall, H, 0.05)
    exact = Smoother(sm, wall, predictor="stretched", laplacian_weight=0.0, mid_area_weight=0.0).smooth(xL)
    still = Smoother(sm, wall, predictor="previous", laplacian_weight=0.0, mid_area_weight=0.0).smooth(xL)
    assert comm.allreduce(float(np.abs(exact - xL).max(initial=0.0)), op=MPI.MAX) < 1e-12
    assert comm.allreduce(float(np.abs(still[inner] - xL[inner]).max(initial=0.0)), op=MPI.MAX) > 0.05

    worst = {}
    for predictor in ("previous", "stretched"):
        smoother = Smoother(sm, wall, predictor=predictor)
        x, q = X.copy(), 1.0
        for _ in range(40):
            xL = _drained(x, wall, H, 0.004, crater=0.5)
            xL[on_wall] = wall.project(xL[on_wall]).closest  # in contact
            x = smoother.smooth(xL)
            q = min(q, smoother.min_scaled_jacobian(x))
        worst[predictor] = q
    assert worst["stretched"] > 0.5, worst
    assert worst["previous"] < 0.1, worst


def _volume_under(r, z):
    """Volume of revolution under a polyline (r ascending): 2π ∫ z r dr, exact."""
    a, b, za, zb = r[:-1], r[1:], z[:-1], z[1:]
    return 2.0 * np.pi * float(np.sum((b - a) * (za * (2.0 * a + b) + zb * (a + 2.0 * b)) / 6.0))


def test_surface_slump_keeps_the_volume_and_brings_the_slope_down():
    """The slump's surface (ale/slump.py) on a 0.35-m surface of 14 segments with a pit on the
    axis (0.10 m deep) and a lip at the wall (0.06 m high): every smoothing keeps the volume
    under the surface to round-off (1e-14 relative: the moves are weighted by the exact
    tributaries), moves no node by more than its cap, and repeated smoothings bring every
    segment to the limit slope (tan 35°, to 1e-9); a surface already gentler is left alone
    (every move exactly 0); an immovable end node leaves its segment steep."""
    from silo_dolfinx.ale import slump

    r = np.linspace(0.0, 0.35, 15)
    z = 1.0 + 0.02 * r
    z[0] -= 0.10
    z[-1] += 0.06
    tan = math.tan(math.radians(35.0))
    movable = np.ones(r.size, np.bool_)
    dz = np.zeros(r.size)
    cap = slump.CAP * np.diff(r).min()
    v0 = _volume_under(r, z)
    for _ in range(400):
        excess = slump.slump_heights(r, z, movable, tan, dz)
        assert np.abs(dz).max() <= cap * (1 + 1e-12)
        z = z + dz
        assert abs(_volume_under(r, z) - v0) <= 1e-14 * v0
        if excess <= 1e-9:
            break
    assert np.max(np.abs(np.diff(z)) / np.diff(r)) <= tan + 1e-9
    gentle = 1.0 + 0.5 * tan * r  # half the limit slope
    assert slump.slump_heights(r, gentle, movable, tan, dz) == 0.0 and not np.any(dz)

    z = 1.0 + 0.02 * r
    z[-1] += 0.06
    movable[-1] = False
    slump.slump_heights(r, z, movable, tan, dz)
    assert dz[-1] == 0.0 and dz[-2] == 0.0  # the segment at the fixed node is not touched


def test_placed_surface_keeps_the_volume_under_a_kinked_surface():
    """The top rule's height correction (ale/smoothing.py, ``keep_volume``): nodes slid by up to
    2 % of the arclength along a kinked surface (a V-shaped crater with a ripple) enclose
    7.6e-5 m³/rad more than the material (measured; bar > 1e-5: the error the correction is for);
    corrected, the volume under them is the material's to round-off (1e-14 relative), by moves
    smaller than the slide (3 mm against 2 cm); nodes at the surface's own vertices and nodes
    slid along a straight surface are returned unchanged (1e-14 m); an overhang is refused."""
    from silo_dolfinx.ale.smoothing import _arclength, keep_volume

    r = np.linspace(0.0, 1.0, 21)
    z = 2.0 + 0.4 * np.abs(r - 0.31) + 0.05 * np.sin(9.0 * r)
    pts = np.column_stack([r, z])
    sp = _arclength(pts)
    lam = sp / sp[-1]
    st = np.clip(lam + 0.02 * np.sin(np.pi * lam), 0.0, 1.0) * sp[-1]  # slid along the surface
    rq, zq = np.interp(st, sp, r), np.interp(st, sp, z)
    v0 = _volume_under(r, z) / (2.0 * np.pi)
    assert _volume_under(rq, zq) / (2.0 * np.pi) - v0 > 1e-5
    zc = zq.copy()
    assert keep_volume(pts, rq, zc)
    assert abs(_volume_under(rq, zc) / (2.0 * np.pi) - v0) <= 1e-14 * v0
    assert 0.0 < np.abs(zc - zq).max() < 0.005 and zc[0] == zq[0] and zc[-1] == zq[-1]
    same = z.copy()
    keep_volume(pts, r.copy(), same)
    assert np.abs(same - z).max() < 1e-14
    line = np.column_stack([r, 2.0 + 0.1 * r])
    zl = np.interp(st, sp, line[:, 1])
    placed = zl.copy()
    keep_volume(line, rq, placed)
    assert np.abs(placed - zl).max() < 1e-14
    over = pts.copy()
    over[5, 0] = over[3, 0]  # r goes back: not a graph over r
    untouched = zq.copy()
    assert not keep_volume(over, rq, untouched) and np.array_equal(untouched, zq)


def test_smoothing_keeps_the_volume_under_a_cratering_surface(comm):
    """Forty drains of the ch. 3 hopper through a crater (the axis falling 1.5 times as fast as
    the wall), each smoothed: the volume of revolution under the placed top nodes is the
    material's, under the Lagrangian ones, to round-off (1e-12 relative), on 1 and 2 ranks, with
    either predictor - at every smoothing that kept its targets. A smoothing that backs off
    towards the Lagrangian mesh (the quality floor's safety net: with ``previous`` this drain
    crushes the top rows, and from the 17th drain on every smoothing backs off; measured) blends
    the two surfaces node by node and keeps the volume only to ~1e-7 relative; ``stretched`` never
    backs off here. (Before the correction the crater gained volume at every smoothing; the remap
    kept the top cells' mass, and the ch. 4 discharge's top row ended at 31 % of the solid's
    density: it never backed off.)"""
    from silo_dolfinx.ale import Smoother

    sm, wall, X, H, on_wall = _hopper_to_drain(comm)
    kept = {}
    for predictor in ("previous", "stretched"):
        smoother = Smoother(sm, wall, predictor=predictor)
        x, kept[predictor] = X.copy(), 0
        for _ in range(40):
            xL = _drained(x, wall, H, 0.004, crater=0.5)
            xL[on_wall] = wall.project(xL[on_wall]).closest
            material = smoother._top_polyline(xL).copy()
            backoffs = smoother.backoffs
            x = smoother.smooth(xL)
            placed = smoother._top_polyline(x)
            if smoother.backoffs == backoffs:
                v = _volume_under(material[:, 0], material[:, 1])
                assert abs(_volume_under(placed[:, 0], placed[:, 1]) - v) <= 1e-12 * v
                kept[predictor] += 1
    assert kept["stretched"] == 40 and kept["previous"] >= 10, kept


def test_top_row_transfer_moves_the_slumped_material_conservatively():
    """The top row's material (ale/slump.py): the volumes a slump's vertical moves sweep are the
    columns 2π ∫ dz r dr (1e-12); after a remap that kept each top cell's mass while the
    slump changed its volume by δV, the 1-D transfer along the row conserves mass exactly (the
    fluxes telescope: 1e-15 relative), gives a row of uniform density exactly that density again
    (m' = ρ (V + δV): 1e-12), and mixes an intensive variable convexly (the new means within the
    old range)."""
    from silo_dolfinx.ale import slump

    r = np.linspace(0.0, 0.35, 8)
    z = 1.0 + 0.05 * np.sin(9.0 * r)
    z[0] -= 0.04
    dz = np.zeros(r.size)
    slump.slump_heights(r, z, np.ones(r.size, np.bool_), math.tan(math.radians(30.0)), dz)
    dV = np.empty(r.size - 1)
    slump.swept_volumes(np.column_stack([r, z]), np.column_stack([r, z + dz]), dV)
    columns = [2.0 * np.pi * np.dot(slump._segment_weights(r[e], r[e + 1]), dz[e:e + 2]) for e in range(r.size - 1)]
    assert np.allclose(dV, columns, rtol=1e-12, atol=1e-15)  # vertical moves: the columns 2π ∫ dz r dr
    assert np.any(dV != 0.0) and abs(dV.sum()) <= 1e-15 * _volume_under(r, z)  # the volume kept, to its round-off
    V0 = 2.0 * np.pi * 0.05 * (r[1:] ** 2 - r[:-1] ** 2) / 2.0 + 1e-4  # cells 5 cm deep
    rho = 1500.0
    mass = rho * V0  # kept by the remap ...
    V = V0 + dV  # ... while the slump changed the volumes
    rng = np.random.default_rng(3)
    Q = rng.uniform(-2.0, 5.0, (r.size - 1, 2))
    dm, dQ = np.zeros(r.size - 1), np.zeros((r.size - 1, 2))
    slump.top_row_transfer(dV, V, mass, Q, dm, dQ)
    assert abs(dm.sum()) <= 1e-15 * mass.sum()
    assert np.allclose((mass + dm) / V, rho, rtol=1e-12, atol=0.0)
    Qn = (mass[:, None] * Q + dQ) / (mass + dm)[:, None]
    assert np.all(Qn >= Q.min(axis=0) - 1e-12) and np.all(Qn <= Q.max(axis=0) + 1e-12)


def test_a_poor_cell_backs_off_only_its_own_nodes(comm):
    """A smoothing that would invert a cell near the top of the wall (an interior node of the
    smoothed sagged hopper thrown across its neighbours, as a cell hung up on a rough wall) is
    scaled back towards the Lagrangian mesh at the nodes of the offending cells only: the outlet
    nodes keep their Eulerian places (with one global θ they followed the material out of the
    silo, and the ch. 7 discharges stopped within seconds), the cell is valid again, and every
    other node away from it keeps its smoothed position."""
    sm, wall, X, xL, xs, smoother = _smoothed_hopper(comm)
    from silo_dolfinx.ale.smoothing import INTERIOR, MIN_SCALED_JACOBIAN

    interior = np.nonzero(smoother.cls == INTERIOR)[0]
    zmax = comm.allreduce(float(X[:, 1].max()), op=MPI.MAX)
    # the interior node nearest the top of the wall (the same node on every rank that holds it)
    key = X[interior, 1] + X[interior, 0]
    best = comm.allreduce(float(key.max(initial=-1.0)), op=MPI.MAX)
    k = interior[np.abs(key - best) < 1e-9]
    x = xs.copy()
    x[k] += np.array([0.3, 0.3]) * (zmax / 8)  # thrown far past its neighbours: inverts its cells
    assert smoother.min_scaled_jacobian(x) < 0
    b0 = smoother.backoffs
    out = smoother._back_off(x, xL, MIN_SCALED_JACOBIAN)
    assert smoother.backoffs > b0
    outlet = sm.nodes_on("outlet")
    assert np.array_equal(out[outlet], X[outlet])
    assert smoother.min_scaled_jacobian(out) >= MIN_SCALED_JACOBIAN
    pk = np.array([comm.allreduce(float(X[k[0], j]) if k.size else -np.inf, op=MPI.MAX) for j in (0, 1)])
    far = np.linalg.norm(X - pk, axis=1) > 3 * 0.08  # beyond two cells (h 0.08) of the thrown node
    moved = comm.allreduce(int(np.sum(np.any(out[far] != x[far], axis=1))), op=MPI.SUM)
    assert moved == 0  # two cells from it, nothing was scaled back


# ---------------------------------------------------------------------------- in a discharge

def _ch3_scene(ale: bool, duration: float, h: float = 0.05):
    """The ch. 3 hopper (Fig. 3-17) with a K0 initial state: the discharge alone."""
    return load_scene(SCENES / "hopper_ch3_ale.toml",
                      [f"ale.enabled={'true' if ale else 'false'}", 'fill.method="k0"', "store.duration=0.0",
                       f"discharge.duration={duration}", f"geometry.element_size={h}",
                       "output.history_rate=50.0", "output.field_interval=100.0"])


@pytest.fixture(scope="module")
def ale_run(tmp_path_factory):
    from silo_dolfinx.simulation import run

    comm = MPI.COMM_WORLD
    out = tmp_path_factory.mktemp("ale") if comm.rank == 0 else None
    from pathlib import Path

    out = Path(comm.bcast(str(out), root=0)) / "run"
    summary = run(_ch3_scene(True, 1.5), out, comm, progress_every=1e9)
    return out, summary


def test_discharge_mass_balance_and_energy(ale_run):
    """Initial mass = mass in the silo + discharged mass to 0.5 % (the issue's bound; the
    remap is conservative, so the measured error is round-off, ~1e-9); energy balance with
    the remap and outflow terms booked < 1 % (measured 0.2 %)."""
    out, summary = ale_run
    d = summary["stages"][-1]
    assert summary["status"] == "completed"
    assert d["mass_balance_error_max"] < 0.005
    o = read_csv(out / "outlet.csv")
    assert o["discharged_mass"][-1] > 0.01 * d["mass_at_opening"]  # it does flow (measured 1.2 % in 1.5 s)
    assert np.all(np.diff(o["discharged_mass"]) >= -1e-9 * d["mass_at_opening"])
    e = read_csv(out / "energy.csv")
    assert np.nanmax(e["relative_error"]) < 0.01


def test_the_monitor_weighs_the_fill(ale_run):
    """The discharge monitor's mass at the opening is ρ times the volume of the hopper's
    frustum, π H/3 (R² + R r + r²): a K0 start takes no step before the opening, and the 2×2
    Gauss volumes of revolution of straight-sided cells are exact (2π r |det J| is of degree 2
    in each reference coordinate), so only round-off separates them (measured 4e-16; bound
    1e-12). Every sample then accounts for it: mass in the silo + what the remap let out (the
    remap conserves to round-off; the Lagrangian density update ρ exp(−ε̇_v Δt) follows the
    cells' volumes to second order in Δt: measured 2.1e-10 of it over 1.5 s; bound 1e-8)."""
    out, summary = ale_run
    scene = _ch3_scene(True, 1.5)
    g, rho = scene.geometry, scene.material.density
    H, R, r = g.height, g.top_radius, g.outlet_radius
    m0 = summary["stages"][-1]["mass_at_opening"]
    assert m0 == pytest.approx(rho * math.pi * H / 3.0 * (R * R + R * r + r * r), rel=1e-12)
    o = read_csv(out / "outlet.csv")
    assert np.max(np.abs(o["mass_in_silo"] + o["discharged_mass"] - m0)) < 1e-8 * m0


def test_discharge_keeps_every_cell_valid_and_the_boundary_rules(ale_run):
    """No inverted cell (scaled Jacobian > 0 throughout) and the aspect ratio within 1.5x its
    initial value (the issue's bound for ALE)."""
    out, summary = ale_run
    q = read_csv(out / "mesh_quality.csv")
    assert q["min_scaled_jacobian"].min() > 0.0
    assert q["max_aspect_ratio"].max() < 1.5 * q["max_aspect_ratio"][0]
    assert q["top_drop"][-1] > 0.0  # the free surface came down


def test_lagrangian_mesh_degrades_where_ale_does_not(ale_run, shared_tmp, comm):
    """Fig. 3-18 analogue: over the same discharge the Lagrangian critical-element aspect ratio
    grows well past the ALE one (thesis: 7 at a 25 mm drop, ALE ~constant). The Lagrangian
    discharge ends within a few hundredths of a second on discharge.min_mesh_quality (its aspect
    ratio several times the initial one; without the floor a cell turns inside out at 0.33 s and
    the step stops on it): the comparison is over the time both runs cover."""
    from silo_dolfinx.simulation import run

    out_ale, _ = ale_run
    out = shared_tmp / "lag"
    try:
        run(_ch3_scene(False, 0.3), out, comm, progress_every=1e9)
    except Exception:  # the Lagrangian run may die of its distortion: that is the point
        pass
    comm.barrier()
    lag = read_csv(out / "mesh_quality.csv")
    ale = read_csv(out_ale / "mesh_quality.csv")
    t = min(lag["t"][-1], ale["t"][-1])
    a_lag = lag["max_aspect_ratio"][lag["t"] <= t].max() / lag["max_aspect_ratio"][0]
    a_ale = ale["max_aspect_ratio"][ale["t"] <= t].max() / ale["max_aspect_ratio"][0]
    assert a_lag > 2.0 and a_ale < 1.5, (a_lag, a_ale)


def test_tracers_follow_the_flow(ale_run):
    """Every seeded tracer is either inside the silo or recorded as discharged; none rises by
    more than a cell size (the flow is downward everywhere); none leaves the half-plane; the
    discharged ones come from below the mean seeding height (the outlet drains the bottom)."""
    out, summary = ale_run
    tr = read_csv(out / "tracers.csv")
    info = summary["stages"][-1]["tracers"]
    assert info["seeded"] == tr["id"].size == 10 * 12  # the scene's default 10 rows x 12
    # identity survives a hop between ranks: every id once, with its own seeding row
    assert np.unique(tr["id"]).size == tr["id"].size
    assert np.array_equal(tr["row"], tr["id"] // 12)
    assert info["inside"] + info["discharged"] == info["seeded"]
    inside = np.isnan(tr["discharged_at"])
    assert np.all(tr["z"][inside] <= tr["z0"][inside] + 0.05)
    assert np.all(tr["r"][inside] >= -1e-12)
    assert np.any(tr["z"][inside] < tr["z0"][inside] - 0.02)  # they do move
    if info["discharged"]:
        assert tr["z0"][~inside].mean() < tr["z0"].mean()


def test_controlled_discharge_follows_eq_3_14(shared_tmp, comm):
    """Controlled discharge (eq. 3-14 ramp to u0 over T) through the Eulerian outlet: the mean
    outlet velocity is the prescribed u(t) (the outlet nodes are driven: round-off), and the
    discharged mass grows at ρ u π R0² — within 12 %, the material near the outlet being
    looser than ρ0: ψ 10° dilates it by up to max_dilation (5 %), and the fit starts 0.1 s
    after the ramp (measured −8 %; the outlet's edge node alone: the next test)."""
    from silo_dolfinx.simulation import ramp_velocity, run

    u0, T = 0.3, 0.2
    sc = load_scene(SCENES / "hopper_ch3_ale.toml",
                    ['fill.method="k0"', "store.duration=0.0", "discharge.duration=0.8", "geometry.element_size=0.05",
                     'discharge.mode="controlled"', f"discharge.velocity={u0}", f"discharge.ramp_time={T}",
                     "output.history_rate=100.0", "output.field_interval=100.0"])
    out = shared_tmp / "controlled"
    summary = run(sc, out, comm, progress_every=1e9)
    comm.barrier()
    o = read_csv(out / "outlet.csv")
    t = o["t"] - o["t"][0]
    u = ramp_velocity(u0, T)
    # the velocities are staggered (t − Δt/2): during the ramp they lag by at most
    # max|u'| Δt/2 = π u0/(2T) · Δt/2 ≈ 1e-3 m/s here (Δt ≈ 5e-4 s); after it, exact
    v = o["mean_outlet_velocity"]
    assert np.allclose(v, [u(tt) for tt in t], rtol=0, atol=2e-3)
    assert np.allclose(v[t > T + 0.01], u0, rtol=1e-9)
    rate, expect = feeder_rate(o, T), sc.material.density * u0 * math.pi * sc.geometry.outlet_radius**2
    assert abs(rate - expect) < 0.12 * expect, (rate, expect)
    assert summary["stages"][-1]["mass_balance_error_max"] < 0.005


def feeder_rate(o: dict, ramp_time: float) -> float:
    """The discharged mass's rate (kg/s) fitted from 0.1 s after a controlled outlet's ramp."""
    t = o["t"] - o["t"][0]
    late = t > ramp_time + 0.1
    return float(np.polyfit(t[late], o["discharged_mass"][late], 1)[0])


FLAT_FEEDER = scene_dict({"shape": "flat_bottom", "radius": 0.3, "height": 0.6, "outlet_radius": 0.06,
                          "element_size": 0.015},
                         material={"model": "drucker_prager", "density": 1500.0, "youngs_modulus": 2.0e6,
                                   "friction_angle": 30.0}, wall={"friction": "coulomb", "mu": 0.4})


@pytest.mark.parametrize("where", ["hopper", "flat_bottom"])
def test_a_slow_feeder_lets_out_what_it_feeds(shared_tmp, comm, where):
    """A feeder at 0.02 m/s under a solid that does not dilate (ψ = 0): what leaves is
    ρ0 u π R0², whatever presses on the outlet's edge node. Driven down with its radial motion
    free, that node was pushed into the wall by the solid's pressure each step and the remap
    let the wall edge beside it sweep the difference out: a leak set by the pressure, +15 % on
    the ch. 3 hopper at this speed (a 2-m wheat bin: 5× at 0.005 m/s), and on a flat bottom the
    floor edge's sliver under the floor, +27 % at 4 cells across the outlet radius. Now the
    node slides down a hopper's wall with the feeder, and on a floor goes down at half its
    speed (effects.OutletDrive): measured −2.5 % and +1.9 %. 5 % holds the transient after the
    ramp (the fit starts 0.1 s after it) and the floor rule's O(h/R0)² remainder, and fails
    either old leak three times over."""
    from silo_dolfinx.simulation import run

    u0, T = 0.02, 0.1
    sets = ['fill.method="k0"', "store.duration=0.0", "discharge.duration=0.8", 'discharge.mode="controlled"',
            f"discharge.velocity={u0}", f"discharge.ramp_time={T}", "output.history_rate=100.0",
            "output.field_interval=100.0", "ale.tracer_rows=0"]
    if where == "hopper":
        sc = load_scene(SCENES / "hopper_ch3_ale.toml", sets + ["geometry.element_size=0.05",
                                                                 "material.dilation_angle=0.0"])
    else:
        sc = load_scene(FLAT_FEEDER, sets)
    out = shared_tmp / f"feeder_{where}"
    summary = run(sc, out, comm, progress_every=1e9)
    comm.barrier()
    rate = feeder_rate(read_csv(out / "outlet.csv"), T)
    expect = sc.material.density * u0 * math.pi * sc.geometry.outlet_radius**2
    assert abs(rate / expect - 1.0) < 0.05, (rate, expect)
    assert summary["stages"][-1]["mass_balance_error_max"] < 0.005


def k0_discharge_velocity(scene, out, comm, sets=()):
    """A ch. 4 scene on a 0.03 m mesh from a K0 state, discharged freely for 2 s: (scene,
    mean outlet velocity over 1-2 s after opening)."""
    from silo_dolfinx.simulation import run

    sc = load_scene(SCENES / f"{scene}.toml",
                    ['fill.method="k0"', "store.duration=0.0", "discharge.duration=2.0", "geometry.element_size=0.03",
                     "ale.tracer_rows=0", "output.history_rate=50.0", "output.field_interval=100.0", *sets])
    summary = run(sc, out, comm, progress_every=1e9)
    comm.barrier()
    assert summary["status"] == "completed"
    o = read_csv(out / "outlet.csv")
    t = o["t"] - o["t"][0]
    return sc, o["mean_outlet_velocity"][(t >= 1.0) & (t <= 2.0)].mean()


def test_smooth_hopper_discharges_at_the_hourglass_rate(shared_tmp, comm):
    """Free discharge of the ch. 4 hopper with a smooth wall and no dilation against the
    hourglass theory (theory.hourglass_discharge, 2.85 m/s mean over the outlet for a
    Drucker-Prager solid with β = 30°, the theory's own parameter: the literal cone):
    the mean outlet velocity over 1-2 s after opening within 20 %. Measured −13 % on this
    0.03 m mesh and −9 % on the scene's 0.0155 m mesh (the gap is the theory's radial stress
    field: uniform over spheres, top boundary a sphere); a wall with friction (the thesis'
    μ 0.267) drops it to ~1.7 m/s, which the smooth-wall theory does not cover."""
    from silo_dolfinx import theory

    sc, v = k0_discharge_velocity("hopper_ch4", shared_tmp / "hourglass", comm,
                                  ['wall.friction="none"', "material.dilation_angle=0.0", 'material.cone="beta"'])
    g = sc.geometry
    expect = theory.hourglass_discharge(sc.cone["beta"], hopper_half_angle(g), g.outlet_radius, g.height)
    assert abs(v / expect["mean_outlet_velocity"] - 1.0) < 0.20, (v, expect["mean_outlet_velocity"])


@pytest.mark.parametrize("scene, bar", [("hopper_ch4_literal_beta", (1.4, 2.0)), ("hopper_ch4", (0.8, 1.3))])
def test_outlet_velocity_depends_on_the_reading_of_the_friction_angle(shared_tmp, comm, scene, bar):
    """Free discharge of the ch. 4 hopper (wall μ 0.267): the mean outlet velocity 1-2 s after
    opening. With β = 30° as the thesis states it (q/p = 0.577) the solid drains at 1.6-1.7 m/s
    (bar 1.4-2.0; the smooth-wall limit is the hourglass test above). The scene as shipped
    reads φ = 30°, ψ = 10° as Mohr-Coulomb angles (β = 50.19°, ψ_DP = 20.24°) with a critical
    state after 5 % dilation; it drains at 1.22 m/s on this 0.03 m mesh (bar 0.8-1.3: TARGETS'
    0.8-1.2 is the full scene's, whose finer outlet drains slower), and the mass actually
    leaving (counted by the remap, 1-2 s after opening) is within 15 % of Beverloo (32.5 kg/s;
    measured 34.8 kg/s, +7 %), with the thesis' nominal ρ0·A·v above it (the outlet material is
    looser than ρ0)."""
    from silo_dolfinx import analysis, theory

    out = shared_tmp / scene
    sc, v = k0_discharge_velocity(scene, out, comm)
    assert bar[0] < v < bar[1], v
    if sc.material.cone != "beta":
        g = sc.geometry
        o = read_csv(out / "outlet.csv")
        t1 = o["t"][0] + 1.0  # one window from 1 s after opening to the end
        _, (w,) = analysis.windowed_mass_flow(o["t"], o["discharged_mass"], o["t"][-1] - t1, t_start=t1)
        bev = theory.beverloo(sc.material.density, 2 * g.outlet_radius)  # 32.5 kg/s
        assert abs(w / bev - 1.0) < 0.15, (w, bev)
        late = o["t"] >= o["t"][0] + 1.0
        assert np.mean(o["nominal_mass_flow_rate"][late]) > w



def test_the_accuracy_problem_flows_regularly_at_two_time_steps(shared_tmp, comm):
    """benchmarks/accuracy_cost.py's discharge problem - the ch. 4 scene at h 0.04 m (1,076
    cells) from a K0 state on the scenes' defaults (compression-matched cone, 2 × 2 points, ALE
    every 10), 1 s of free discharge - at time-step scales 0.8 and 0.4: both flow to the end (the
    last quarter's rate at least half the fastest quarter's), within 25 % of Beverloo (32.5 kg/s;
    measured 35.3 and 36.0 kg/s over the second half, +9 / +11 %) and within 5 % of each other
    (measured 2.0 %; the benchmark's 2-s table: 1.2 %). The table is only worth its numbers if the
    problem answers a knob smoothly: the thesis' ch. 3 mesh (h 0.08 m, 1.25 cells across the outlet
    radius), on which it ran until 2026-12-05, arches from this start (5.5 kg in 10 s) and, at h
    0.06, flowed 14 % apart between these two scales."""
    from silo_dolfinx import theory
    from silo_dolfinx.simulation import run

    rates = []
    for scale in (0.8, 0.4):
        out = shared_tmp / f"accuracy_problem_{scale}"
        sc = load_scene(SCENES / "hopper_ch4.toml",
                        ['fill.method="k0"', "store.duration=0.3", "geometry.element_size=0.04", "discharge.duration=1.0",
                         f"numerics.time_step_scale={scale}", "output.field_interval=0", "output.points=[]"])
        summary = run(sc, out, comm, progress_every=1e9)
        comm.barrier()
        d = next(st for st in summary["stages"] if st["name"] == "discharge")
        quarters = d["mass_flow_quarters"]
        assert quarters[-1] >= 0.5 * max(quarters), quarters  # no arch closed
        assert not any(w.startswith("[discharge] the flow stopped") for w in summary["warnings"])
        rates.append(d["mean_mass_flow_rate_second_half"])
    bev = theory.beverloo(sc.material.density, 2 * sc.geometry.outlet_radius)
    assert all(abs(w / bev - 1.0) < 0.25 for w in rates), (rates, bev)
    assert abs(rates[0] / rates[1] - 1.0) < 0.05, rates


def test_a_discharge_that_arches_says_so(shared_tmp, comm):
    """The thesis' ch. 3 mesh (h 0.08 m, 1.25 cells across the outlet radius) from a K0 state on
    the scenes' compression-matched cone, 1 s of free discharge: an arch closes over the outlet
    within ~0.25 s (measured serially: 3.6 kg out by 0.25 s, 5.5 kg in 10 s) while Δt and the
    balances hold, so the run completes - and its summary says the flow stopped, with the silo
    still full, naming the fixes. Its quarters of mass flow show it: the last under a tenth of
    the first (measured 9.4 → 0.14 kg/s over 2 s)."""
    from silo_dolfinx.simulation import run

    sc = load_scene(SCENES / "hopper_ch3_ale.toml", ['fill.method="k0"', "store.duration=0.3", "discharge.duration=1.0",
                                                     "output.field_interval=0", "output.points=[]"])
    summary = run(sc, shared_tmp / "arch", comm, progress_every=1e9)
    assert summary["status"] == "completed"
    q = summary["stages"][-1]["mass_flow_quarters"]
    assert len(q) == 4 and q[-1] < 0.1 * max(q), q
    (w,) = [w for w in summary["warnings"] if w.startswith("[discharge] the flow stopped")]
    assert "100 % of the fill still inside" in w and 'material.model = "mohr_coulomb"' in w

def test_dilation_is_reported_with_its_fix(ale_run):
    """Each stage records its lowest cell density and the cell that limits Δt; the discharge's
    equal the lowest density of the last field snapshot (written at the stage's end) and a cell
    of it. With the default critical state the
    solid sheared at the outlet stops dilating: in this 1.5 s discharge no cell falls below
    half of ρ0 and no warning is given. Without it (max_dilation = 0, the thesis' model) ψ
    dilates the solid for as long as it shears (a cell of the same run with max_dilation = 0
    reached 415 kg/m³ when ψ_DP was 10°), and a stage that ends below half of ρ0 is warned
    about, naming material.max_dilation; with it, what can still loosen a cell is tensile
    separation at the cone's apex, and the warning says so and names material.recompaction
    unless it is on."""
    import glob

    from silo_dolfinx.simulation import _dilation_warnings

    out, summary = ale_run
    sc = _ch3_scene(True, 1.5)
    rho0 = sc.material.density
    d = summary["stages"][-1]
    snap = np.load(sorted(glob.glob(str(out / "fields" / "snapshot_*.npz")))[-1])
    assert abs(d["density_min"] - snap["cell_density"].min()) < 1e-9 * rho0
    # and the cell that limits Δt at the stage's end: a cell of that snapshot, with its density
    lim = d["dt_limit"]
    k = np.argmin(np.hypot(*(snap["corners"].mean(axis=1) - [lim["r"], lim["z"]]).T))
    assert np.allclose(snap["corners"][k].mean(axis=0), [lim["r"], lim["z"]], atol=1e-12)
    assert abs(snap["cell_density"][k] - lim["density"]) < 1e-9 * rho0 and lim["dt"] > 0.0
    assert summary["stages"][0]["density_min"] > (1 - 1e-9) * rho0  # the K0 start: no volume change yet
    assert sc.material.max_dilation == 0.05 and d["density_min"] > 0.5 * rho0
    assert not [w for w in summary["warnings"] if "dilated" in w]
    unbounded = sc.with_overrides(["material.max_dilation=0.0"])
    warned = _dilation_warnings(unbounded, [dict(d, density_min=0.4 * rho0)])
    assert len(warned) == 1 and "discharge" in warned[0] and "Set material.max_dilation" in warned[0]
    warned = _dilation_warnings(sc, [dict(d, density_min=0.4 * rho0)])  # bounded: the apex's separation
    assert len(warned) == 1 and "apex" in warned[0] and "Set material.max_dilation" not in warned[0]
    assert "material.recompaction = true" in warned[0]  # the key that closes it (a flat bottom's flow decays)
    closing = sc.with_overrides(["material.recompaction=true"])  # on already: the cause, no key to set
    warned = _dilation_warnings(closing, [dict(d, density_min=0.4 * rho0)])
    assert len(warned) == 1 and "apex" in warned[0] and "material.recompaction" not in warned[0]
    assert _dilation_warnings(sc, [dict(d, density_min=0.6 * rho0)]) == []


def test_the_top_polyline_is_walked_along_its_edges_not_sorted_by_radius():
    """A re-meshed surface with a pit need not be a graph of r (its side can lean over): the
    smoother orders the top nodes by walking the top facets from the axis corner to the wall
    corner. Sorting by radius scrambled such a surface (a rezone then stopped a run: 'not the
    top edges of one cell each'). A chain that folds back in r is walked in its own order; a
    branched or broken chain is refused (None), not guessed."""
    from silo_dolfinx.ale.smoothing import _walk

    # axis 0 -> 1 -> 2 -> 3 -> 4 wall, radii 0, .3, .2 (leans back), .5, .9: argsort(r) would give 0 2 1 3 4
    edges = np.array([[2, 3], [0, 1], [3, 4], [1, 2]])
    assert _walk(edges, 0, 4) == [0, 1, 2, 3, 4]
    assert _walk(edges, 4, 0) == [4, 3, 2, 1, 0]
    assert _walk(np.array([[0, 1], [1, 2], [1, 3], [3, 4]]), 0, 4) is None  # a branch at node 1
    assert _walk(np.array([[0, 1], [2, 3], [3, 4]]), 0, 4) is None  # a gap between 1 and 2
    assert _walk(np.array([[0, 1], [1, 2], [2, 4], [5, 6], [6, 5]]), 0, 4) is None  # edges off the chain


def test_a_top_that_leans_back_is_ordered_by_its_facets(comm):
    """The smoother's top polyline on a real mesh whose surface is not a graph of r: the third
    top node from the axis leans out over its outer neighbour (a pit's overhanging side). The
    polyline runs along the top facets - axis, 0.08, the leaning node, 0.24, ... - where the
    order by radius (before) put 0.24 ahead of it and joined nodes that share no facet."""
    from silo_dolfinx.ale import Smoother
    from silo_dolfinx.simulation import SiloModel, mesh_scene

    sc = _ch3_scene(True, 0.1, h=0.08)
    sm = mesh_scene(sc, comm)
    wall = SiloModel(sc, sm).contact_wall_open
    x = sm.mesh.geometry.x
    top = sm.nodes_on("top")  # owned and ghost: every rank moves its copy alike
    radii = np.unique(np.round(np.concatenate(comm.allgather(x[top, 0])), 12))
    r2, r3 = radii[2], radii[3]
    lean = top[np.isclose(x[top, 0], r2)]
    x[lean, 0] = r3 + 0.3 * (r3 - r2)
    x[lean, 1] += 0.5 * (r3 - r2)
    pts = Smoother(sm, wall)._top_polyline(np.ascontiguousarray(x[:, :2]))
    expected = np.concatenate([radii[:2], [r3 + 0.3 * (r3 - r2)], radii[3:]])
    assert pts.shape[0] == radii.size and np.allclose(pts[:, 0], expected)
    assert pts[2, 0] > pts[3, 0]  # not monotone in r: the order is the facets'
