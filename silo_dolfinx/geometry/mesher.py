"""gmsh meshes of a silo outline: quadrilaterals in the (r, z) half-plane, tagged and distributed.

Two strategies, chosen by ``[geometry] mesh``:

``structured`` (default)
    The fill is cut into horizontal bands at every wall vertex, at the fill height, and where
    the requested size stops grading (refinement distance around the outlet edge and the
    transition). Each band is a transfinite quadrilateral block between the axis and one
    wall piece, so wall corners and fillet ends are mesh nodes and every band boundary is a
    mesh line. A flat floor adds a vertical block boundary above the outlet edge, so the
    outlet has its own column of cells. This is the layout of the thesis' meshes (Fig. 4-2).

``unstructured``
    One surface bounded by the axis, outlet, wall and top, meshed by gmsh's frontal-Delaunay
    quadrilateral algorithm with blossom full-quad recombination and a size field (distance
    thresholds around the outlet edge and the transition). Works for any wall, including
    ledges.

In both, the tops of the filling layers are mesh lines (bands / OCC cuts at the layer
heights): a layer activated on a jagged top would leave single cells standing proud of the
fill, which a cohesionless solid cannot support.

Tags (physical groups, names and numbers): cells ``material`` = 1; facets ``wall`` = 1,
``outlet`` = 2, ``top`` = 3, ``axis`` = 4. The mesh is built on rank 0 and distributed by
:func:`dolfinx.io.gmsh.model_to_mesh`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from silo_dolfinx.geometry.shapes import Outline
from silo_dolfinx.geometry.wall import Segment

MATERIAL = 1
WALL, OUTLET, TOP, AXIS = 1, 2, 3, 4
FACET_TAGS = {"wall": WALL, "outlet": OUTLET, "top": TOP, "axis": AXIS}


class MeshingError(ValueError):
    """The geometry cannot be meshed as asked (names the key to change)."""


@dataclass(frozen=True)
class MeshOptions:
    element_size: float
    outlet_size_factor: float = 1.0
    transition_size_factor: float = 1.0
    refinement_distance: float = 1.0
    structured: bool = True
    max_aspect_ratio: float = 2.0
    layer_heights: tuple[float, ...] = ()  # filling-layer boundaries: mesh lines

    @classmethod
    def from_geometry(cls, g, layer_heights=()) -> MeshOptions:
        return cls(g["element_size"], g["outlet_size_factor"], g["transition_size_factor"],
                   g["refinement_distance"], g["mesh"] == "structured", g["max_aspect_ratio"],
                   tuple(layer_heights))

    @classmethod
    def from_scene(cls, scene) -> MeshOptions:
        """Options of a scene: its geometry, with its filling layers' tops as mesh lines."""
        f = scene.fill
        hf = scene.geometry.fill_height
        layers = [hf * k / f.layers for k in range(1, f.layers)] if f.method == "layers" else []
        return cls.from_geometry(scene.geometry, layers)

    def refinement_points(self, outline: Outline) -> list[tuple[float, float, float]]:
        """(r, z, size) of the points around which the mesh is refined."""
        h = self.element_size
        pts = []
        if self.outlet_size_factor < 1.0:
            pts.append((outline.outlet_radius, 0.0, self.outlet_size_factor * h))
        if self.transition_size_factor < 1.0:
            pts += [(r, z, self.transition_size_factor * h) for r, z in outline.transition_points
                    if z <= outline.fill_height]
        return pts

    def outlet_column_cells(self, outline: Outline) -> int:
        """Cells across the outlet in a structured mesh with a floor: the outlet's column, the same
        in every row up the silo (enough for its own refinement and for the widest row)."""
        xi_o = outline.outlet_radius / outline.floor_radius
        return max(1, math.ceil(outline.outlet_radius / (self.element_size * self.outlet_size_factor) - 1e-9),
                   math.ceil(xi_o * outline.r_max / self.element_size - 1e-9))

    def radial_divisions(self, outline: Outline) -> int:
        """Cells across the silo in a structured mesh (without a floor)."""
        return max(2, math.ceil(outline.r_max / self.element_size - 1e-9))

    def size_branches(self, outline: Outline, z: np.ndarray) -> np.ndarray:
        """Candidate vertical sizes at heights z, (branches, len(z)); the size is their minimum.

        Branches: the element size; a linear ramp from each refinement height; and, in
        structured meshes, max_aspect_ratio × the local radial cell size r_wall(z)/n_r, so
        cells in a narrowing hopper do not become needles at the outlet.
        """
        z = np.atleast_1d(np.asarray(z, float))
        rows = [np.full_like(z, self.element_size)]
        for _, zk, hk in self.refinement_points(outline):
            rows.append(hk + (self.element_size - hk) * np.abs(z - zk) / self.refinement_distance)
        if self.structured:
            rw = outline.wall.radius_at(np.maximum(z, 1e-12 * outline.fill_height))
            rows.append(self.max_aspect_ratio * rw / self.radial_divisions(outline))
        return np.array(rows)

    def size_along_z(self, outline: Outline, z) -> np.ndarray:
        return self.size_branches(outline, z).min(axis=0)


