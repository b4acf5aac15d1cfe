"""High order: linear reconstruction in the upwind cell (Remhos' HO stage), as corrections
A = HO − LO to the donor-cell fluxes, which the flux correction (:mod:`.fct`) then limits.

Gradients are least-squares fits (weights 1/|Δx|²) over the edge neighbours about each cell's
r-weighted centroid. Mass (stage 1): the reconstructed ρ integrated exactly over the swept
region from its moments ∫r, ∫r², ∫rz dA. Intensive variables (stage 2): F·Q at the swept
region's centroid."""

from __future__ import annotations

from silo_dolfinx._jit_cache import numba
from silo_dolfinx.ale.remap.geometry import TWO_PI
from silo_dolfinx.kernels import FAST


@numba.njit(cache=True, fastmath=FAST)
def ls_gradients(vals, cen, faces, scratch, grads):
    """Least-squares gradients (weights 1/|Δx|²) of every column of ``vals`` in owned cells.
    faces = (left, right, n_owned); scratch = (normal equations (n_owned, 3), right-hand
    sides (n_owned, k, 2)), overwritten (work arrays of the caller: nothing allocated)."""
    fl, fr, n_owned = faces
    normal, b = scratch
    k = vals.shape[1]
    normal[:n_owned] = 0.0
    b[:n_owned] = 0.0
    for f in range(fl.shape[0]):
        l, r = fl[f], fr[f]
        if l < 0 or r < 0:
            continue
        dx = cen[r, 0] - cen[l, 0]
        dy = cen[r, 1] - cen[l, 1]
        w = 1.0 / (dx * dx + dy * dy + 1e-300)
        wx, wy = w * dx, w * dy
        # both cells of the edge get the same terms (the signs of Δx and Δq cancel)
        lown, rown = l < n_owned, r < n_owned
        nxx, nxy, nyy = wx * dx, wx * dy, wy * dy
        if lown:
            normal[l, 0] += nxx
            normal[l, 1] += nxy
            normal[l, 2] += nyy
        if rown:
            normal[r, 0] += nxx
            normal[r, 1] += nxy
            normal[r, 2] += nyy
        for j in range(k):
            dq = vals[r, j] - vals[l, j]
            if lown:
                b[l, j, 0] += wx * dq
                b[l, j, 1] += wy * dq
            if rown:
                b[r, j, 0] += wx * dq
                b[r, j, 1] += wy * dq
    for c in range(n_owned):
        axx, axy, ayy = normal[c, 0], normal[c, 1], normal[c, 2]
        det = axx * ayy - axy * axy
        if det <= 1e-10 * (axx + ayy) ** 2:
            for j in range(k):
                grads[c, j, 0] = 0.0
                grads[c, j, 1] = 0.0
            continue
        for j in range(k):
            grads[c, j, 0] = (ayy * b[c, j, 0] - axy * b[c, j, 1]) / det
            grads[c, j, 1] = (axx * b[c, j, 1] - axy * b[c, j, 0]) / det


@numba.njit(cache=True, fastmath=FAST)
def mass_corrections(faces, R, grads, cen, mom, low, A):
    """Stage 1: A[:, 0] = (the upwind linear ρ integrated over the swept region) − low[:, 0]."""
    fl, fr = faces[0], faces[1]
    for f in range(fl.shape[0]):
        l, r = fl[f], fr[f]
        m0 = mom[f, 0]
        d = l if m0 > 0.0 else r
        # at an outlet the donor cell's flux stands: the linear ρ extrapolated to the outlet face
        # (an emptied cell under a dense one: the free-fall zone) can turn the flux inwards,
        # and nothing outside bounds what the limiter would let in - mass from nowhere
        if d < 0 or m0 == 0.0 or l < 0 or r < 0:
            A[f, 0] = 0.0
            continue
        lo = TWO_PI * m0 * R[d, 0]  # = low[f, 0], recomputed: the same arithmetic as the donor flux
        hi = TWO_PI * (R[d, 0] * m0 + grads[d, 0, 0] * (mom[f, 1] - cen[d, 0] * m0)
                       + grads[d, 0, 1] * (mom[f, 2] - cen[d, 1] * m0))
        A[f, 0] = hi - lo


@numba.njit(cache=True, fastmath=FAST)
def value_corrections(faces, fmass, grads, cen, xf, A):
    """Stage 2: A[:, 1..k] = F · (∇Q_up · (x_f − x_up)), the high-order part of F·Q(x_f)."""
    fl, fr = faces[0], faces[1]
    k1 = A.shape[1]
    for f in range(fl.shape[0]):
        l, r = fl[f], fr[f]
        F = fmass[f]
        d = l if F > 0.0 else r
        if d < 0 or F == 0.0:
            for j in range(1, k1):
                A[f, j] = 0.0
            continue
        dr = xf[f, 0] - cen[d, 0]
        dz = xf[f, 1] - cen[d, 1]
        for j in range(1, k1):
            A[f, j] = F * (grads[d, j, 0] * dr + grads[d, j, 1] * dz)
