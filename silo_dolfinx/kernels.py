"""Compiled (numba) kernels of one explicit step, vectorised over cells and quadrature points.

Layout: arrays over quadrature points are (num_cells · nq, k) with the nq points of a cell
contiguous, in the order of the solver's active-cell list. Stress/strain 4-vectors are
(rr, zz, θθ, rz) with engineering shear strain.

Kinematics (:func:`kinematics`)
    From the velocity gradient at the quadrature points: the rate of deformation, its
    **mean-dilatation (B-bar)** projection — the volumetric part replaced by its r-weighted
    cell average, which removes volumetric locking of Q1 in isochoric and dilatant plastic
    flow (Nagtegaal, Parks & Rice 1974) — the strain increment, and the in-plane spin.

Objective stress rate (:func:`rotate`)
    Jaumann: the in-plane block (rr, zz, rz) is rotated by the spin angle ω Δt with an
    exact rotation (Hughes-Winget-like incremental objectivity); the hoop stress σθθ is
    normal to the plane of rotation and unchanged. Jaumann rather than Green-Naghdi: it
    needs no deformation gradient (which an ALE remap could not carry consistently), and
    its known defect (oscillating shear stress in hypoelastic simple shear beyond ~100 %
    shear strain) does not arise when the stress is bounded by a perfectly plastic yield
    surface, as in flowing granular solids.

Closure (:func:`closure`)
    Bulk viscosity (linear b1 ρ c_d L ε̇v, quadratic ρ (b2 L ε̇v)² in compression; not part of
    the material stress), the B-bar pressure, the force stress σ̃ written straight into the
    packed coefficient array of the internal-force form, and the work increments.

Stable time step (:func:`stable_dt`)
    Element by element: L_e / c_d with the bulk-viscosity damping correction of eq. 3-11,
    Δt_e = (L_e/c_d)(√(1+ξ²) − ξ), ξ = b1 − b2² (L_e/c_d) min(0, ε̇v); L_e is the element's
    smallest altitude (area / longest edge), reduced near the axis for the hoop stiffness.
"""

from __future__ import annotations

import math

from silo_dolfinx._jit_cache import numba


TWO_PI = 2.0 * math.pi

# Hoop-stiffness correction of the characteristic length near the axis: 1/L² += HOOP / r_c².
# Calibrated by bisection on the scale at which undamped runs blow up
# (benchmarks/stable_dt.py): with 0.1 the critical scale is 1.09-1.32 over structured and
# unstructured columns and hoppers, ν 0.3-0.45 (1.12-1.52 before unstructured meshes were
# relocated, geometry.relocate: more even cells leave the element estimate less slack), so
# the default scale 0.8 (and 0.9) is safe and 1.5 is unstable on every one of them.
HOOP = 0.1

# Fast math for pure arithmetic kernels, but not 'nnan'/'ninf': NaN must still propagate.
FAST = {"contract", "arcp", "reassoc", "nsz", "afn"}


@numba.njit(cache=True, fastmath=FAST)
def kinematics(kin, wq, dt, bbar, out):
    """Strain increments (B-bar if ``bbar``), spin angles and volumes at quadrature points.

    out = (deps, spin, dvol, dV, trd_cell) (:meth:`QuadratureData.kinematics_out`):

    kin   (nc, nq, 6): ∂v_r/∂r, ∂v_r/∂z, ∂v_z/∂r, ∂v_z/∂z, v_r/r, r·|det J|
    wq    (nq,): reference quadrature weights
    deps  (nc·nq, 4) out: strain increment (rr, zz, θθ, γrz) over dt
    spin  (nc·nq,) out: rotation angle ω dt of the material (counter-clockwise in (r, z))
    dvol  (nc·nq,) out: volumetric strain rate used for the density update
    dV    (nc·nq,) out: quadrature volume 2π r |det J| w_q (current configuration)
    trd_cell (nc,) out: volume-averaged volumetric strain rate of each cell
    """
    deps, spin, dvol, dV, trd_cell = out
    nc, nq = kin.shape[0], kin.shape[1]
    for c in range(nc):
        vol = 0.0
        tr_sum = 0.0
        for q in range(nq):
            i = c * nq + q
            g = kin[c, q]
            w = TWO_PI * g[5] * wq[q]
            dV[i] = w
            tr = g[0] + g[3] + g[4]
            vol += w
            tr_sum += tr * w
        tr_avg = tr_sum / vol
        trd_cell[c] = tr_avg
        for q in range(nq):
            i = c * nq + q
            g = kin[c, q]
            drr, dzz, dtt = g[0], g[3], g[4]
            shift = 0.0
            if bbar:
                shift = (tr_avg - (drr + dzz + dtt)) / 3.0
            deps[i, 0] = (drr + shift) * dt
            deps[i, 1] = (dzz + shift) * dt
            deps[i, 2] = (dtt + shift) * dt
            deps[i, 3] = (g[1] + g[2]) * dt
            spin[i] = 0.5 * (g[2] - g[1]) * dt
            dvol[i] = tr_avg if bbar else drr + dzz + dtt


