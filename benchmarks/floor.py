"""The floor of the step's cost: the same explicit step written by hand in numba, no dolfinx.

One kernel per step, fused as an explicit code written for speed would be: the nodal update
(a = M⁻¹(f_ext − f_int), v += Δt a, axis and wall constraints, x += Δt v), then one pass over
the cells doing everything a cell does - velocity gradient at the mid-step configuration,
B-bar strain increment and spin, Jaumann rotation, the Drucker-Prager return (dilation, the
critical state, cohesion: the same law and constants), the density, the bulk viscosity, the
internal force σ̃ : B 2π r dV at the end configuration scattered to the nodes (with the viscous
hourglass force at one point) and the cell's stable Δt. The one-point cell is the solver's
uniform-strain cell: the gradient's mean over the cell's exact volume and the force's integrals
in the solver's closed form (kernels.uniform_strain_vectors), σ̃ constant on the cell. Same mesh,
same quadrature, same constants as the solver's step; the wall contact is reduced to a
frictionless constraint on the same nodes (the solver's contact costs a few per cent of its
step: the 'update' phase).

Used by ``benchmarks/step_cost.py`` (``ours / floor``); checked there against the solver: the
same stable Δt and the same stress after a few steps from the same geostatic state.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from silo_dolfinx.kernels import uniform_strain_vectors

FAST = {"contract", "arcp", "reassoc", "nsz", "afn"}
TWO_PI = 2.0 * math.pi


@numba.njit(cache=True, fastmath=FAST)
def _shape(points, q):
    xi, eta = points[q, 0], points[q, 1]
    return ((1.0 - xi) * (1.0 - eta), xi * (1.0 - eta), (1.0 - xi) * eta, xi * eta,
            -(1.0 - eta), 1.0 - eta, -eta, eta, -(1.0 - xi), -xi, 1.0 - xi, xi)


@numba.njit(cache=True, fastmath=FAST, inline="always")
def _jacobian(a, c, ri, zi):
    """(∂r/∂ξ, ∂r/∂η, ∂z/∂ξ, ∂z/∂η, det J) for shape derivatives a = ∂N/∂ξ, c = ∂N/∂η."""
    r_x = a[0] * ri[0] + a[1] * ri[1] + a[2] * ri[2] + a[3] * ri[3]
    r_e = c[0] * ri[0] + c[1] * ri[1] + c[2] * ri[2] + c[3] * ri[3]
    z_x = a[0] * zi[0] + a[1] * zi[1] + a[2] * zi[2] + a[3] * zi[3]
    z_e = c[0] * zi[0] + c[1] * zi[1] + c[2] * zi[2] + c[3] * zi[3]
    return r_x, r_e, z_x, z_e, r_x * z_e - r_e * z_x


@numba.njit(cache=True, fastmath=FAST)
def step(arrays, law, dt):
    """One fused step; returns the stable Δt (unscaled) of the new configuration.

    arrays = (x (n,2), v (n,2), minv (n,), f_ext (n,2), f (n,2), axis (n,) bool, wall_n (n,2) unit
    normals (0 off the wall), cells (nc,4) tensor order, points (nq,2), weights (nq,), sig (nc·nq,4),
    eqps (nc·nq,), rho (nc·nq,)); law = (K, G, tan β, tan ψ, d, eqps_c, b1, b2, κ_v)."""
    x, v, minv, fext, f, axis, wall_n, cells, points, wq, sig, eqps, rho = arrays
    K, G, tanb, tanpsi0, d, eqps_c, b1, b2, kv = law
    lam = K - 2.0 * G / 3.0
    M = K + 4.0 * G / 3.0
    n = x.shape[0]
    for i in range(n):  # predict, constrain
        for k in range(2):
            v[i, k] += dt * minv[i] * (fext[i, k] - f[i, k])
            f[i, k] = 0.0
        if axis[i]:
            v[i, 0] = 0.0
        vn = v[i, 0] * wall_n[i, 0] + v[i, 1] * wall_n[i, 1]
        v[i, 0] -= vn * wall_n[i, 0]
        v[i, 1] -= vn * wall_n[i, 1]
    nq = points.shape[0]  # integration points; stress points: nq, or one (the uniform-strain cell)
    ns = sig.shape[0] // cells.shape[0]
    dt_min = 1e300
    ri = np.empty(4)
    zi = np.empty(4)
    ui = np.empty(4)
    wi = np.empty(4)
    g = np.empty((nq, 6))
    gam = np.empty(4)
    for c in range(cells.shape[0]):
        for a in range(4):
            nd = cells[c, a]
            ui[a], wi[a] = v[nd, 0], v[nd, 1]
            ri[a], zi[a] = x[nd, 0] + 0.5 * dt * ui[a], x[nd, 1] + 0.5 * dt * wi[a]  # mid-step
        vol = 0.0
        trs = 0.0
        for q in range(nq if ns > 1 else 0):
            N0, N1, N2, N3, a0, a1, a2, a3, c0, c1, c2, c3 = _shape(points, q)
            r_x, r_e, z_x, z_e, det = _jacobian((a0, a1, a2, a3), (c0, c1, c2, c3), ri, zi)
            inv = 1.0 / det
            u_x = a0 * ui[0] + a1 * ui[1] + a2 * ui[2] + a3 * ui[3]
            u_e = c0 * ui[0] + c1 * ui[1] + c2 * ui[2] + c3 * ui[3]
            w_x = a0 * wi[0] + a1 * wi[1] + a2 * wi[2] + a3 * wi[3]
            w_e = c0 * wi[0] + c1 * wi[1] + c2 * wi[2] + c3 * wi[3]
            r = N0 * ri[0] + N1 * ri[1] + N2 * ri[2] + N3 * ri[3]
            g[q, 0] = (u_x * z_e - u_e * z_x) * inv
            g[q, 1] = (u_e * r_x - u_x * r_e) * inv
            g[q, 2] = (w_x * z_e - w_e * z_x) * inv
            g[q, 3] = (w_e * r_x - w_x * r_e) * inv
            g[q, 4] = (N0 * ui[0] + N1 * ui[1] + N2 * ui[2] + N3 * ui[3]) / r
            g[q, 5] = TWO_PI * r * abs(det) * wq[q]
            vol += g[q, 5]
            trs += (g[q, 0] + g[q, 3] + g[q, 4]) * g[q, 5]
        if ns == 1:  # one point: the gradient's mean over the cell's exact volume, in closed form
            br, bz, h, v1 = uniform_strain_vectors((ri[0], ri[1], ri[2], ri[3]), (zi[0], zi[1], zi[2], zi[3]))
            inv = 1.0 / v1
            g[0, 0] = (br[0] * ui[0] + br[1] * ui[1] + br[2] * ui[2] + br[3] * ui[3]) * inv
            g[0, 1] = (bz[0] * ui[0] + bz[1] * ui[1] + bz[2] * ui[2] + bz[3] * ui[3]) * inv
            g[0, 2] = (br[0] * wi[0] + br[1] * wi[1] + br[2] * wi[2] + br[3] * wi[3]) * inv
            g[0, 3] = (bz[0] * wi[0] + bz[1] * wi[1] + bz[2] * wi[2] + bz[3] * wi[3]) * inv
            g[0, 4] = (h[0] * ui[0] + h[1] * ui[1] + h[2] * ui[2] + h[3] * ui[3]) * inv
            g[0, 5] = vol = TWO_PI * abs(v1)
            trs = (g[0, 0] + g[0, 3] + g[0, 4]) * vol
        tr_avg = trs / vol
        mbar = 0.0
        rho_c = 0.0
        for q in range(ns):  # strain, rotation, return map, density
            i = c * ns + q
            shift = (tr_avg - (g[q, 0] + g[q, 3] + g[q, 4])) / 3.0
            e0, e1, e2 = (g[q, 0] + shift) * dt, (g[q, 3] + shift) * dt, (g[q, 4] + shift) * dt
            e3 = (g[q, 1] + g[q, 2]) * dt
            ang = 0.5 * (g[q, 2] - g[q, 1]) * dt
            h = 0.25 * ang * ang
            co, si = (1.0 - h) / (1.0 + h), ang / (1.0 + h)
            s0, s1, s2, s3 = sig[i, 0], sig[i, 1], sig[i, 2], sig[i, 3]
            tr0 = co * co * s0 - 2.0 * co * si * s3 + si * si * s1
            tr1 = si * si * s0 + 2.0 * co * si * s3 + co * co * s1
            tr3 = co * si * (s0 - s1) + (co * co - si * si) * s3
            tr = e0 + e1 + e2
            t0 = tr0 + lam * tr + 2.0 * G * e0
            t1 = tr1 + lam * tr + 2.0 * G * e1
            t2 = s2 + lam * tr + 2.0 * G * e2
            t3 = tr3 + G * e3
            p = -(t0 + t1 + t2) / 3.0
            d0, d1, d2 = t0 + p, t1 + p, t2 + p
            qq = math.sqrt(1.5 * (d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * t3 * t3))
            fy = qq - p * tanb - d
            if fy > 0.0:
                tanpsi = tanpsi0 if eqps[i] < eqps_c else 0.0
                dlam = fy / (3.0 * G + K * tanb * tanpsi)
                if 3.0 * G * dlam <= qq:
                    qn = qq - 3.0 * G * dlam
                    pn = p + K * tanpsi * dlam
                    k = qn / qq
                    t0, t1, t2, t3 = k * d0 - pn, k * d1 - pn, k * d2 - pn, k * t3
                else:
                    pa = -d / tanb
                    t0, t1, t2, t3 = -pa, -pa, -pa, 0.0
                eqps[i] += dlam
            sig[i, 0], sig[i, 1], sig[i, 2], sig[i, 3] = t0, t1, t2, t3
            rho[i] *= math.exp(-tr_avg * dt)
            mbar += (t0 + t1 + t2) / 3.0 * g[q, 5]
            rho_c += rho[i] * g[q, 5]
        mbar /= vol
        rho_c /= vol
        for a in range(4):  # the end configuration
            ri[a] += 0.5 * dt * ui[a]
            zi[a] += 0.5 * dt * wi[a]
        # stable Δt of the cell (area over longest edge, the hoop correction, bulk viscosity)
        area = 0.5 * ((ri[1] - ri[2]) * (zi[3] - zi[0]) - (ri[3] - ri[0]) * (zi[1] - zi[2]))
        area = abs(area)
        e2 = max((ri[1] - ri[0]) ** 2 + (zi[1] - zi[0]) ** 2, (ri[3] - ri[1]) ** 2 + (zi[3] - zi[1]) ** 2,
                 (ri[2] - ri[3]) ** 2 + (zi[2] - zi[3]) ** 2, (ri[0] - ri[2]) ** 2 + (zi[0] - zi[2]) ** 2)
        rcen = 0.25 * (ri[0] + ri[1] + ri[2] + ri[3])
        L = 1.0 / math.sqrt(e2 / (area * area) + 0.1 / (rcen * rcen))
        cd = math.sqrt(M / rho_c)
        xi_v = b1 - b2 * b2 * (L / cd) * min(0.0, tr_avg)
        dt_min = min(dt_min, (L / cd) * (math.sqrt(1.0 + xi_v * xi_v) - xi_v))
        s_bv = b1 * rho_c * cd * L * tr_avg
        if tr_avg < 0.0:
            s_bv -= rho_c * (b2 * L * tr_avg) ** 2
        if ns == 1:  # internal force at the end configuration: σ̃ constant on the cell, its integrals closed
            br, bz, h, v1 = uniform_strain_vectors((ri[0], ri[1], ri[2], ri[3]), (zi[0], zi[1], zi[2], zi[3]))
            sg = TWO_PI if v1 > 0.0 else -TWO_PI  # the vectors are signed by the orientation
            i = c
            p_use = mbar - (sig[i, 0] + sig[i, 1] + sig[i, 2]) / 3.0 + s_bv
            srr, szz, stt, srz = sig[i, 0] + p_use, sig[i, 1] + p_use, sig[i, 2] + p_use, sig[i, 3]
            for a in range(4):
                nd = cells[c, a]
                f[nd, 0] += sg * (srr * br[a] + stt * h[a] + srz * bz[a])
                f[nd, 1] += sg * (szz * bz[a] + srz * br[a])
        for q in range(nq if ns > 1 else 0):  # internal force at the end configuration, at the points
            i = c * ns + q
            N0, N1, N2, N3, a0, a1, a2, a3, c0, c1, c2, c3 = _shape(points, q)
            r_x, r_e, z_x, z_e, det = _jacobian((a0, a1, a2, a3), (c0, c1, c2, c3), ri, zi)
            inv = 1.0 / det
            r = N0 * ri[0] + N1 * ri[1] + N2 * ri[2] + N3 * ri[3]
            dv = TWO_PI * r * abs(det) * wq[q]
            m = (sig[i, 0] + sig[i, 1] + sig[i, 2]) / 3.0
            p_use = mbar - m + s_bv
            srr, szz, stt, srz = sig[i, 0] + p_use, sig[i, 1] + p_use, sig[i, 2] + p_use, sig[i, 3]
            Ns = (N0, N1, N2, N3)
            As = (a0, a1, a2, a3)
            Cs = (c0, c1, c2, c3)
            for a in range(4):
                br = (As[a] * z_e - Cs[a] * z_x) * inv
                bz = (Cs[a] * r_x - As[a] * r_e) * inv
                nd = cells[c, a]
                f[nd, 0] += (srr * br + stt * Ns[a] / r + srz * bz) * dv
                f[nd, 1] += (szz * bz + srz * br) * dv
        if ns == 1 and kv > 0.0:  # viscous hourglass control (kernels.hourglass_update, κ_s = 0)
            r_x = 0.5 * (ri[1] - ri[0] + ri[3] - ri[2])
            r_e = 0.5 * (ri[2] - ri[0] + ri[3] - ri[1])
            z_x = 0.5 * (zi[1] - zi[0] + zi[3] - zi[2])
            z_e = 0.5 * (zi[2] - zi[0] + zi[3] - zi[1])
            det = r_x * z_e - r_e * z_x
            inv = 1.0 / det
            hr = ri[0] - ri[1] - ri[2] + ri[3]
            hz = zi[0] - zi[1] - zi[2] + zi[3]
            bb = 0.0
            for a in range(4):
                br = 0.5 * ((-1.0 if a % 2 == 0 else 1.0) * z_e - (-1.0 if a < 2 else 1.0) * z_x) * inv
                bz = 0.5 * ((-1.0 if a < 2 else 1.0) * r_x - (-1.0 if a % 2 == 0 else 1.0) * r_e) * inv
                bb += br * br + bz * bz
                gam[a] = 0.25 * ((1.0 if a == 0 or a == 3 else -1.0) - hr * br - hz * bz)
            cv = kv * rho_c * cd * abs(det) * math.sqrt(0.5 * bb) * TWO_PI * rcen
            for k in range(2):
                qd = 0.0
                for a in range(4):
                    qd += gam[a] * v[cells[c, a], k]
                for a in range(4):
                    f[cells[c, a], k] += cv * qd * gam[a]
    for i in range(n):
        x[i, 0] += dt * v[i, 0]
        x[i, 1] += dt * v[i, 1]
    return dt_min


def from_solver(solver) -> tuple:
    """The floor's arrays for the solver's mesh and state (dof numbering; copies), and the law."""
    s = solver
    x = np.ascontiguousarray(s.mesh.geometry.x[s.dof_node, :2])
    cells = np.ascontiguousarray(s.node_dof[s.cell_tensor[s.active_cells]])
    axis = x[:, 0] < 1e-9
    wall_n = np.zeros_like(x)
    for contact in s.contacts:  # the wall nodes and their normals at the last step
        wall_n[contact.dofs] = contact.normal
    f_ext = np.zeros_like(x)
    f_ext[:, 1] = -s.gravity * s.mass
    m = s.material
    law = tuple(map(float, (m.K, m.G, m.tan_beta, m.tan_psi, m.cohesion, m.eqps_critical,
                            *s.numerics.bulk_viscosity, s.numerics.hourglass[1])))
    arrays = (x, s.v.copy(), s.minv.copy(), f_ext, s.f_int.copy(), axis, wall_n, cells,
              np.ascontiguousarray(s.forms.points), s.forms.weights, s.sig.copy(),
              s.state["eqps"].copy(), s.rho.copy())
    return arrays, law
