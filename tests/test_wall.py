"""Analytic wall: closest-point projection exact (1e-12) near an abrupt corner, on a fillet
arc and on a user profile, on the material side and beyond the wall.

Expected values are worked out by hand from the geometry (comments give the construction);
1e-12 is round-off for coordinates of order 1 m."""

import math

import numpy as np
import pytest

from silo_dolfinx.geometry import outline_from_geometry
from silo_dolfinx.scene import load_geometry

TOL = 1e-12
A = math.radians(20.0)
R, R0, HB = 0.35, 0.1, 4.0
HH = (R - R0) / math.tan(A)  # hopper height
C = np.array([R, HH])  # the transition corner
L_HOP = (R - R0) / math.sin(A)  # hopper wall length
N_HOP = np.array([math.cos(A), -math.sin(A)])  # outward normal of the hopper wall
T_HOP = np.array([math.sin(A), math.cos(A)])


def bin_hopper(fillet=0.0):
    g = load_geometry({"shape": "bin_hopper", "radius": R, "bin_height": HB, "hopper_half_angle": 20.0,
                       "outlet_radius": R0, "fillet_radius": fillet})
    return outline_from_geometry(g).wall


def check(proj, i, distance, closest, normal, s):
    assert abs(proj.distance[i] - distance) < TOL
    assert np.allclose(proj.closest[i], closest, atol=TOL, rtol=0)
    assert np.allclose(proj.normal[i], normal, atol=TOL, rtol=0)
    assert np.allclose(proj.tangent[i], [-normal[1], normal[0]], atol=TOL, rtol=0)
    assert abs(proj.s[i] - s) < TOL


def test_abrupt_corner_both_sides():
    wall = bin_hopper()
    assert abs(wall.length - (L_HOP + HB)) < TOL
    d = 0.05
    pts = np.array([
        C + [-d, 0.01],  # 0: material side, just above the corner: nearest is the bin wall
        C - d * N_HOP - 0.02 * T_HOP,  # 1: material side, below the corner: nearest is the hopper
        C + 0.01 * np.array([math.cos(A / 2), -math.sin(A / 2)]),  # 2: beyond the wall, corner wedge
        C + [0.01, 0.1],  # 3: beyond the bin wall
        C + 0.004 * N_HOP - 0.3 * T_HOP,  # 4: beyond the hopper wall
        C,  # 5: on the corner
    ])
    p = wall.project(pts)
    check(p, 0, d, C + [0, 0.01], [1, 0], L_HOP + 0.01)
    check(p, 1, d, C - 0.02 * T_HOP, N_HOP, L_HOP - 0.02)
    # In the exterior wedge between the two normals the corner itself is nearest: the normal
    # is the direction to the point, the distance negative (penetration).
    check(p, 2, -0.01, C, [math.cos(A / 2), -math.sin(A / 2)], L_HOP)
    check(p, 3, -0.01, C + [0, 0.1], [1, 0], L_HOP + 0.1)
    check(p, 4, -0.004, C - 0.3 * T_HOP, N_HOP, L_HOP - 0.3)
    assert abs(p.distance[5]) < TOL and abs(p.s[5] - L_HOP) < TOL
    # The corner's pseudo-normal bisects the two wall normals.
    assert np.allclose(p.normal[5], [math.cos(A / 2), -math.sin(A / 2)], atol=TOL)


def test_fillet_arc():
    rf = 1.0
    wall = bin_hopper(rf)
    T = rf * math.tan(A / 2)
    centre = np.array([R - rf, HH + T])
    s_arc0 = L_HOP - T  # arclength where the arc starts
    assert abs(wall.length - (L_HOP - T + rf * A + HB - T)) < TOL
    th = -A / 3
    u = np.array([math.cos(th), math.sin(th)])
    pts = np.array([centre + (rf - 0.02) * u, centre + (rf + 0.01) * u])
    p = wall.project(pts)
    s = s_arc0 + rf * (th + A)
    check(p, 0, 0.02, centre + rf * u, u, s)  # inside the material
    check(p, 1, -0.01, centre + rf * u, u, s)  # beyond the wall
    # Tangent points: continuous normal, no corner.
    ends = wall.project(np.array([centre + rf * np.array([math.cos(-A), math.sin(-A)]), centre + [rf, 0]]))
    assert np.allclose(ends.normal[0], N_HOP, atol=TOL) and np.allclose(ends.normal[1], [1, 0], atol=TOL)
    assert wall.corners().shape == (0, 2)