@numba.njit(cache=True, fastmath=FAST)
def rotate(sig, angle, out):
    """Jaumann update: rotate the in-plane stress by ``angle`` (CCW, radians); out may be sig.

    The rotation is the Cayley transform (I − ½W)⁻¹(I + ½W) of Hughes & Winget (1980):
    exactly orthogonal, second-order accurate in the angle, and free of trigonometric calls;
    with c = (1 − a²/4)/(1 + a²/4), s = a/(1 + a²/4) it rotates by 2 atan(a/2) ≈ a."""
    for i in range(sig.shape[0]):
        a = angle[i]
        h = 0.25 * a * a
        c = (1.0 - h) / (1.0 + h)
        s = a / (1.0 + h)
        srr, szz, stt, srz = sig[i, 0], sig[i, 1], sig[i, 2], sig[i, 3]
        out[i, 0] = c * c * srr - 2.0 * c * s * srz + s * s * szz
        out[i, 1] = s * s * srr + 2.0 * c * s * srz + c * c * szz
        out[i, 2] = stt
        out[i, 3] = c * s * (srr - szz) + (c * c - s * s) * srz


@numba.njit(cache=True)
def update_density(rho_old, dvol, dt, nq, bbar, rho_new):
    """ρ ← ρ exp(−ε̇v Δt) (mass conservation). With B-bar ε̇v is uniform over a cell: one exp."""
    nc = rho_old.shape[0] // nq
    for c in range(nc):
        if bbar:
            f = math.exp(-dvol[c * nq] * dt)
            for q in range(nq):
                rho_new[c * nq + q] = rho_old[c * nq + q] * f
        else:
            for q in range(nq):
                i = c * nq + q
                rho_new[i] = rho_old[i] * math.exp(-dvol[i] * dt)


@numba.njit(cache=True, fastmath=FAST)
def closure(points, cells, viscosity, bbar, packed):
    """Force stress σ̃ into ``packed`` (nc, nq·4); returns (internal work, viscous work) increments.

    points = (sig_old, sig_new, deps, dV, rho) (:meth:`QuadratureData.force_in`); cells =
    (trd, L, c, rho) (:attr:`CellData.arrays`); viscosity = (b1, b2).

    σ̃ = dev σ + (p̄ + σ_bv) I with p̄ the r-weighted cell mean of the mean stress (B-bar) or
    the point value, and σ_bv the bulk-viscosity stress of the cell. ``sig_old`` is the
    rotated stress at the start of the step (for the trapezoidal internal work).
    """
    sig_old, sig_new, deps, dV, rho = points
    trd_cell, L_cell, c_cell = cells[0], cells[1], cells[2]
    b1, b2 = viscosity
    nc = trd_cell.shape[0]
    nq = packed.shape[1] // 4
    w_int = 0.0
    w_visc = 0.0
    for c in range(nc):
        vol = 0.0
        m_sum = 0.0
        rho_c = 0.0
        for q in range(nq):
            i = c * nq + q
            m = (sig_new[i, 0] + sig_new[i, 1] + sig_new[i, 2]) / 3.0
            m_sum += m * dV[i]
            vol += dV[i]
            rho_c += rho[i] * dV[i]
        m_bar = m_sum / vol
        rho_c /= vol
        e = trd_cell[c]
        s_bv = 0.0
        if b1 > 0.0 or b2 > 0.0:
            L = L_cell[c]
            s_bv = b1 * rho_c * c_cell[c] * L * e
            if e < 0.0:
                s_bv -= rho_c * (b2 * L * e) ** 2
        for q in range(nq):
            i = c * nq + q
            m = (sig_new[i, 0] + sig_new[i, 1] + sig_new[i, 2]) / 3.0
            p_use = m_bar if bbar else m
            k = q * 4
            packed[c, k + 0] = sig_new[i, 0] - m + p_use + s_bv
            packed[c, k + 1] = sig_new[i, 1] - m + p_use + s_bv
            packed[c, k + 2] = sig_new[i, 2] - m + p_use + s_bv
            packed[c, k + 3] = sig_new[i, 3]
            de = deps[i]
            w_int += 0.5 * dV[i] * ((sig_old[i, 0] + sig_new[i, 0]) * de[0] + (sig_old[i, 1] + sig_new[i, 1]) * de[1]
                                    + (sig_old[i, 2] + sig_new[i, 2]) * de[2] + (sig_old[i, 3] + sig_new[i, 3]) * de[3])
            w_visc += dV[i] * s_bv * (de[0] + de[1] + de[2])
    return w_int, w_visc