# ---------------------------------------------------------------------------- gmsh model
def build_model(outline: Outline, opts: MeshOptions, name: str = "silo") -> None:
    """Create and mesh the silo in the current gmsh session (gmsh must be initialised)."""
    import gmsh

    gmsh.option.setNumber("General.Terminal", 0)
    if opts.structured:
        gmsh.model.add(name)
        _structured(outline, opts)
        gmsh.model.mesh.generate(2)
    else:
        _unstructured_best(outline, opts, name)
    gmsh.model.mesh.setOrder(1)
    if any(t != 3 for t in gmsh.model.mesh.getElementTypes(2)):  # 3 = 4-node quadrilateral
        raise MeshingError("gmsh left non-quadrilateral cells; try [geometry] mesh = \"structured\" or a "
                           "smaller element_size.")


#: Frontal-Delaunay for quads first (the most regular cells); where it leaves a corner farther
#: from 90° than this sine allows (arcsin 0.34 = 20°, or 160°), frontal-Delaunay, then Delaunay
#: triangles recombined. Measured on a 2-m bin with a 0.2-m fillet at h 0.05 m: 0.13 (a 172.5°
#: corner on the fillet) with the first, 0.70 with the second.
UNSTRUCTURED_ALGORITHMS = (8, 6, 5)
UNSTRUCTURED_MIN_SCALED_JACOBIAN = 0.34


def _unstructured_best(outline: Outline, opts: MeshOptions, name: str) -> None:
    """Mesh unstructured with the first of UNSTRUCTURED_ALGORITHMS whose worst corner passes
    UNSTRUCTURED_MIN_SCALED_JACOBIAN (after relocation), else with the one whose worst corner
    is best; the mesh is left in the current gmsh model."""
    import gmsh

    best = None
    for algorithm in UNSTRUCTURED_ALGORITHMS:
        sj = _unstructured_attempts(outline, opts, name, algorithm)
        if sj >= UNSTRUCTURED_MIN_SCALED_JACOBIAN:
            return
        if sj > -np.inf and (best is None or sj > best[1]):
            best = (algorithm, sj)
        gmsh.model.remove()
    if best is None:
        raise MeshingError("gmsh could not mesh the silo in quadrilaterals; try [geometry] mesh = \"structured\" "
                           "or another element_size.")
    _unstructured_attempts(outline, opts, name, best[0])


def _unstructured_attempts(outline: Outline, opts: MeshOptions, name: str, algorithm: int) -> float:
    """Mesh in quadrilaterals with gmsh's ``algorithm`` and relocate the nodes; returns the
    worst corner's scaled Jacobian (−inf, and no model left, if no attempt gave all quads)."""
    import gmsh

    from silo_dolfinx.geometry.quality import corner_measures
    from silo_dolfinx.geometry.relocate import gmsh_mesh, relocate_gmsh_model

    # Blossom full-quad gives the best cells but needs an even edge count on every curve;
    # plain blossom may leave a triangle; subdivision (at twice the size) never does.
    attempts = ({"Mesh.RecombinationAlgorithm": 3, "Mesh.SubdivisionAlgorithm": 0}, 1.0), \
               ({"Mesh.RecombinationAlgorithm": 1, "Mesh.SubdivisionAlgorithm": 0}, 1.0), \
               ({"Mesh.RecombinationAlgorithm": 1, "Mesh.SubdivisionAlgorithm": 1}, 2.0)
    for options, scale in attempts:
        gmsh.model.add(name)
        _unstructured(outline, opts, scale, algorithm)
        for k, v in options.items():
            gmsh.option.setNumber(k, v)
        try:
            gmsh.model.mesh.generate(2)
            if all(t == 3 for t in gmsh.model.mesh.getElementTypes(2)):
                # even out the cells the front left small: they set Δt (geometry.relocate)
                relocate_gmsh_model()
                _, x, cn, _ = gmsh_mesh()
                return float(corner_measures(x[cn])[0].min())
        except Exception:  # noqa: BLE001 - gmsh raises bare Exception; try the next way
            pass
        gmsh.model.remove()
    return -np.inf


