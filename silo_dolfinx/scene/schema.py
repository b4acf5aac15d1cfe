"""The scene schema: every section and key a scene file may hold, with units, ranges and defaults.

This table is the single source of truth: the loader validates against it, ``silo check``
prints defaults from it, and ``docs/scene.md`` is generated from it
(``silo schema > docs/scene.md``; a test keeps the two in sync).

Conventions: SI units, angles in degrees, heights measured upwards from the outlet (or from
the flat bottom), radii from the axis. Sections with a *selector* key (``geometry.shape``,
``material.model``, ``wall.friction``, ``fill.method``, ``discharge.mode``) take the
common keys plus the keys of the selected variant.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


class _Sentinel:
    def __init__(self, name: str):
        self.name = name

    def __repr__(self) -> str:
        return self.name


REQUIRED = _Sentinel("REQUIRED")
DERIVED = _Sentinel("DERIVED")  # filled in by the loader from other keys (documented per key)


@dataclass(frozen=True)
class Key:
    name: str
    kind: str  # float | int | bool | str | choice | floats | strings | points | locations
    default: Any = REQUIRED
    unit: str = ""
    doc: str = ""
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple = ()
    length: int | None = None  # for floats
    example: Any = None

    def range_text(self) -> str:
        """Human-readable allowed range, e.g. '> 0 kg/m³' or 'in (-1, 0.5)'."""
        u = f" {self.unit}" if self.unit and self.unit != "-" else ""
        if self.kind == "choice":
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.lo is not None and self.hi is not None:
            lb = "(" if self.lo_open else "["
            rb = ")" if self.hi_open else "]"
            return f"in {lb}{_num(self.lo)}, {_num(self.hi)}{rb}{u}"
        if self.lo is not None:
            return f"{'>' if self.lo_open else '≥'} {_num(self.lo)}{u}"
        if self.hi is not None:
            return f"{'<' if self.hi_open else '≤'} {_num(self.hi)}{u}"
        return {"bool": "true or false", "str": "a string", "strings": "a list of strings (may be empty)",
                "points": "a list of [r, z] pairs",
                "locations": "a list of [r, z] pairs (may be empty)"}.get(
            self.kind, f"a {self.kind}"
        )

    def example_value(self) -> Any:
        if self.example is not None:
            return self.example
        if self.default not in (REQUIRED, DERIVED):
            return self.default
        if self.kind == "choice":
            return self.choices[0]
        if self.lo is not None and self.hi is not None:
            return 0.5 * (self.lo + self.hi)
        return 1.0


def _num(x: float) -> str:
    return f"{x:g}"


@dataclass(frozen=True)
class Section:
    name: str
    doc: str
    keys: tuple[Key, ...] = ()
    selector: str | None = None
    variants: dict[str, tuple[Key, ...]] = field(default_factory=dict)

    def keys_for(self, variant: str | None) -> tuple[Key, ...]:
        return self.keys + (self.variants.get(variant, ()) if variant is not None else ())

    def all_key_names(self) -> set[str]:
        names = {k.name for k in self.keys}
        for ks in self.variants.values():
            names |= {k.name for k in ks}
        return names


def F(name, default=REQUIRED, unit="", doc="", **kw) -> Key:
    return Key(name, "float", default, unit, doc, **kw)


def I(name, default=REQUIRED, unit="-", doc="", **kw) -> Key:  # noqa: E743
    return Key(name, "int", default, unit, doc, **kw)


def C(name, choices, default=REQUIRED, doc="") -> Key:
    return Key(name, "choice", default, "", doc, choices=tuple(choices))


POS = dict(lo=0.0, lo_open=True)
NONNEG = dict(lo=0.0)
# Upper bounds guard typos (a length in mm written as m, an exponent off by ten): no silo this
# code is meant for has a dimension above a kilometre.
LENGTH = dict(lo=0.0, lo_open=True, hi=1000.0)
DURATION = dict(lo=0.0, hi=1.0e6)  # s of simulated time: 11 days; a silo empties in minutes

# ---------------------------------------------------------------------------- top level
TOP_KEYS: tuple[Key, ...] = (
    Key("title", "str", "", doc="Name of the run (default: the scene file's name)."),
    Key("description", "str", "", doc="Free text: what the scene reproduces, assumptions made."),
    Key(
        "base",
        "str",
        "",
        doc="Another scene file (path relative to this one) whose keys this scene starts from; "
        "keys given here override it. Used for variants of one study.",
    ),
)

# ---------------------------------------------------------------------------- sections
_radius_out = F("outlet_radius", unit="m", doc="Radius of the central outlet.", **LENGTH, example=0.1)

GEOMETRY = Section(
    "geometry",
    "The silo in the (r, z) half-plane. `shape` selects the keys; `profile` takes any wall.",
    keys=(
        C("shape", ("hopper", "flat_bottom", "bin_hopper", "column", "profile"),
          doc="hopper: conical hopper; flat_bottom: cylinder on a flat floor with a central "
          "outlet; bin_hopper: cylinder on a conical hopper, abrupt or filleted transition; "
          "column: tapered column whose whole base is the outlet; profile: your own wall."),
        F("fill_height", DERIVED, "m", "Height of the (flat) top surface of the fill. Default: the "
          "wall's full height.", **LENGTH),
        F("element_size", DERIVED, "m", "Target element size away from refinement. Default: the "
          "largest wall radius below the fill / 20.", **LENGTH),
        C("mesh", ("structured", "unstructured"), "structured",
          "structured: block-structured quadrilaterals in horizontal bands (the thesis' meshes); "
          "unstructured: frontal-Delaunay quadrilaterals (any wall, e.g. with ledges), their smallest cells "
          "evened out by node relocation (they set the stable Δt)."),
        F("max_aspect_ratio", 2.0, "-", "Structured meshes: the vertical cell size is at most this "
          "times the local radial cell size (keeps cells near a hopper outlet from becoming needles). Not "
          "with a floor: there the outlet's column of cells runs the silo's height, and a refined outlet "
          "makes it needles (silo check says so).",
          lo=1.0, hi=20.0),
        F("outlet_size_factor", 1.0, "-", "Element size at the outlet edge as a fraction of "
          "element_size (1 = no refinement).", lo=0.0, hi=1.0, lo_open=True),
        F("transition_size_factor", 1.0, "-", "Element size at wall corners and fillets (the "
          "transition) as a fraction of element_size.", lo=0.0, hi=1.0, lo_open=True),
        F("refinement_distance", DERIVED, "m", "Distance over which the size grows back from a "
          "refined point to element_size. Default: 1/4 of the largest wall radius.", **LENGTH),
        Key("mesh_file", "str", "", doc="Use this gmsh .msh file (tags material, wall, outlet, "
            "top, axis) instead of meshing; it must fit the wall described by the other keys."),
        I("max_cells", 2_000_000, doc="Refuse to mesh more cells than this (guards typos in "
          "element_size).", lo=1, hi=100_000_000),
    ),
    selector="shape",
    variants={
        "hopper": (
            F("height", unit="m", doc="Height of the hopper wall above the outlet.", **LENGTH, example=2.64),
            F("top_radius", unit="m", doc="Radius at the top of the hopper.", **LENGTH, example=1.2),
            _radius_out,
        ),
        "flat_bottom": (
            F("radius", unit="m", doc="Radius of the cylinder.", **LENGTH, example=0.35),
            F("height", unit="m", doc="Height of the cylinder wall.", **LENGTH, example=4.0),
            _radius_out,
        ),
        "bin_hopper": (
            F("radius", unit="m", doc="Radius of the cylinder (bin).", **LENGTH, example=0.35),
            F("bin_height", unit="m", doc="Height of the vertical wall above the transition.", **LENGTH,
              example=4.18),
            F("hopper_half_angle", unit="deg", doc="Hopper apex half-angle, from the vertical.",
              lo=0.0, hi=90.0, lo_open=True, hi_open=True, example=20.0),
            _radius_out,
            F("fillet_radius", 0.0, "m", "Radius of the circular blend at the transition; 0 = "
              "abrupt corner.", lo=0.0, hi=1000.0),
        ),
        "column": (
            F("base_radius", unit="m", doc="Radius of the base (the whole base is the outlet).",
              **LENGTH, example=0.5),
            F("height", unit="m", doc="Height of the column.", **LENGTH, example=5.0),
            F("half_angle", 0.0, "deg", "Wall angle from the vertical: + converging (widening "
              "upwards, apex down), - diverging, 0 parallel.", lo=-60.0, hi=60.0),
        ),
        "profile": (
            Key("wall", "points", REQUIRED, "m", "Wall points [r, z] from the outlet edge (z = 0) "
                "up to the top; z may not decrease. Straight segments join them.",
                example=[[0.1, 0.0], [0.5, 1.0], [0.5, 3.0]]),
            _radius_out,
        ),
    },
)

MATERIAL = Section(
    "material",
    "The granular solid. Friction and dilation angles are Mohr-Coulomb angles φ, ψ (as silo "
    "engineers quote them: EN 1991-4 Annex E, shear-cell tests), mapped to the Drucker-Prager "
    "cone of the return map by `cone`: yield q = p tan β + cohesion, plastic potential slope "
    "tan ψ_DP (q = sqrt(3 J2), p the mean pressure, compression +). The default matches the "
    "cones in axisymmetric compression, tan β = 6 sin φ/(3 − sin φ) (φ 30° → β 50.19°, 35° → "
    "54.81°, 40° → 58.57°), ψ by the same rule; `cone = \"beta\"` reads the angles as β, ψ_DP "
    "themselves (the thesis' stated convention). `silo check` prints the β it resolves to.",
    keys=(
        C("model", ("elastic", "drucker_prager", "non_coaxial", "mohr_coulomb"),
          doc="elastic: linear elastic; drucker_prager: elastic-perfectly plastic, "
          "non-associated, on a cone (`cone`); non_coaxial: Drucker-Prager with a yield-vertex "
          "non-coaxial term; mohr_coulomb: elastic-perfectly plastic, non-associated, on "
          "Mohr-Coulomb's own pyramid - φ holds at every Lode angle, so no cone is matched "
          "(docs/material.md)."),
        F("density", unit="kg/m³", doc="Bulk density (unit weight / g).", **POS, example=1000.0),
        F("youngs_modulus", unit="Pa", doc="Young's modulus (granular solids: 10⁵-10⁸; at most 10¹², diamond's).",
          lo=0.0, hi=1.0e12, lo_open=True, example=5.5e5),
        F("poisson_ratio", 0.3, "-", "Poisson's ratio.", lo=-1.0, hi=0.5, lo_open=True, hi_open=True),
    ),
    selector="model",
    variants={
        "elastic": (),
        "drucker_prager": (
            F("friction_angle", unit="deg", doc="φ: Mohr-Coulomb angle of internal friction, in (0, 60]° "
              "(with cone = \"beta\": the Drucker-Prager slope β itself, in (0, 70)°).",
              lo=0.0, hi=70.0, lo_open=True, hi_open=True, example=30.0),
            F("dilation_angle", 0.0, "deg", "ψ: Mohr-Coulomb dilation angle, mapped like φ "
              "(≤ friction_angle; equal = associated).", lo=0.0, hi=70.0, hi_open=True),
            C("cone", ("compression", "extension", "plane_strain", "plane_strain_zero_dilation", "beta"),
              "compression",
              "How φ, ψ become the Drucker-Prager slopes β, ψ_DP. compression: the cones meet in "
              "axisymmetric compression, tan β = 6 sin φ/(3 − sin φ) (outer cone; a fill settles in "
              "this state); extension: tan β = 6 sin φ/(3 + sin φ) (inner cone); plane_strain: the "
              "plane-strain limit load, tan β = 3√3 tan φ/√(9 + 12 tan² φ) for ψ = φ, else "
              "tan β = √3 sin φ; plane_strain_zero_dilation: tan β = √3 sin φ, tan ψ_DP = √3 sin ψ "
              "(the thesis' ch. 8 choice); beta: no mapping, the angles are β and ψ_DP."),
            F("cohesion", 1.0, "Pa", "d: yield q at p = 0. The tension cut-off (steep cones, "
              "tan β > 1.5) keeps every principal stress below the cone's apex tension d/tan β.", **NONNEG),
            F("max_dilation", 0.05, "-", "Critical state: the plastic volumetric strain tan ψ_DP · ε̄p "
              "at which dilation stops (ψ → 0; a sheared sand reaches its critical void ratio). "
              "0.05 is the dilation of a loosely poured sand (relative density ≈ 37 %, Toyoura "
              "void ratios) to its critical void ratio at silo stresses; 0.036-0.10 spans relative "
              "densities 30-60 % (docs/material.md). 0 = dilation never stops (the "
              "thesis' Drucker-Prager: the density near an outlet then keeps falling).", lo=0.0, hi=1.0),
            F("relaxation_time", 0.0, "s", "τ of a Duvaut-Lions viscoplasticity around the law: plastic "
              "flow relaxes the stress towards the yield surface over τ, so a point may lie outside it by an "
              "overstress τ·C:ε̇_vp. It gives the solid's shear bands a width ~ wave speed × τ (a "
              "rate-independent solid localises into one element's width, whatever the mesh). 0 = "
              "rate-independent (nothing built); a granular solid in slow flow has no such time of its own "
              "(docs/validation/ch7.md, \"A solid with a relaxation time\").", lo=0.0, hi=1.0),
        Key("recompaction", "bool", False, doc="true: volume a point opens at the apex (pulled apart, its "
            "grains out of contact) is closed again without stress by later compression before it carries "
            "load (state field `opening`); false: the opening is permanent, and a cell that is stretched and "
            "squeezed in turn ratchets its density down (docs/material.md)."),
        ),
    },
)
MATERIAL.variants["mohr_coulomb"] = (
    F("friction_angle", unit="deg", doc="φ: Mohr-Coulomb angle of internal friction, in (0, 60]°, "
      "at every Lode angle (triaxial compression and extension alike).",
      lo=0.0, hi=60.0, lo_open=True, example=30.0),
    F("dilation_angle", 0.0, "deg", "ψ: Mohr-Coulomb dilation angle of the plastic potential "
      "(≤ friction_angle; equal = associated).", lo=0.0, hi=60.0),
    F("cohesion", 1.0, "Pa", "c: Mohr-Coulomb cohesion; the pyramid's apex is the hydrostatic "
      "tension c/tan φ, and no principal stress exceeds it.", **NONNEG),
    *(k for k in MATERIAL.variants["drucker_prager"] if k.name in ("max_dilation", "relaxation_time", "recompaction")),
)
MATERIAL.variants["non_coaxial"] = MATERIAL.variants["drucker_prager"] + (
    F("noncoaxial_modulus", unit="Pa", doc="H_nc: modulus of the non-coaxial plastic strain rate "
      "(1/H_nc)·ṡⁿ (eq. 8-9); at most 10¹² (Young's modulus' bound): far above the shear modulus the "
      "non-coaxial term vanishes, and drucker_prager is the same law without it.",
      lo=0.0, hi=1.0e12, lo_open=True, example=1.0e7),
)

WALL = Section(
    "wall",
    "Contact between the solid and the rigid wall (all wall pieces, floors included).",
    keys=(C("friction", ("none", "coulomb", "velocity_dependent"),
            doc="none: smooth wall; coulomb: constant μ, stick/slip; velocity_dependent: "
            "μ = μk + (μs − μk)·exp(−decay·v_slip) (eq. 7-1)."),
          F("regularisation_length", 0.0, "m", "L of the friction limit's memory (the simplified "
            "Prakash–Clifton law, Cochard & Rice 2000): the limit μ·Ñ follows the contact force N as "
            "dÑ/dt = −(|v_slip| + v*)/L·(Ñ − N). 0 = Coulomb's instantaneous limit (no memory is "
            "built). Above a μ set by the solid, Coulomb sliding on a deformable solid is ill-posed (the "
            "shorter a disturbance, the faster it grows), so its pulses can depend on the mesh; the memory "
            "gives the wall a length of its own - and is itself a source of slip-stick "
            "(docs/validation/ch7.md measures both).", lo=0.0, hi=1.0),
          F("regularisation_speed", 0.01, "m/s", "v* of the memory: the rate at which a sticking "
            "node's limit follows its force is v*/L (read only when regularisation_length > 0).",
            lo=0.0, lo_open=True, hi=100.0)),
    selector="friction",
    variants={
        "none": (),
        "coulomb": (F("mu", unit="-", doc="Wall friction coefficient.", lo=0.0, hi=2.0, example=0.3),),
        "velocity_dependent": (
            F("mu_static", unit="-", doc="μs, at zero slip velocity.", lo=0.0, hi=2.0, example=0.67),
            F("mu_kinetic", unit="-", doc="μk, at high slip velocity (≤ mu_static).", lo=0.0, hi=2.0,
              example=0.3),
            F("decay", unit="s/m", doc="ϖ, decay coefficient in eq. 7-1 (the thesis: 2-10; 10⁴ already drops μ "
              "to μk at 0.1 mm/s of slip).", lo=0.0, hi=1.0e4, example=2.0),
        ),
    },
)

LOADS = Section(
    "loads",
    "Body force and top surcharge.",
    keys=(
        F("gravity", 9.81, "m/s²", "Gravitational acceleration.", **POS),
        F("top_surcharge", 0.0, "Pa", "Uniform pressure on the top surface (ch. 5 columns use one "
          "for a near-uniform initial stress).", **NONNEG),
    ),
)

FILL = Section(
    "fill",
    "How the initial (end-of-filling) state is made.",
    keys=(
        C("method", ("layers", "ramp", "k0"), "layers",
          "layers: the fill is activated in horizontal layers from the bottom, each stress-free "
          "when it appears; ramp: gravity is ramped smoothly on the whole fill; k0: start from "
          "the geostatic field σzz = −ρg(H−z), σrr = σθθ = k0·σzz, no filling stage."),
        F("duration", 10.0, "s", "Duration of the filling stage.", **DURATION),
        F("ramp_fraction", 0.5, "-", "Fraction of each layer's (or the ramp's) time over which "
          "its gravity is ramped smoothly; the rest lets it settle.", lo=0.0, hi=1.0, lo_open=True),
        F("damping", 0.0, "-", "Fraction of critical damping of the fill's fundamental vertical mode, "
          "applied as mass-proportional damping during filling and storage only (0 = none, as the "
          "thesis).", lo=0.0, hi=2.0),
    ),
    selector="method",
    variants={
        "layers": (I("layers", 10, doc="Number of layers (the thesis: 10-20); each layer's top is a mesh line.",
                     lo=1, hi=1000),),
        "ramp": (),
        "k0": (F("k0", DERIVED, "-", "Lateral pressure ratio. Default: ν/(1−ν).", lo=0.0, hi=10.0, lo_open=True),),
    },
)

STORE = Section(
    "store",
    "Storage after filling: the silo closed, the solid coming to rest.",
    keys=(
        F("duration", 2.0, "s", "Longest storage time.", **DURATION),
        F("kinetic_energy_tol", 0.0, "-", "End storage early once kinetic energy < tol × work of "
          "gravity (0: always run the full duration; ≥ 1 would end it at once).", lo=0.0, hi=1.0, hi_open=True),
    ),
)

DISCHARGE = Section(
    "discharge",
    "Opening the outlet.",
    keys=(
        C("mode", ("none", "free", "controlled"), "none",
          "none: no discharge stage; free: the outlet support is removed at once; controlled: "
          "the outlet velocity is prescribed, u(t) = u0/2·(1 − cos(π t/ramp_time)) then u0 (a feeder: the node "
          "at the outlet's edge slides down a wall steeper than 45° with it, beside a flatter wall or a floor it "
          "goes down at u/2; what leaves is ρ u π R0², ρ the density at the outlet)."),
        F("duration", 0.0, "s", "Duration of the discharge stage.", **DURATION),
        C("gate", ("smooth", "rough", "fixed"), "smooth",
          "How the closed outlet holds the solid before discharge: smooth (no friction), rough "
          "(wall friction law), fixed (no slip)."),
        F("min_mesh_quality", 0.1, "-", "End the discharge early - cleanly: the run completes and its "
          "discharge record says why - once the worst cell's scaled Jacobian (sampled at the history "
          "rate) falls below this: the silo has drained so far (a crater down to the outlet, the last "
          "rows over it) that the mesh, which keeps all its rows, cannot follow it. 0 = never: the run "
          "goes on until a cell turns inside out, and then stops with an error.", lo=0.0, hi=1.0,
          hi_open=True),
    ),
    selector="mode",
    variants={
        "none": (),
        "free": (),
        "controlled": (
            F("velocity", unit="m/s", doc="u0, the final outlet velocity (downwards).", **POS,
              example=1.0),
            F("ramp_time", 2.0, "s", "Time to reach u0 (longer than the discharge: a warning).", **DURATION),
        ),
    },
)

NUMERICS = Section(
    "numerics",
    "Explicit time integration.",
    keys=(
        F("time_step_scale", 0.8, "-", "Δt = scale × min over elements of L_min/c_d (with the "
          "bulk-viscosity correction).", lo=0.0, hi=2.0, lo_open=True),
        Key("bulk_viscosity", "floats", (0.06, 1.2), "-", "[linear, quadratic] bulk viscosity "
            "coefficients; [0, 0] switches it off.", lo=0.0, length=2),
        F("mass_scaling", 1.0, "-", "Factor on the inertial mass (Δt grows with its square root); "
          "1 = none.", lo=1.0, hi=1.0e6),
        C("integration", ("full", "reduced"), "full",
          "Quadrature of the Q1 cells: full = 2 × 2 Gauss points with the mean-dilatation (B-bar) pressure; "
          "reduced = one point per cell, Flanagan-Belytschko's uniform strain (the mean over the cell's exact "
          "volume; the thesis' Abaqus CAX4R) with their hourglass control: ~1.4× cheaper per step, the discharge "
          "rate within 3.3 % and wall pressures within 1 % of full on the ch. 4 hopper, but a coarse mesh needs "
          "hourglass stiffness to hold a cell at rest (docs/performance.md)."),
        F("hourglass_viscosity", 0.1, "-", "κ_v of the viscous hourglass control (reduced integration): "
          "Q = κ_v ρ c_d A √((b·b)/2) · 2πr q̇ per cell. Its work is the energy column hourglass.", lo=0.0, hi=1.0),
        F("hourglass_stiffness", 0.0, "-", "κ_s of the stiffness hourglass control (reduced integration): "
          "Q̇ = κ_s (λ+2μ) A (b·b)/2 · 2πr q̇ per cell, |Q| capped at the cell's shear strength (p tan β + d) "
          "A √((b·b)/2) 2πr. Holds hourglass modes at rest (a coarse K0 start needs ~0.3) but slows a "
          "discharge (0.1-0.3: −7 to −9 % on the ch. 4 hopper), so off by default.", lo=0.0, hi=1.0),
        F("min_time_step_fraction", 0.01, "-", "Stop with a diagnosis (the limiting cell, its density, the "
          "likely cause and fix) when the stable Δt falls below this fraction of its value when the "
          "cells were last activated (a remap does not reset it): an arch over the outlet empties the "
          "cells below it and Δt falls towards zero. 0 = never stop.", lo=0.0, hi=1.0, hi_open=True),
        I("max_steps", 100_000_000, doc="Refuse a scene whose estimated number of time steps (its "
          "durations over the stable Δt of its element size, modulus and density) exceeds this: a "
          "modulus, density or duration off by some powers of ten would otherwise run for weeks. The "
          "largest thesis run needs ~10⁶.", lo=1, hi=1_000_000_000_000),
    ),
)

ALE = Section(
    "ale",
    "Arbitrary Lagrangian-Eulerian mesh motion (thesis ch. 3.2).",
    keys=(
        Key("enabled", "bool", True, doc="false = purely Lagrangian."),
        I("frequency", 10, doc="Smooth and remap every this many steps.", lo=1, hi=10_000),
        I("sweeps", 1, doc="Smoothing sweeps per smoothing.", lo=1, hi=100),
        F("laplacian_weight", 0.5, "-", "Weight of Laplacian smoothing (eq. 3-4).", lo=0.0, hi=1.0),
        F("mid_area_weight", 0.5, "-", "Weight of mid-area (volume-weighted) smoothing (eq. 3-5); "
          "the two weights sum to at most 1.", lo=0.0, hi=1.0),
        I("remap_order", 2, doc="1: donor cell (first order); 2: limited second order.", lo=1, hi=2),
        C("predictor", ("previous", "current", "stretched"), "previous",
          "Where interior nodes start each smoothing: previous = their last smoothed position (the "
          "mesh stays put unless the boundary moves: mostly Eulerian); current = where the material "
          "took them (mostly Lagrangian, more distortion, less remapping); stretched = the previous "
          "position stretched with the free surface above it (each node keeps its fraction of the "
          "height between the wall's highest corner under the fill and the surface; the axis too), "
          "so that the top rows follow a crater or a surface falling at the wall."),
        F("max_surface_slope", 0.0, "°", "The steepest free surface the ALE keeps: a steeper segment of "
          "the top slumps (its nodes move towards each other vertically, keeping the volume under the "
          "surface, and the material moves with them along the top row of cells), as grains roll down "
          "a slope steeper than their angle of repose - which a cohesionless continuum at its free "
          "surface (no pressure, no strength) does not do by itself. About the solid's angle of repose "
          "(≈ its friction angle); 0 = off (the surface follows the material wherever it goes).",
          lo=0.0, hi=89.0),
        F("rezone_dt_fall", 0.0, "-", "Re-mesh the material during the discharge once the stable Δt has "
          "fallen by this fraction below its value after the opening (or the last re-mesh): the domain "
          "as it is then - the free surface through its nodes - is meshed again at the scene's element "
          "size and the state carried over conservatively (silo_dolfinx.ale.rezone). A draining fill "
          "squeezes the rows under its falling surface, which sets Δt; a fresh mesh has the scene's "
          "cells again, and fewer of them. Only when the cell that sets Δt has shrunk by as much (a "
          "cell dilated at the outlet sets a smaller Δt that no mesh cures). 0 = never. Checkpoints "
          "stop at the first re-mesh.", lo=0.0, hi=0.9),
        F("rezone_min_quality", 0.0, "-", "Re-mesh the material (as rezone_dt_fall does) once the worst "
          "cell's scaled Jacobian falls below this, instead of ending the discharge at "
          "discharge.min_mesh_quality: set it above that. 0 = never.", lo=0.0, hi=0.9),
        C("smoothing_objective", ("graded", "uniform"), "graded",
          "graded: smooth only the distortion relative to the initial mesh (keeps its refinement); "
          "uniform: plain eqs. 3-4/3-5 (evens out element sizes)."),
        I("tracer_rows", 10, doc="Rows of tracers (material points) seeded at the opening, for flow "
          "patterns; 0 = none.", lo=0, hi=1000),
        I("tracer_columns", 12, doc="Tracers per row, from the axis to the wall.", lo=1, hi=1000),
    ),
)

OUTPUT = Section(
    "output",
    "What is written to the results folder.",
    keys=(
        Key("stations", "floats", DERIVED, "m", "Wall stations for time histories, as heights "
            "(or arclengths, see station_coordinate). Default: 10 evenly spaced on the fill, and on a "
            "bin_hopper one at its transition (the corner, or the fillet's middle; labelled \"transition\" "
            "unless station_labels are given); [] = no wall_history.csv (the wall stream is not built)."),
        C("station_coordinate", ("z", "s"), "z", "z: stations are heights; s: wall arclengths "
          "from the outlet edge."),
        Key("station_labels", "strings", (), "-", "Names of the stations, one per station in the same "
            "order (the thesis' cell or point labels, e.g. \"A5\" or \"D\"; \"\" leaves one unnamed), "
            "shown with their height in the report's figures and numbers; [] = heights only.",
            example=["A", "D", "H"]),
        F("history_rate", 200.0, "Hz", "Sampling rate of time histories (at most one sample per step).",
          lo=0.0, hi=1.0e6, lo_open=True),
        C("history_sampling", ("mean", "instant"), "mean", "What a wall_history.csv and point_history.csv sample "
          "is. mean: the time mean over the interval since the previous sample (of the wall forces and slip; of "
          "the stress and velocity of the cell holding a point), what a pressure cell records: nothing faster "
          "than half the history rate folds into the record's band - the stiff ch. 4 solid's ~157-Hz ringing "
          "at point e shows as a 43-Hz peak in 200-Hz instants; instant: the step at the sample (the thesis' "
          "history output)."),
        Key("points", "locations", (), "m", "Interior points [r, z] whose stress (the mean of the cell "
            "containing each, as the thesis' one-point elements report it) is written to "
            "point_history.csv at the history rate (the thesis' Figs. 4-16 to 4-18); [] = none.",
            example=[[0.3, 0.66], [0.6, 1.32]]),
        C("point_motion", ("fixed", "material"), "fixed", "fixed: the points stay where they are (the "
          "thesis'); material: they stay until the outlet opens, then move with the solid (carried "
          "through ALE remaps like tracers; a point that leaves through the outlet has no values after)."),
        I("zone_bands", 20, doc="Height bands (equal, from the bottom of the silo to the fill height) in "
          "which shear_zones.csv records at the history rate where the solid is failing: the share of the "
          "band's loaded solid at yield, the mean share of its strength mobilised, the share separated (at "
          "the apex) - the thesis' Figs. 4-19/8-13 as a map in height and time, which `silo report` sets "
          "beside the wall pressure. Instants. 0 = none (the stream is not built; nor for an elastic solid).",
          lo=0, hi=1000),
        F("field_interval", 0.5, "s", "Simulated time between field outputs (VTX, and the snapshots "
          "`silo report` draws); 0 = no field output at all (the field stream is not built).", **DURATION),
        F("checkpoint_interval", 300.0, "s", "Wall-clock seconds between checkpoints (written at a history sample "
          "into `checkpoint/` of the results folder; a killed run continues with `silo run --resume FOLDER`, on "
          "the same number of ranks). 0 = no checkpoints.", lo=0.0, hi=1.0e6),
    ),
)

SECTIONS: tuple[Section, ...] = (
    GEOMETRY, MATERIAL, WALL, LOADS, FILL, STORE, DISCHARGE, NUMERICS, ALE, OUTPUT
)
SECTION_BY_NAME = {s.name: s for s in SECTIONS}
REQUIRED_SECTIONS = ("geometry", "material", "wall")

# The accuracy knobs: keys that change how closely the run approximates the same silo and solid,
# and what it costs in time (not the silo, the solid or what is recorded). Each names its tables in
# ``python benchmarks/accuracy_cost.py --knobs NAME`` (error against the most accurate setting, and
# wall-clock); docs/performance.md quotes them. A test holds this map and that script's tables to
# each other, and every key of [geometry], [fill], [store], [numerics] and [ale] to being a knob or
# saying why it is not.
ACCURACY_KNOBS: dict[str, tuple[str, ...]] = {
    "geometry.element_size": ("mesh_size",),
    "geometry.mesh": ("mesh_type",),
    "geometry.max_aspect_ratio": ("max_aspect_ratio",),
    "geometry.outlet_size_factor": ("outlet_size_factor",),
    "geometry.transition_size_factor": ("transition_size_factor",),
    "geometry.refinement_distance": ("refinement_distance",),
    "fill.method": ("fill_method",),
    "fill.duration": ("fill_duration",),
    "fill.ramp_fraction": ("fill_ramp_fraction",),
    "fill.damping": ("fill_damping",),
    "fill.layers": ("fill_layers",),
    "store.duration": ("store_duration",),
    "store.kinetic_energy_tol": ("store_kinetic_energy_tol",),
    "numerics.time_step_scale": ("time_step_scale", "table_3_2", "table_3_2_filled", "table_3_2_beyond"),
    "numerics.bulk_viscosity": ("bulk_viscosity",),
    "numerics.mass_scaling": ("mass_scaling",),
    "numerics.integration": ("integration", "integration_filling"),
    "numerics.hourglass_viscosity": ("hourglass_viscosity",),
    "numerics.hourglass_stiffness": ("hourglass_stiffness",),
    "ale.enabled": ("lagrangian",),
    "ale.frequency": ("smoothing_frequency",),
    "ale.sweeps": ("smoothing_sweeps",),
    "ale.laplacian_weight": ("laplacian_weight",),
    "ale.mid_area_weight": ("mid_area_weight",),
    "ale.remap_order": ("remap_order",),
    "ale.predictor": ("smoothing_predictor",),
    "ale.smoothing_objective": ("smoothing_objective",),
    "ale.rezone_dt_fall": ("rezone_dt_fall",),
    "ale.rezone_min_quality": ("rezone_min_quality",),
}


def markdown() -> str:
    """The scene reference as Markdown (docs/scene.md is this, verbatim)."""
    out = [
        "# Scene file reference",
        "",
        "<!-- generated by `silo schema > docs/scene.md`; do not edit -->",
        "",
        __doc__.split("\n\n", 1)[1].strip(),
        "",
        "Sections [" + "], [".join(REQUIRED_SECTIONS) + "] are required; all others are optional.",
        "",
        "## Top level",
        "",
        _table(TOP_KEYS),
    ]
    for s in SECTIONS:
        out += ["", f"## [{s.name}]", "", s.doc, "", _table(s.keys, s.name)]
        for v, ks in s.variants.items():
            if ks:
                out += ["", f"`{s.selector} = \"{v}\"`:", "", _table(ks, s.name)]
    return "\n".join(out) + "\n"


def _table(keys, section: str = "") -> str:
    rows = ["| key | unit | default | allowed | meaning |", "|---|---|---|---|---|"]
    for k in keys:
        d = k.default
        ds = "**required**" if d is REQUIRED else ("derived" if d is DERIVED else f"`{_toml(d)}`")
        knobs = ACCURACY_KNOBS.get(f"{section}.{k.name}", ())
        cost = (" *Accuracy knob:* error and wall-clock by setting, `python benchmarks/accuracy_cost.py --knobs "
                + " ".join(knobs) + "` (docs/performance.md)." if knobs else "")
        rows.append(f"| `{k.name}` | {k.unit or '-'} | {ds} | {k.range_text()} | {k.doc}{cost} |")
    return "\n".join(rows)


def _toml(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    return f"{v:g}" if isinstance(v, float) else str(v)


if __name__ == "__main__":  # pragma: no cover
    print(markdown(), end="")