@numba.njit(cache=True, fastmath=FAST, inline="always")
def dt_length(x, cell_nodes, c, o, hoop):
    """Characteristic length L of cell c for the stable Δt (nodes in boundary-cycle order,
    o its orientation ±1): the smallest altitude a/e_max, with the hoop stiffness near the
    axis, 1/L² = e_max²/a² + hoop/r_c²; 0 if the cell has collapsed, inverted or turned a
    corner inside out (a non-convex quadrilateral: a turn between consecutive edges against
    the orientation)."""
    n0, n1, n2, n3 = cell_nodes[c, 0], cell_nodes[c, 1], cell_nodes[c, 2], cell_nodes[c, 3]
    r0, r1, r2, r3 = x[n0, 0], x[n1, 0], x[n2, 0], x[n3, 0]
    z0, z1, z2, z3 = x[n0, 1], x[n1, 1], x[n2, 1], x[n3, 1]
    e0r, e0z, e1r, e1z = r1 - r0, z1 - z0, r2 - r1, z2 - z1  # the edges 0 → 1 → 2 → 3 → 0
    e2r, e2z, e3r, e3z = r3 - r2, z3 - z2, r0 - r3, z0 - z3
    convex = (o * (e3r * e0z - e3z * e0r) >= 0.0 and o * (e0r * e1z - e0z * e1r) >= 0.0
              and o * (e1r * e2z - e1z * e2r) >= 0.0 and o * (e2r * e3z - e2z * e3r) >= 0.0)
    a = 0.5 * o * ((r0 - r2) * (z1 - z3) - (r1 - r3) * (z0 - z2))  # half the diagonals' cross product
    e2max = max(max(e0r * e0r + e0z * e0z, e1r * e1r + e1z * e1z), max(e2r * e2r + e2z * e2z, e3r * e3r + e3z * e3z))
    rc = 0.25 * (r0 + r1 + r2 + r3)
    if not (a > 0.0 and rc > 0.0 and convex):
        return 0.0
    return 1.0 / math.sqrt(e2max / (a * a) + hoop / (rc * rc))


@numba.njit(cache=True, fastmath=FAST)
def stable_dt(x, cell_nodes, orient, cells, modulus, viscosity, mass_scaling, hoop=HOOP):
    """Smallest element stable time step (without the user's scale factor).

    x: mesh coordinates; cell_nodes (nc, 4): corner nodes in boundary-cycle order; orient
    (nc,): each cell's orientation (±1, the sign of its area when it was valid);
    cells = (trd, L, c, rho) (:attr:`CellData.arrays`): reads the cell densities and
    volumetric strain rates, writes each cell's characteristic length and wave speed;
    modulus: P-wave modulus λ + 2μ; viscosity = (b1, b2).

    Returns −(c + 1) for the first cell c that has collapsed or inverted - zero or negative
    area against its orientation, or a corner turned inside out (a non-convex quadrilateral:
    its Jacobian changes sign inside it, so the quadrature sees a valid cell that is not) -
    and the caller stops with a clear message.
    """
    trd_cell, L_out, c_out, rho_cell = cells
    b1, b2 = viscosity
    nc = cell_nodes.shape[0]
    dt_min = 1e300
    viscous = b1 > 0.0 or b2 > 0.0
    for c in range(nc):
        L = dt_length(x, cell_nodes, c, orient[c], hoop)
        if L <= 0.0:
            return -(c + 1.0)
        cd = math.sqrt(modulus / (rho_cell[c] * mass_scaling))
        L_out[c] = L
        c_out[c] = cd
        dt_min = min(dt_min, cell_dt(L, cd, trd_cell[c], b1, b2) if viscous else L / cd)
    return dt_min