def _wall_pieces_between(outline: Outline, za: float, zb: float):
    """The wall pieces (clipped) spanning heights [za, zb] on the rising part of the wall."""
    wall = outline.wall
    sa, sb = wall.s_at_height([za, zb])
    out = []
    for i, p in enumerate(wall.pieces):
        s0 = wall._s0[i]
        s1 = s0 + p.length
        if p.end[1] <= p.start[1]:
            continue  # floor
        lo, hi = max(s0, sa), min(s1, sb)
        if hi - lo > 1e-12 * max(1.0, wall.length):
            out.append((p, lo, hi))
    return out


def _band_heights(outline: Outline, opts: MeshOptions) -> list[float]:
    """Band boundaries: wall vertices, fill height, and the ends of every size ramp."""
    hf = outline.fill_height
    zs = {0.0, hf} | {z for z in opts.layer_heights if 0.0 < z < hf}
    for p in outline.wall.pieces:
        if p.end[1] > p.start[1]:
            zs |= {p.start[1], p.end[1]}
    rho = opts.refinement_distance
    ramps = [zk for _, zk, _ in opts.refinement_points(outline)]
    for zk in ramps:
        zs |= {zk, zk - rho, zk + rho}
    for a in ramps:  # where two ramps meet (a local maximum of the size)
        for b in ramps:
            if a < b and b - a < 2 * rho:
                zs.add(0.5 * (a + b))
    # Where the governing size rule changes, so each band's size is one linear branch.
    zz = np.linspace(0.0, hf, 4001)
    which = opts.size_branches(outline, zz).argmin(axis=0)
    for i in np.nonzero(np.diff(which))[0]:
        lo, hi = zz[i], zz[i + 1]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if opts.size_branches(outline, mid).argmin(axis=0)[0] == which[i]:
                lo = mid
            else:
                hi = mid
        zs.add(0.5 * (lo + hi))
    zs = sorted(z for z in zs if 0.0 <= z <= hf)
    merged = [zs[0]]
    tol = 1e-3 * opts.element_size * min(1.0, min(opts.outlet_size_factor, opts.transition_size_factor))
    for z in zs[1:]:
        if z - merged[-1] > tol:
            merged.append(z)
        else:
            merged[-1] = z if z in (hf,) else merged[-1]
    return merged


def _progression(length: float, ha: float, hb: float) -> tuple[int, float]:
    """Number of elements and gmsh progression ratio for sizes ha -> hb over length."""
    if abs(hb - ha) < 1e-9 * max(ha, hb):
        n = max(1, round(length / ha))
        return n, 1.0
    integral = length * math.log(hb / ha) / (hb - ha)  # ∫ dz / h(z) for linear h
    n = max(1, round(integral))
    q = (hb / ha) ** (1.0 / (n - 1)) if n > 1 else 1.0
    return n, q


