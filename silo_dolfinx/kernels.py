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

import numba

TWO_PI = 2.0 * math.pi

# Hoop-stiffness correction of the characteristic length near the axis: 1/L² += HOOP / r_c².
# Calibrated by bisection on the scale at which undamped runs blow up
# (benchmarks/stable_dt.py): with 0.1 the critical scale is 1.12-1.52 over structured and
# unstructured columns and hoppers, ν 0.3-0.45, so the default scale 0.8 (and 0.9) is safe
# and 1.5 is unstable on the column meshes (the guard test uses one).
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
def closure(points, cells, viscosity, bbar, nq, packed):
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
        a = 0.0
        e2max = 0.0
        rc = 0.0
        o = orient[c]
        convex = True
        for k in range(4):
            n0 = cell_nodes[c, (k + 3) % 4]
            n1 = cell_nodes[c, k]
            n2 = cell_nodes[c, (k + 1) % 4]
            x0, z0, x1, z1 = x[n1, 0], x[n1, 1], x[n2, 0], x[n2, 1]
            a += x0 * z1 - x1 * z0
            e2max = max(e2max, (x1 - x0) ** 2 + (z1 - z0) ** 2)
            rc += 0.25 * x0
            if o * ((x0 - x[n0, 0]) * (z1 - z0) - (z0 - x[n0, 1]) * (x1 - x0)) < 0.0:
                convex = False
        a = 0.5 * a * o
        if not (a > 0.0 and rc > 0.0 and convex):
            return -(c + 1.0)
        # altitude a/e_max, with the hoop stiffness near the axis: 1/L² = e²/a² + hoop/r²
        L = 1.0 / math.sqrt(e2max / (a * a) + hoop / (rc * rc))
        cd = math.sqrt(modulus / (rho_cell[c] * mass_scaling))
        L_out[c] = L
        c_out[c] = cd
        xi = b1 - b2 * b2 * (L / cd) * min(0.0, trd_cell[c]) if viscous else 0.0
        dt = (L / cd) * (math.sqrt(1.0 + xi * xi) - xi)
        dt_min = min(dt_min, dt)
    return dt_min


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