@numba.njit(cache=True, fastmath=FAST)
def cell_dt(L, cd, trd, b1, b2):
    """One cell's stable Δt: L/c reduced by the bulk viscosity (b1 linear, b2 quadratic in the
    compressive volumetric strain rate trd)."""
    xi = b1 - b2 * b2 * (L / cd) * min(0.0, trd)
    return (L / cd) * (math.sqrt(1.0 + xi * xi) - xi)


@numba.njit(cache=True, fastmath=FAST)
def cell_dts(cells, viscosity, out):
    """Every cell's stable Δt (``out``) from the lengths and wave speeds :func:`stable_dt` wrote
    into ``cells`` = (trd, L, c, rho)."""
    trd, L, c, _ = cells
    b1, b2 = viscosity
    viscous = b1 > 0.0 or b2 > 0.0
    for k in range(out.shape[0]):
        out[k] = cell_dt(L[k], c[k], trd[k], b1, b2) if viscous else L[k] / c[k]


@numba.njit(cache=True)
def cell_average(values, dV, nq, out):
    """r-weighted cell mean of a quadrature-point scalar."""
    nc = out.shape[0]
    for c in range(nc):
        s = 0.0
        v = 0.0
        for q in range(nq):
            i = c * nq + q
            s += values[i] * dV[i]
            v += dV[i]
        out[c] = s / v


# ---------------------------------------------------------------------------- the compiled strain path
@numba.njit(cache=True, fastmath=FAST, inline="always")
def _point_kinematics(cell, xi, eta, g):
    """g (6,) ← ∂v_r/∂r, ∂v_r/∂z, ∂v_z/∂r, ∂v_z/∂z, v_r/r, r·|det J| at reference point (ξ, η)
    of a Q1 cell - cell = (r, z, v_r, v_z) at its four nodes in tensor order (tuples,
    :func:`_gather_cell`)."""
    rn, zn, u, w = cell
    # ∂N/∂ξ, ∂N/∂η of the four bilinear shape functions
    a0, a1, a2, a3 = -(1.0 - eta), 1.0 - eta, -eta, eta
    b0, b1, b2, b3 = -(1.0 - xi), -xi, 1.0 - xi, xi
    N0, N1, N2, N3 = (1.0 - xi) * (1.0 - eta), xi * (1.0 - eta), (1.0 - xi) * eta, xi * eta
    r_xi = a0 * rn[0] + a1 * rn[1] + a2 * rn[2] + a3 * rn[3]
    r_eta = b0 * rn[0] + b1 * rn[1] + b2 * rn[2] + b3 * rn[3]
    z_xi = a0 * zn[0] + a1 * zn[1] + a2 * zn[2] + a3 * zn[3]
    z_eta = b0 * zn[0] + b1 * zn[1] + b2 * zn[2] + b3 * zn[3]
    u_xi = a0 * u[0] + a1 * u[1] + a2 * u[2] + a3 * u[3]
    u_eta = b0 * u[0] + b1 * u[1] + b2 * u[2] + b3 * u[3]
    w_xi = a0 * w[0] + a1 * w[1] + a2 * w[2] + a3 * w[3]
    w_eta = b0 * w[0] + b1 * w[1] + b2 * w[2] + b3 * w[3]
    r = N0 * rn[0] + N1 * rn[1] + N2 * rn[2] + N3 * rn[3]
    det = r_xi * z_eta - r_eta * z_xi
    inv = 1.0 / det
    # ∂f/∂r = (f_ξ z_η − f_η z_ξ)/det, ∂f/∂z = (f_η r_ξ − f_ξ r_η)/det
    g[0] = (u_xi * z_eta - u_eta * z_xi) * inv
    g[1] = (u_eta * r_xi - u_xi * r_eta) * inv
    g[2] = (w_xi * z_eta - w_eta * z_xi) * inv
    g[3] = (w_eta * r_xi - w_xi * r_eta) * inv
    g[4] = (N0 * u[0] + N1 * u[1] + N2 * u[2] + N3 * u[3]) / r
    g[5] = r * abs(det)