def _structured(outline: Outline, opts: MeshOptions) -> None:
    import gmsh

    geo = gmsh.model.geo
    h = opts.element_size
    for p in outline.wall.pieces:
        if p.end[1] == p.start[1] and p.start[1] > 0.0:
            raise MeshingError("[geometry] mesh = \"structured\" needs a wall that rises in every piece "
                               f"above the floor; the piece {p.start} -> {p.end} is horizontal. Fix: "
                               "mesh = \"unstructured\".")
    zs = _band_heights(outline, opts)
    rf = outline.floor_radius
    has_floor = outline.has_floor
    xi_o = outline.outlet_radius / rf  # fraction of each row inside the outlet column

    # Radial divisions. Without a floor all rows have n_r cells; with one, the outlet column
    # gets n_in and the rest n_out, graded towards the outlet edge.
    rmax = outline.r_max
    if has_floor:
        h_edge = h * opts.outlet_size_factor
        n_in = opts.outlet_column_cells(outline)
        n_out, q_out = _progression(rf - outline.outlet_radius, h_edge, h)
        n_top = math.ceil((1.0 - xi_o) * rmax / h - 1e-9)
        if n_top > n_out:
            n_out, q_out = n_top, 1.0
    else:
        n_r = opts.radial_divisions(outline)

    axis_pts, split_pts, wall_pts = [], [], []
    center_tags: dict[tuple[float, float], int] = {}
    for z in zs:
        rw = float(outline.wall.radius_at(z)[0]) if z > 0.0 else rf
        axis_pts.append(geo.addPoint(0.0, z, 0.0))
        split_pts.append(geo.addPoint(xi_o * rw, z, 0.0) if has_floor else None)
        wall_pts.append(geo.addPoint(rw, z, 0.0))
    # horizontal lines (bottom row: outlet [+ floor])
    horiz_in, horiz_out = [], []
    for k in range(len(zs)):
        if has_floor:
            horiz_in.append(geo.addLine(axis_pts[k], split_pts[k]))
            horiz_out.append(geo.addLine(split_pts[k], wall_pts[k]))
        else:
            horiz_in.append(geo.addLine(axis_pts[k], wall_pts[k]))
    axis_lines, split_lines, wall_lines, surfaces = [], [], [], []
    for k in range(len(zs) - 1):
        za, zb = zs[k], zs[k + 1]
        ha, hb = opts.size_along_z(outline, [za, zb])
        n_z, q_z = _progression(zb - za, float(ha), float(hb))
        a_line = geo.addLine(axis_pts[k], axis_pts[k + 1])
        pieces = _wall_pieces_between(outline, za, zb)
        if len(pieces) != 1:
            raise MeshingError(f"band {za:g}..{zb:g} m does not hold exactly one wall piece")
        piece = pieces[0][0]
        if isinstance(piece, Segment):
            w_line = geo.addLine(wall_pts[k], wall_pts[k + 1])
        else:
            c = piece.center
            if c not in center_tags:
                center_tags[c] = geo.addPoint(c[0], c[1], 0.0)
            w_line = geo.addCircleArc(wall_pts[k], center_tags[c], wall_pts[k + 1])
        axis_lines.append(a_line)
        wall_lines.append(w_line)
        for ln in (a_line, w_line):
            geo.mesh.setTransfiniteCurve(ln, n_z + 1, "Progression", q_z)
        if has_floor:
            s_line = geo.addLine(split_pts[k], split_pts[k + 1])
            split_lines.append(s_line)
            geo.mesh.setTransfiniteCurve(s_line, n_z + 1, "Progression", q_z)
            loop_in = geo.addCurveLoop([horiz_in[k], s_line, -horiz_in[k + 1], -a_line])
            loop_out = geo.addCurveLoop([horiz_out[k], w_line, -horiz_out[k + 1], -s_line])
            surfaces += [geo.addPlaneSurface([loop_in]), geo.addPlaneSurface([loop_out])]
        else:
            loop = geo.addCurveLoop([horiz_in[k], w_line, -horiz_in[k + 1], -a_line])
            surfaces.append(geo.addPlaneSurface([loop]))
    for k in range(len(zs)):
        if has_floor:
            geo.mesh.setTransfiniteCurve(horiz_in[k], n_in + 1)
            geo.mesh.setTransfiniteCurve(horiz_out[k], n_out + 1, "Progression", q_out)
        else:
            geo.mesh.setTransfiniteCurve(horiz_in[k], n_r + 1)
    for s in surfaces:
        geo.mesh.setTransfiniteSurface(s)
        geo.mesh.setRecombine(2, s)
    geo.synchronize()
    wall_curves = list(wall_lines) + ([horiz_out[0]] if has_floor else [])
    gmsh.model.addPhysicalGroup(2, surfaces, MATERIAL, "material")
    gmsh.model.addPhysicalGroup(1, wall_curves, WALL, "wall")
    gmsh.model.addPhysicalGroup(1, [horiz_in[0]], OUTLET, "outlet")
    gmsh.model.addPhysicalGroup(1, [horiz_in[-1]] + ([horiz_out[-1]] if has_floor else []), TOP, "top")
    gmsh.model.addPhysicalGroup(1, axis_lines, AXIS, "axis")


