"""Stress invariants — in one place (tension positive; p compression positive).

    p = −tr σ / 3,   s = σ − (tr σ / 3) I,   J2 = ½ s:s (with the rz shear counted twice),
    q = √(3 J2)

for the axisymmetric 4-vectors (rr, zz, θθ, rz). Point versions are numba functions that
inline into the kernels (the material laws, the energy); :func:`p_q` is the vectorised one
for output and analysis.
"""

from __future__ import annotations

import math

import numpy as np

from silo_dolfinx._jit_cache import numba


@numba.njit(cache=True, inline="always")
def mean_j2(s):
    """(tr σ/3, J2) of one stress."""
    m = (s[0] + s[1] + s[2]) / 3.0
    j2 = 0.5 * ((s[0] - m) ** 2 + (s[1] - m) ** 2 + (s[2] - m) ** 2) + s[3] ** 2
    return m, j2


@numba.njit(cache=True)
def invariants(s):
    """(p, q, deviator) of one stress: p = −tr σ/3 (compression +), q = √(3 J2)."""
    m = (s[0] + s[1] + s[2]) / 3.0
    d0, d1, d2, d3 = s[0] - m, s[1] - m, s[2] - m, s[3]
    j2 = 0.5 * (d0 * d0 + d1 * d1 + d2 * d2) + d3 * d3
    return -m, math.sqrt(3.0 * j2), d0, d1, d2, d3


@numba.njit(cache=True, inline="always")
def deviator_q_p(t0, t1, t2, t3):
    """Deviator (normal components), q and p of a stress given by its four components (the
    return map's hot loop works in scalars)."""
    m = (t0 + t1 + t2) * (1.0 / 3.0)
    d0, d1, d2 = t0 - m, t1 - m, t2 - m
    q = math.sqrt(1.5 * (d0 * d0 + d1 * d1 + d2 * d2) + 3.0 * t3 * t3)
    return d0, d1, d2, q, -m


@numba.njit(cache=True, inline="always")
def principal(s0, s1, s2, s3):
    """Principal stresses a ≥ b ≥ k of an axisymmetric stress (rr, zz, θθ, rz) and what
    :func:`from_principal` needs to rebuild the components on the same axes: cos 2θ, sin 2θ of
    the in-plane axes and where the hoop stress (itself principal) went: 0 → k, 1 → b, 2 → a."""
    c = 0.5 * (s0 + s1)
    h = 0.5 * (s0 - s1)
    r = math.sqrt(h * h + s3 * s3)
    cs, sn = (h / r, s3 / r) if r > 0.0 else (1.0, 0.0)
    v0, v1 = c + r, c - r  # in plane, v0 ≥ v1
    if s2 <= v1:
        return v0, v1, s2, cs, sn, 0
    if s2 <= v0:
        return v0, s2, v1, cs, sn, 1
    return s2, v0, v1, cs, sn, 2


@numba.njit(cache=True, inline="always")
def from_principal(a, b, k, cs, sn, hoop):
    """The components (rr, zz, θθ, rz) of principal values a, b, k on the axes
    :func:`principal` returned (``hoop``: which of them is θθ)."""
    if hoop == 0:
        w0, w1, w2 = a, b, k
    elif hoop == 1:
        w0, w2, w1 = a, b, k
    else:
        w2, w0, w1 = a, b, k
    cn, rn = 0.5 * (w0 + w1), 0.5 * (w0 - w1)
    return cn + rn * cs, cn - rn * cs, w2, rn * sn


STRESS_FREE = 1e-3  # a mean pressure below this × ρ g H: the solid is all but stress-free


def stress_free_pressure(density: float, gravity: float, height: float) -> float:
    """The mean pressure below which a cell counts as stress-free: the weight of a thousandth of
    the fill's height (2.6 Pa... 26 Pa in the thesis' silos). Below it the solid has separated -
    stretched to the cone's apex (q = 0, p = −c/tan β), as in the free-fall zone over an outlet
    or a crater - and q/p is the ratio of two numbers near zero."""
    return STRESS_FREE * density * gravity * height


def stress_ratio(p, q, p_min: float) -> np.ndarray:
    """q/p (eq. 4-11), NaN where p ≤ p_min (:func:`stress_free_pressure`): undefined, not 0 -
    a separated cell at the apex is on the yield surface, not far from it, and drawing it as
    0 beside its neighbours on the cone (q/p = tan β) showed as a checkerboard above outlets."""
    p = np.asarray(p, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(p > p_min, np.asarray(q, float) / p, np.nan)


def p_q(sig) -> tuple[np.ndarray, np.ndarray]:
    """(p, q) of (n, 4) stresses."""
    s = np.atleast_2d(np.asarray(sig, float))
    m = s[:, :3].mean(axis=1)
    d = s[:, :3] - m[:, None]
    j2 = 0.5 * (d**2).sum(axis=1) + s[:, 3] ** 2
    return -m, np.sqrt(3.0 * j2)


def principal_values(sig) -> np.ndarray:
    """(n, 3) principal stresses a ≥ b ≥ k of (n, 4) stresses (tension +): the vectorised
    :func:`principal` for output and analysis (the in-plane pair from the Mohr circle, the hoop
    stress itself principal)."""
    s = np.atleast_2d(np.asarray(sig, float))
    centre = 0.5 * (s[:, 0] + s[:, 1])
    radius = np.hypot(0.5 * (s[:, 0] - s[:, 1]), s[:, 3])
    return -np.sort(-np.stack([centre + radius, centre - radius, s[:, 2]], axis=1), axis=1)