@numba.njit(cache=True, fastmath=FAST, inline="always")
def _gather_cell(x, v, node_dof, cn, c):
    """Cell c's (r, z, v_r, v_z) at its four nodes, as tuples (no allocation in the step)."""
    n0, n1, n2, n3 = cn[c, 0], cn[c, 1], cn[c, 2], cn[c, 3]
    d0, d1, d2, d3 = node_dof[n0], node_dof[n1], node_dof[n2], node_dof[n3]
    return ((x[n0, 0], x[n1, 0], x[n2, 0], x[n3, 0]), (x[n0, 1], x[n1, 1], x[n2, 1], x[n3, 1]),
            (v[d0, 0], v[d1, 0], v[d2, 0], v[d3, 0]), (v[d0, 1], v[d1, 1], v[d2, 1], v[d3, 1]))


@numba.njit(cache=True, fastmath=FAST)
def gradients_q1(x, v, node_dof, cn, points, kin):
    """Velocity gradient at the quadrature points of Q1 cells, straight from the node
    positions and the velocity (what ``fem.Expression`` of the same UFL gives, without its
    per-call packing: the strain path of every step).

    x (n_nodes, ≥2) geometry nodes; v (n_dofs, 2) velocity by dof; node_dof: geometry node →
    velocity dof; cn (nc, 4) the cells' nodes in tensor order ((ξ, η) = (0,0), (1,0), (0,1),
    (1,1) on the reference square [0, 1]²); points (nq, 2) reference points.
    kin (nc, nq, 6) out: ∂v_r/∂r, ∂v_r/∂z, ∂v_z/∂r, ∂v_z/∂z, v_r/r, r·|det J|.
    """
    nc, nq = cn.shape[0], points.shape[0]
    for c in range(nc):
        cell = _gather_cell(x, v, node_dof, cn, c)
        for q in range(nq):
            _point_kinematics(cell, points[q, 0], points[q, 1], kin[c, q])


@numba.njit(cache=True, fastmath=FAST, inline="always")
def uniform_strain_vectors(rn, zn):
    """The uniform-strain cell's integrals in closed form, for a Q1 cell with corners rn, zn (4-tuples,
    tensor order): B^r_a = ∫ r ∂N_a/∂r dA, B^z_a = ∫ r ∂N_a/∂z dA and H_a = ∫ N_a dA over the cell
    (4-tuples each), and ∫ r dA = Σ H_a r_a (the volume over 2π), all signed by the cell's
    orientation (positive when ξ → η turns counter-clockwise in (r, z)). Then ∫ f dA = Σ H_a f_a
    for any Q1 field f and ∫ r ∇f dA = Σ (B^r_a, B^z_a) f_a.

    Derivation (Flanagan & Belytschko 1981 do the plane case the same way): det J of a bilinear
    map is linear in (ξ, η), so it equals its Q1 interpolant through the corner values D_a (twice
    the corner triangles' areas) and H_a = Σ_b M_ab D_b with M the Q1 mass matrix of the unit
    square (1/9, 1/18 on an edge, 1/36 across). By Green's theorem ∫ r ∂N_a/∂z dA = −∮ r N_a dr
    and ∫ r ∂N_a/∂r dA = ∮ r N_a dz − ∫ N_a dA, and on a straight edge i → j, where r and N_a are
    linear, ∫ r N_i = (2 r_i + r_j)/6 and ∫ r N_j = (r_i + 2 r_j)/6 per unit of dr or dz. About a
    third of the arithmetic of the same integrals at the 2 × 2 Gauss points, and no division."""
    r0, r1, r2, r3 = rn
    z0, z1, z2, z3 = zn
    # the boundary cycle 0 → 1 → 3 → 2 → 0
    dr01, dz01 = r1 - r0, z1 - z0
    dr13, dz13 = r3 - r1, z3 - z1
    dr32, dz32 = r2 - r3, z2 - z3
    dr20, dz20 = r0 - r2, z0 - z2
    D0 = dr20 * dz01 - dr01 * dz20
    D1 = dr01 * dz13 - dr13 * dz01
    D2 = dr32 * dz20 - dr20 * dz32
    D3 = dr13 * dz32 - dr32 * dz13
    m = 1.0 / 36.0
    H0 = (4.0 * D0 + 2.0 * (D1 + D2) + D3) * m
    H1 = (4.0 * D1 + 2.0 * (D0 + D3) + D2) * m
    H2 = (4.0 * D2 + 2.0 * (D0 + D3) + D1) * m
    H3 = (4.0 * D3 + 2.0 * (D1 + D2) + D0) * m
    a01, b01 = 2.0 * r0 + r1, r0 + 2.0 * r1  # 6 ∫ r N_i, 6 ∫ r N_j on each edge i → j
    a13, b13 = 2.0 * r1 + r3, r1 + 2.0 * r3
    a32, b32 = 2.0 * r3 + r2, r3 + 2.0 * r2
    a20, b20 = 2.0 * r2 + r0, r2 + 2.0 * r0
    s = 1.0 / 6.0
    br = ((a01 * dz01 + b20 * dz20) * s - H0, (a13 * dz13 + b01 * dz01) * s - H1,
          (a20 * dz20 + b32 * dz32) * s - H2, (a32 * dz32 + b13 * dz13) * s - H3)
    bz = (-(a01 * dr01 + b20 * dr20) * s, -(a13 * dr13 + b01 * dr01) * s,
          -(a20 * dr20 + b32 * dr32) * s, -(a32 * dr32 + b13 * dr13) * s)
    return br, bz, (H0, H1, H2, H3), H0 * r0 + H1 * r1 + H2 * r2 + H3 * r3