def _unstructured(outline: Outline, opts: MeshOptions, scale: float = 1.0, algorithm: int = 8) -> None:
    """One OCC surface bounded by the axis, outlet, wall and top, cut by horizontal lines at
    the filling-layer heights (so every layer's top is a mesh line), meshed in quadrilaterals
    under a size field by gmsh's ``algorithm`` (8: frontal-Delaunay for quads). Boundary
    curves are tagged by position."""
    import gmsh

    occ = gmsh.model.occ
    hf = outline.fill_height
    h = opts.element_size * scale
    wall = outline.wall
    s_top = outline.wall_length_below_fill
    p_axis0 = occ.addPoint(0.0, 0.0, 0.0)
    p_out = occ.addPoint(outline.outlet_radius, 0.0, 0.0)
    curves = [occ.addLine(p_axis0, p_out)]
    prev = p_out
    for i, p in enumerate(wall.pieces):
        s0 = wall._s0[i]
        if s0 >= s_top - 1e-12:
            break
        s1 = min(s0 + p.length, s_top)
        end_xy = wall.point_at(s1)[0]
        nxt = occ.addPoint(float(end_xy[0]), float(end_xy[1]), 0.0)
        if isinstance(p, Segment):
            curves.append(occ.addLine(prev, nxt))
        else:
            c = occ.addPoint(p.center[0], p.center[1], 0.0)
            curves.append(occ.addCircleArc(prev, c, nxt))
        prev = nxt
    top_curves = []
    if outline.surface is None:  # the flat top of the fill
        p_axis1 = occ.addPoint(0.0, hf, 0.0)
        top_curves.append(occ.addLine(prev, p_axis1))
    else:  # a free surface through the given points (axis first): one curve, meshed at the size field
        pts = [prev] + [occ.addPoint(float(r), float(z), 0.0) for r, z in outline.surface[-2::-1]]
        top_curves.append(occ.addSpline(pts) if len(pts) > 2 else occ.addLine(*pts))
        p_axis1 = pts[-1]
    curves += top_curves + [occ.addLine(p_axis1, p_axis0)]
    surf = occ.addPlaneSurface([occ.addCurveLoop(curves)])
    cuts = [z for z in opts.layer_heights if 1e-9 * hf < z < hf * (1 - 1e-9)]
    if cuts and outline.surface is not None:
        raise MeshingError("filling-layer cuts and a free-surface polyline together: a rezoned mesh has no layers")
    if cuts:
        rmax = 2.0 * outline.r_max + 1.0
        lines = [occ.addLine(occ.addPoint(-1.0, z, 0.0), occ.addPoint(rmax, z, 0.0)) for z in cuts]
        occ.fragment([(2, surf)], [(1, ln) for ln in lines])
    refine = [occ.addPoint(r, z, 0.0) for r, z, _ in opts.refinement_points(outline)]
    occ.synchronize()
    surfaces = [t for _, t in gmsh.model.getEntities(2)]
    # drop the parts of the cutting lines outside the silo
    boundary = {abs(t) for _, t in gmsh.model.getBoundary([(2, t) for t in surfaces], combined=True, oriented=False)}
    tol = 1e-6 * max(hf, outline.r_max)  # OCC pads bounding boxes by ~1e-7
    groups = {"wall": [], "outlet": [], "top": [], "axis": []}
    for c in boundary:
        xmin, zmin, _, xmax, zmax, _ = gmsh.model.getBoundingBox(1, c)
        if xmax < tol:
            groups["axis"].append(c)
        elif zmax < tol and xmax <= outline.outlet_radius + tol:
            groups["outlet"].append(c)
        elif (c in top_curves) if outline.surface is not None else zmin > hf - tol:
            groups["top"].append(c)
        else:
            groups["wall"].append(c)
    fields = []
    for pt, (r, z, hk) in zip(refine, opts.refinement_points(outline)):
        d = gmsh.model.mesh.field.add("Distance")
        gmsh.model.mesh.field.setNumbers(d, "PointsList", [pt])
        t = gmsh.model.mesh.field.add("Threshold")
        gmsh.model.mesh.field.setNumber(t, "InField", d)
        gmsh.model.mesh.field.setNumber(t, "SizeMin", hk * scale)
        gmsh.model.mesh.field.setNumber(t, "SizeMax", h)
        gmsh.model.mesh.field.setNumber(t, "DistMin", 0.0)
        gmsh.model.mesh.field.setNumber(t, "DistMax", opts.refinement_distance)
        fields.append(t)
    const = gmsh.model.mesh.field.add("MathEval")
    gmsh.model.mesh.field.setString(const, "F", repr(h))
    fields.append(const)
    fmin = gmsh.model.mesh.field.add("Min")
    gmsh.model.mesh.field.setNumbers(fmin, "FieldsList", fields)
    gmsh.model.mesh.field.setAsBackgroundMesh(fmin)
    for k, v in {"Mesh.MeshSizeExtendFromBoundary": 0, "Mesh.MeshSizeFromPoints": 0,
                 "Mesh.MeshSizeFromCurvature": 0, "Mesh.Algorithm": algorithm, "Mesh.RecombineAll": 1,
                 "Mesh.Smoothing": 10}.items():
        gmsh.option.setNumber(k, v)
    for sf in surfaces:
        gmsh.model.mesh.setRecombine(2, sf)
    gmsh.model.addPhysicalGroup(2, surfaces, MATERIAL, "material")
    for name, tag in FACET_TAGS.items():
        gmsh.model.addPhysicalGroup(1, sorted(groups[name]), tag, name)