def test_user_profile():
    g = load_geometry({"shape": "profile", "wall": [[0.15, 0.0], [0.6, 0.9], [0.6, 2.0], [0.5, 3.0]],
                       "outlet_radius": 0.05})
    ol = outline_from_geometry(g)
    wall = ol.wall
    assert ol.floor_pieces == 1  # outlet narrower than the first point: a floor is added
    L0, L1 = 0.1, math.hypot(0.45, 0.9)
    v = np.array([0.6, 2.0])  # convex corner of the material (bin -> diverging top)
    t3 = np.array([-0.1, 1.0]) / math.hypot(0.1, 1.0)
    n3 = np.array([t3[1], -t3[0]])
    bis = (np.array([1.0, 0.0]) + n3) / np.linalg.norm(np.array([1.0, 0.0]) + n3)
    pts = np.array([
        [0.1, -0.0],  # 0: on the floor
        [0.1, 0.01],  # 1: above the floor, nearest is the floor (0.01 < distance to the hopper)
        v + 0.02 * bis,  # 2: beyond the wall at the corner
        v + [-0.1, 0.05],  # 3: inside, near the top segment
    ])
    p = wall.project(pts)
    check(p, 0, 0.0, [0.1, 0.0], [0, -1], 0.05)
    check(p, 1, 0.01, [0.1, 0.0], [0, -1], 0.05)
    check(p, 2, -0.02, v, bis, L0 + L1 + 1.1)
    q = v + [-0.1, 0.05]
    foot = v + ((q - v) @ t3) * t3
    check(p, 3, float((foot - q) @ n3), foot, n3, L0 + L1 + 1.1 + float((q - v) @ t3))


@pytest.mark.parametrize("fillet", [0.0, 1.0])
def test_height_and_arclength_are_inverse(fillet):
    wall = bin_hopper(fillet)
    z = np.linspace(0.0, wall.end[1], 37)
    s = wall.s_at_height(z)
    assert np.allclose(wall.point_at(s)[:, 1], z, atol=TOL, rtol=0)
    assert np.all(np.diff(s) > 0)
    # projecting points on the wall returns them, with their arclength
    p = wall.project(wall.point_at(s))
    assert np.allclose(p.distance, 0.0, atol=TOL) and np.allclose(p.s, s, atol=1e-11)


def test_projection_matches_brute_force():
    """Random points against a dense sampling of the wall (independent of the kernel)."""
    wall = bin_hopper(1.0)
    rng = np.random.default_rng(0)
    pts = rng.uniform([0.0, -0.2], [0.6, 5.0], size=(2000, 2))
    p = wall.project(pts)
    dense = wall.point_at(np.linspace(0.0, wall.length, 400_001))  # spacing 1.3e-5 m
    from scipy.spatial import cKDTree

    dist, _ = cKDTree(dense).query(pts)
    # Sampling error of the dense polyline is at most half its spacing (~7e-6 m).
    assert np.allclose(np.abs(p.distance), dist, atol=1e-5, rtol=0)
    assert np.allclose(np.linalg.norm(pts - p.closest, axis=1), np.abs(p.distance), atol=TOL)
    # the sign: positive exactly for points on the material side (inside the silo)
    inside = pts[:, 0] < wall.radius_at(np.clip(pts[:, 1], 0.0, wall.end[1]))
    sel = (pts[:, 1] > 0.0) & (np.abs(p.distance) > 1e-9)
    assert np.array_equal(p.distance[sel] > 0, inside[sel])


@pytest.mark.parametrize("fillet", [0.0, 1.0])
def test_slide_keeps_the_gap_and_reaches_the_arclength(fillet):
    """The ALE smoother's wall rule (wall.slide): a node moved along the wall to a new
    arclength keeps its normal gap; a node beyond the wall lands on it (gap 0)."""
    from silo_dolfinx.geometry.wall import slide

    wall = bin_hopper(fillet)
    s_old = np.array([0.05, 0.3, 0.6, L_HOP - 0.01, 1.5])
    gap = np.array([0.01, 0.0, 0.02, 0.005, -0.003])  # the last one penetrates
    p, n = wall.point_normal_at(s_old)
    pts = p - gap[:, None] * n
    s_new = s_old + np.array([0.1, -0.2, 0.9, 0.03, 5.0])  # across the transition; past the top (clipped)
    out = np.empty_like(pts)
    slide(pts, s_new, *wall.arrays, out)
    q = wall.project(out)
    want_s = np.clip(s_new, 0.0, wall.length)
    assert np.allclose(q.distance, np.maximum(gap, 0.0), atol=TOL, rtol=0)
    # arclength of the foot point; near the abrupt corner a node with a gap projects to the
    # corner itself when it sits in the corner's normal fan, so compare the wall point instead
    assert np.allclose(out + np.maximum(gap, 0.0)[:, None] * wall.point_normal_at(want_s)[1],
                       wall.point_at(want_s), atol=TOL, rtol=0)