@numba.njit(cache=True, fastmath=FAST)
def mean_gradients_q1(x, v, node_dof, cn, points, kin):
    """The one-point cell of ``numerics.integration = "reduced"``: the **uniform strain** of
    Flanagan & Belytschko (1981) (Abaqus' CAX4R) - the velocity gradient and v_r/r averaged over
    the cell's exact volume of revolution, (1/V)∫ (·) 2πr dA, in closed form
    (:func:`uniform_strain_vectors`) - and that volume itself: kin (nc, 1, 6) out as
    :func:`gradients_q1`, with kin[c, 0, 5] = ∫ r dA (so the point's volume 2π·kin[..., 5]·w,
    w = 1, is the cell's exact volume). ``points`` is not read (the closed form needs none); the
    signature is :func:`gradients_q1`'s, so the solver calls either strain path alike.

    Why not the gradient at the centre: its trace is the rate of the one-point volume 2π r_c A,
    not of the cell's volume, which the ALE remap moves mass by. On a cell near the axis that is
    not a parallelogram the two differ, and in the converging flow over an outlet the difference
    compacted the solid with no pressure to resist it - the ch. 6 silo's outlet cells rose to
    1,810-2,340 kg/m³ from 1,455 on an unstructured mesh, and the mass leaving to 1.3 × ρ0 A v
    (docs/validation/ch6.md). The mean trace is exactly d ln V/dt, so ρ V is conserved in the
    Lagrangian step in the volume the remap conserves it in, and the pressure resists exactly
    the volume change the mass sees; the internal force σ : ∫ B_a 2πr dA is its work conjugate
    (:mod:`silo_dolfinx.forms`)."""
    for c in range(cn.shape[0]):
        rn, zn, u, w = _gather_cell(x, v, node_dof, cn, c)
        br, bz, h, vol = uniform_strain_vectors(rn, zn)  # signed alike: the ratios are not
        inv = 1.0 / vol
        out = kin[c, 0]
        out[0] = (br[0] * u[0] + br[1] * u[1] + br[2] * u[2] + br[3] * u[3]) * inv
        out[1] = (bz[0] * u[0] + bz[1] * u[1] + bz[2] * u[2] + bz[3] * u[3]) * inv
        out[2] = (br[0] * w[0] + br[1] * w[1] + br[2] * w[2] + br[3] * w[3]) * inv
        out[3] = (bz[0] * w[0] + bz[1] * w[1] + bz[2] * w[2] + bz[3] * w[3]) * inv
        out[4] = (h[0] * u[0] + h[1] * u[1] + h[2] * u[2] + h[3] * u[3]) * inv
        out[5] = abs(vol)