# ---------------------------------------------------------------------------- dolfinx
@dataclass
class SiloMesh:
    """A distributed silo mesh with its tags and the exact geometry it discretises."""

    mesh: object  # dolfinx.mesh.Mesh
    cell_tags: object
    facet_tags: object
    outline: Outline

    @property
    def comm(self):
        return self.mesh.comm

    def num_cells_global(self) -> int:
        im = self.mesh.topology.index_map(2)
        return im.size_global

    def volume_of_revolution(self) -> float:
        """2π ∫ r dA over the mesh (current coordinates)."""
        import ufl
        from dolfinx import fem

        x = ufl.SpatialCoordinate(self.mesh)
        form = fem.form(2 * math.pi * x[0] * ufl.dx(domain=self.mesh))
        return self.comm.allreduce(fem.assemble_scalar(form), op=_mpi_sum())

    def facets(self, name: str) -> np.ndarray:
        """Local indices of the facets tagged ``name`` (wall, outlet, top, axis)."""
        return self.facet_tags.find(FACET_TAGS[name])

    def shortest_facet(self, name: str) -> float:
        """Length of the shortest facet tagged ``name`` over all ranks (0 if there is none)."""
        from dolfinx import mesh as dmesh
        from mpi4py import MPI

        facets = self.facets(name)
        local = np.inf
        if len(facets):
            x = self.mesh.geometry.x
            nodes = dmesh.entities_to_geometry(self.mesh, self.mesh.topology.dim - 1, facets)
            local = float(np.linalg.norm(x[nodes[:, 1], :2] - x[nodes[:, 0], :2], axis=1).min())
        edge = self.mesh.comm.allreduce(local, op=MPI.MIN)
        return edge if np.isfinite(edge) else 0.0

    def outlet_cells(self) -> int:
        """Cells across the outlet radius: its facets over all ranks, each counted once
        (collective)."""
        from mpi4py import MPI

        owned = self.mesh.topology.index_map(self.mesh.topology.dim - 1).size_local
        return self.comm.allreduce(int(np.sum(self.facets("outlet") < owned)), op=MPI.SUM)

    def nodes_on(self, name: str) -> np.ndarray:
        """Local geometry-node indices on the facets tagged ``name`` (owned and ghost)."""
        from dolfinx import mesh as dmesh

        m = self.mesh
        m.topology.create_connectivity(1, 0)
        verts = dmesh.compute_incident_entities(m.topology, self.facets(name), 1, 0)
        return _vertex_to_node(m, verts)


def _vertex_to_node(m, verts: np.ndarray) -> np.ndarray:
    """Map topology vertices to geometry nodes (Q1: one node per vertex)."""
    from dolfinx import mesh as dmesh

    m.topology.create_connectivity(0, m.topology.dim)
    return np.unique(dmesh.entities_to_geometry(m, 0, np.asarray(verts, np.int32)).ravel())


def _mpi_sum():
    from mpi4py import MPI

    return MPI.SUM