# ---------------------------------------------------------------------------- hourglass control
# One-point quadrature (numerics.integration = "reduced", the thesis' CAX4R) sees neither of
# the two hourglass modes of a Q1 quadrilateral - in axisymmetry too: the hoop strain v_r/r at
# the centre is blind to them. Flanagan & Belytschko (1981): with b_a = ∂N_a/∂x at the centre
# and h = (1, −1, −1, 1) (tensor order), γ_a = ¼ (h_a − (h·r) b_a^r − (h·z) b_a^z) is orthogonal
# to every linear field, so the generalised hourglass rate q̇_i = Σ_a γ_a v_ai measures only the
# modes; the nodal forces f_ai = Q_i γ_a resist them and do no work on a linear field (the
# patch test holds). Q = Q_s + Q_v:
#   stiffness  Q̇_s = C_s q̇,  C_s = κ_s (λ + 2μ) A (b·b)/2 · 2π r_c   (stored, remapped by ALE)
#   viscosity  Q_v = C_v q̇,  C_v = κ_v ρ c_d A √((b·b)/2) · 2π r_c
# For a square cell of side L: C_s = κ_s (λ + 2μ) 2π r_c (the mode's own plane-strain energy
# under full integration is (2/3)(λ + 3μ) q² per unit ring length, so κ_s ~ 0.05-0.1 is a few
# per cent of it) and C_v = κ_v ρ c_d L 2π r_c (critical damping of the stiffness-held mode is
# 2 √κ_s ρ c_d L 2π r_c). The work Σ Q·q̇ Δt is booked in the energy ledger as ``hourglass``
# (Abaqus' ALLAE), to be read against the internal energy.

@numba.njit(cache=True, fastmath=FAST, inline="always")
def _centre_gradients(r0, r1, r2, r3, z0, z1, z2, z3):
    """∂N_a/∂r, ∂N_a/∂z at the centre of a Q1 cell (tensor order) and det J there."""
    # at the centre: ∂N/∂ξ = ½(−1, 1, −1, 1), ∂N/∂η = ½(−1, −1, 1, 1)
    r_xi = 0.5 * (r1 - r0 + r3 - r2)
    r_eta = 0.5 * (r2 - r0 + r3 - r1)
    z_xi = 0.5 * (z1 - z0 + z3 - z2)
    z_eta = 0.5 * (z2 - z0 + z3 - z1)
    det = r_xi * z_eta - r_eta * z_xi
    inv = 1.0 / det
    br0 = 0.5 * (-z_eta + z_xi) * inv
    br1 = 0.5 * (z_eta + z_xi) * inv
    br2 = 0.5 * (-z_eta - z_xi) * inv
    br3 = 0.5 * (z_eta - z_xi) * inv
    bz0 = 0.5 * (r_eta - r_xi) * inv
    bz1 = 0.5 * (-r_eta - r_xi) * inv
    bz2 = 0.5 * (r_eta + r_xi) * inv
    bz3 = 0.5 * (-r_eta + r_xi) * inv
    return br0, br1, br2, br3, bz0, bz1, bz2, bz3, det


@numba.njit(cache=True, fastmath=FAST, inline="always")
def _hourglass_shape(x, cn, c):
    """γ (4,) and (area, b·b, r_c) of cell c at positions x (tensor-order nodes)."""
    n0, n1, n2, n3 = cn[c, 0], cn[c, 1], cn[c, 2], cn[c, 3]
    r0, r1, r2, r3 = x[n0, 0], x[n1, 0], x[n2, 0], x[n3, 0]
    z0, z1, z2, z3 = x[n0, 1], x[n1, 1], x[n2, 1], x[n3, 1]
    br0, br1, br2, br3, bz0, bz1, bz2, bz3, det = _centre_gradients(r0, r1, r2, r3, z0, z1, z2, z3)
    hr = r0 - r1 - r2 + r3
    hz = z0 - z1 - z2 + z3
    g0 = 0.25 * (1.0 - hr * br0 - hz * bz0)
    g1 = 0.25 * (-1.0 - hr * br1 - hz * bz1)
    g2 = 0.25 * (-1.0 - hr * br2 - hz * bz2)
    g3 = 0.25 * (1.0 - hr * br3 - hz * bz3)
    bb = br0 * br0 + br1 * br1 + br2 * br2 + br3 * br3 + bz0 * bz0 + bz1 * bz1 + bz2 * bz2 + bz3 * bz3
    return g0, g1, g2, g3, abs(det), bb, 0.25 * (r0 + r1 + r2 + r3)