def create_mesh(outline: Outline, opts: MeshOptions, comm, *, msh_path: str | Path | None = None,
                rank: int = 0) -> SiloMesh:
    """Mesh the silo with gmsh on ``rank`` and distribute it over ``comm``."""
    import gmsh
    from dolfinx.io import gmsh as dgmsh

    error = None
    if comm.rank == rank:
        started = gmsh.is_initialized()
        if not started:
            gmsh.initialize(interruptible=False)
        gmsh.option.setNumber("General.Terminal", 0)
        try:
            build_model(outline, opts)
            if msh_path is not None:
                Path(msh_path).parent.mkdir(parents=True, exist_ok=True)
                gmsh.write(str(msh_path))
        except Exception as e:  # broadcast so no rank waits forever
            error = e
    error = comm.bcast(error, root=rank)
    if error is not None:
        if comm.rank == rank and not started:
            gmsh.finalize()
        raise error
    from silo_dolfinx._compat import facet_ghost_partitioner

    data = dgmsh.model_to_mesh(gmsh.model, comm, rank, gdim=2, partitioner=facet_ghost_partitioner())
    if comm.rank == rank:
        gmsh.model.remove()
        if not started:
            gmsh.finalize()
    sm = SiloMesh(data.mesh, data.cell_tags, data.facet_tags, outline)
    return sm


def read_mesh(path: str | Path, outline: Outline, comm, *, rank: int = 0) -> SiloMesh:
    """Read a user's gmsh mesh and check that it is a silo that fits ``outline``."""
    from dolfinx import mesh as dmesh
    from dolfinx.io import gmsh as dgmsh

    path = Path(path)
    if not path.is_file():
        raise MeshingError(f"[geometry] mesh_file = {str(path)!r}: file not found. Fix: check the path, "
                           "or remove mesh_file to mesh the geometry with gmsh.")
    from silo_dolfinx._compat import facet_ghost_partitioner

    problem = comm.bcast(_msh_problem(path) if comm.rank == rank else None, root=rank)
    if problem:
        raise MeshingError(f"[geometry] mesh_file = {path.name!r}: {problem}")
    data = dgmsh.read_from_msh(str(path), comm, rank, gdim=2, partitioner=facet_ghost_partitioner())
    m = data.mesh
    if m.topology.cell_type != dmesh.CellType.quadrilateral:
        raise MeshingError(f"[geometry] mesh_file = {path.name!r}: cells are {m.topology.cell_type.name}, "
                           "not quadrilaterals. Fix: recombine the mesh in gmsh (Mesh.RecombineAll = 1).")
    groups = data.physical_groups
    missing = [n for n in ("material", *FACET_TAGS) if n not in groups]
    if missing:
        raise MeshingError(f"[geometry] mesh_file = {path.name!r}: physical groups {missing} are missing "
                           "(needed: material, wall, outlet, top, axis). Fix: add them in the gmsh script "
                           "(see meshes/*.py).")
    # Re-number facet tags to our convention, by physical name.
    ft = data.facet_tags
    idx, val = [], []
    for name, tag in FACET_TAGS.items():
        f = ft.find(groups[name].tag)
        idx.append(f)
        val.append(np.full(f.size, tag, np.int32))
    idx = np.concatenate(idx)
    order = np.argsort(idx)
    facet_tags = dmesh.meshtags(m, 1, idx[order].astype(np.int32), np.concatenate(val)[order])
    sm = SiloMesh(m, data.cell_tags, facet_tags, outline)
    check_fits(sm)
    return sm