@numba.njit(cache=True, fastmath=FAST, inline="always")
def _add_hourglass_force(f, dofs, gamma, i, Q):
    """f[dof_a, i] += Q γ_a over the cell's four nodes."""
    for a in range(4):
        f[dofs[a], i] += Q * gamma[a]


@numba.njit(cache=True, fastmath=FAST, inline="always")
def _cell_dofs(node_dof, cn, c):
    return node_dof[cn[c, 0]], node_dof[cn[c, 1]], node_dof[cn[c, 2]], node_dof[cn[c, 3]]


@numba.njit(cache=True, fastmath=FAST)
def hourglass_update(x, v, node_dof, cn, cell, law, dt, forces):
    """Generalised hourglass forces of the step, forces = (Q_s^n, Q_s^{n+1}, Q_v, f): Q_s
    (stiffness, from Q_s^n into Q_s^{n+1}) and Q_v (viscosity), all (nc, 2), from the hourglass
    rate of v^{n+½} on the cells at x, and their nodal forces Q_i γ_a added to f (n_dofs, 2) in
    the same pass (:func:`hourglass_force` for a force rebuilt later); returns the hourglass
    work of the step (J), trapezoidal in Q_s.

    cell = (ρ (nc,), σ (nc, 4)) of the cells (one point each); law = (λ + 2μ, κ_s, κ_v, tan β, d).
    The stored force is capped at the cell's shear strength, |Q_s,i| ≤ q_y A √(b·b/2) 2π r_c with
    q_y = p tan β + d (tan β < 0: no cap): the bilinear stress field an hourglass mode stands for
    cannot exceed yield in a plastic solid either (with 2 × 2 points it is capped at the points),
    so the control holds a cell at rest against its load but does not hold back a flowing one."""
    rho_cell, sig = cell
    modulus, ks, kv, tanb, d = law
    qs_old, qs_new, qv, f = forces
    w = 0.0
    for c in range(cn.shape[0]):
        g0, g1, g2, g3, area, bb, rc = _hourglass_shape(x, cn, c)
        d0, d1, d2, d3 = _cell_dofs(node_dof, cn, c)
        ring = TWO_PI * rc
        shear = area * math.sqrt(0.5 * bb) * ring  # what a shear stress on the mode becomes a force by
        cs = ks * modulus * area * bb * 0.5 * ring
        cv = kv * math.sqrt(modulus * rho_cell[c]) * shear  # κ_v ρ c_d A √(b·b/2) 2π r_c
        cap = 1e300
        if tanb >= 0.0:
            p = -(sig[c, 0] + sig[c, 1] + sig[c, 2]) / 3.0
            cap = max(p * tanb + d, 0.0) * shear
        for i in range(2):
            qd = g0 * v[d0, i] + g1 * v[d1, i] + g2 * v[d2, i] + g3 * v[d3, i]
            qs_new[c, i] = min(max(qs_old[c, i] + cs * qd * dt, -cap), cap)
            qv[c, i] = cv * qd
            w += (0.5 * (qs_old[c, i] + qs_new[c, i]) + qv[c, i]) * qd * dt
            _add_hourglass_force(f, (d0, d1, d2, d3), (g0, g1, g2, g3), i, qs_new[c, i] + qv[c, i])
    return w


@numba.njit(cache=True, fastmath=FAST)
def hourglass_force(x, node_dof, cn, q_hourglass, f):
    """Add the hourglass forces f_ai += Q_i γ_a of every cell, Q = Q_s + Q_v with
    ``q_hourglass`` = (Q_s, Q_v), (nc, 2) each (Q_s: zeros when the stiffness form is off), to the
    internal force ``f`` (n_dofs, 2; owned and ghost rows, before the ghost accumulation)."""
    qs, qv = q_hourglass
    for c in range(cn.shape[0]):
        g0, g1, g2, g3, _, _, _ = _hourglass_shape(x, cn, c)
        for i in range(2):
            _add_hourglass_force(f, _cell_dofs(node_dof, cn, c), (g0, g1, g2, g3), i, qs[c, i] + qv[c, i])