def _msh_problem(path: Path) -> str | None:
    """Why gmsh's file ``path`` cannot be a silo mesh (unreadable, not 2D, off the plane), or None.
    Checked with gmsh on one rank before DOLFINx reads it, whose own errors name neither."""
    import gmsh

    started = gmsh.is_initialized()
    if not started:
        gmsh.initialize(interruptible=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("silo_dolfinx_mesh_file_check")
    try:
        try:
            gmsh.merge(str(path))
        except Exception as e:  # gmsh raises a bare Exception with its parser's message
            return f"gmsh cannot read it ({e}). Fix: give a gmsh .msh file (see meshes/*.py)."
        dim = gmsh.model.getDimension()
        if dim != 2:
            return (f"it is a {dim}D mesh; a silo is meshed in its (r, z) half-plane: a 2D mesh of quadrilaterals "
                    "with x = r, y = z. Fix: mesh the meridian section (see meshes/*.py).")
        _, xyz, _ = gmsh.model.mesh.getNodes()
        if xyz.size and float(np.abs(xyz[2::3]).max()) > 0.0:
            return ("its nodes leave the plane z = 0 (gmsh's third coordinate); the mesh must lie in the (r, z) "
                    "half-plane as x = r, y = z. Fix: draw the section in the x-y plane.")
        return None
    finally:
        gmsh.model.remove()
        if not started:
            gmsh.finalize()


def check_fits(sm: SiloMesh, rel_tol: float = 1e-6) -> None:
    """Raise MeshingError unless the mesh lies inside the wall and its wall nodes lie on it."""
    m = sm.mesh
    x = m.geometry.x
    comm = m.comm
    scale = max(sm.outline.r_max, sm.outline.fill_height)
    tol = rel_tol * scale
    proj = sm.outline.wall.project(x)
    worst_in = comm.allreduce(float(proj.distance.min(initial=np.inf)), op=_mpi_min())
    wall_nodes = sm.nodes_on("wall")
    off = np.abs(proj.distance[wall_nodes]).max(initial=0.0)
    worst_off = comm.allreduce(float(off), op=_mpi_max())
    rmin = comm.allreduce(float(x[:, 0].min(initial=np.inf)), op=_mpi_min())
    if rmin < -tol:
        raise MeshingError(f"mesh is not a silo: it has nodes at r = {rmin:.3g} < 0. Fix: the (r, z) mesh "
                           "must lie in r ≥ 0 with the axis at r = 0.")
    if worst_in < -tol:
        raise MeshingError(f"the wall crosses the material: a mesh node lies {-worst_in:.3g} m beyond the "
                           "wall described by [geometry]. Fix: make the geometry keys match the mesh "
                           "(or remesh with silo mesh).")
    if worst_off > max(tol, 1e-3 * scale):
        raise MeshingError(f"mesh nodes tagged 'wall' lie up to {worst_off:.3g} m off the wall described "
                           "by [geometry]. Fix: make the geometry keys match the mesh.")


def _mpi_min():
    from mpi4py import MPI

    return MPI.MIN


def _mpi_max():
    from mpi4py import MPI

    return MPI.MAX


def mesh_scene(scene, comm, *, msh_path: str | Path | None = None) -> SiloMesh:
    """The mesh a scene asks for: its ``mesh_file`` if given, else a gmsh mesh of its geometry."""
    g = scene.geometry
    if g.mesh_file:
        path = Path(g.mesh_file)
        if not path.is_absolute() and scene.source is not None:
            path = scene.source.parent / path
        return read_mesh(path, scene.outline, comm)
    sm = create_mesh(scene.outline, MeshOptions.from_scene(scene), comm, msh_path=msh_path)
    return sm


def mesh_geometry(geometry: dict, msh_path: str | Path, comm=None, *, show: bool = True) -> SiloMesh:
    """Validate a [geometry] dict, mesh it, write ``msh_path`` (and a PNG next to it).

    This is what the scripts in ``meshes/`` call: edit their GEOMETRY dict for a new silo.
    """
    from mpi4py import MPI

    from silo_dolfinx.geometry.plot import plot_mesh
    from silo_dolfinx.geometry.quality import quality_report
    from silo_dolfinx.geometry.shapes import outline_from_geometry
    from silo_dolfinx.scene.loader import load_geometry

    comm = MPI.COMM_WORLD if comm is None else comm
    g = load_geometry(geometry)
    outline = outline_from_geometry(g)
    sm = create_mesh(outline, MeshOptions.from_geometry(g), comm, msh_path=msh_path)
    q = quality_report(sm.mesh)
    if show:
        plot_mesh(sm, Path(msh_path).with_suffix(".png"), title=f"{Path(msh_path).stem}: {q['cells']} cells")
    if comm.rank == 0:
        vol, exact = sm.volume_of_revolution(), outline.volume()
        print(f"{msh_path}: {q['cells']} cells, volume {vol:.6g} m³ (exact {exact:.6g}), "
              f"corner angles {q['min_angle_deg']:.1f}-{q['max_angle_deg']:.1f}°, inverted {q['inverted']}")
    else:
        sm.volume_of_revolution()
    return sm
