"""Scene files: every shipped scene is valid, and every class of bad input is refused before
meshing with one message naming the key, the value, the allowed range and a fix."""

import copy

import pytest
from conftest import ROOT, SCENES, scene_dict

from silo_dolfinx.scene import SceneError, load_geometry, load_scene
from silo_dolfinx.scene.schema import markdown

HOPPER = {"shape": "hopper", "height": 2.64, "top_radius": 1.2, "outlet_radius": 0.1}
DP = {"model": "drucker_prager", "density": 1000.0, "youngs_modulus": 5.5e5, "friction_angle": 30.0,
      "dilation_angle": 10.0}


def refused(scene, overrides=()) -> SceneError:
    with pytest.raises(SceneError) as e:
        load_scene(scene, list(overrides))
    return e.value


def assert_names(err: SceneError, key: str, *fragments: str):
    """The error names ``section.key`` and its message contains each fragment and a fix."""
    assert key in err.keys, f"{key} not named in: {err}"
    text = str(err)
    assert "Fix" in text or "Did you mean" in text, text
    for f in fragments:
        assert f in text, f"{f!r} not in: {text}"


@pytest.mark.parametrize("path", sorted(SCENES.glob("*.toml")), ids=lambda p: p.stem)
def test_shipped_scenes_are_valid_and_round_trip(path):
    scene = load_scene(path)
    # each scene says what it is: a variant does not inherit its base's description (the loader
    # drops it), so a variant without its own would show none in `silo check` and summary.json
    assert scene.description.strip(), f"{path.name}: no description"
    again = load_scene(scene.to_dict())
    assert again.to_dict() == scene.to_dict()
    # The resolved TOML is itself a scene that resolves to the same thing.
    import tomllib

    assert load_scene(tomllib.loads(scene.to_toml())).to_dict() == scene.to_dict()


def test_every_targets_case_has_a_scene():
    names = {p.stem for p in SCENES.glob("*.toml")}
    wanted = {"hopper_ch4", "hopper_ch4_stiff", "hopper_ch4_smooth", "hopper_ch4_controlled_u0",
              "hopper_ch4_controlled_u0_2", "hopper_ch4_controlled_u0_4", "hopper_ch4_controlled_u0_10",
              "hopper_ch4_controlled_u0_100", "hopper_ch3_lagrangian", "hopper_ch3_ale",
              "column_ch5_FE1", "column_ch5_FE2", "column_ch5_FE3", "column_ch5_FE4", "column_ch5_FE5",
              "column_ch5_hopper22", "flat_bottom_ch6", "flat_bottom_ch6_discharge", "bin_hopper_ch7_abrupt", "bin_hopper_ch7_fillet02",
              "bin_hopper_ch7_fillet10", "bin_hopper_ch7_fillet30", "bin_hopper_ch7_dynamic",
              "bin_hopper_ch7_dynamic_2u0", "steep_hopper_ch8_coaxial", "steep_hopper_ch8_noncoaxial"}
    assert wanted <= names, wanted - names
    assert any(n.startswith("column_ch5_alpha_m") for n in names)
    assert any(n.startswith("column_ch5_alpha_p") for n in names)


def test_thesis_parameters_in_scenes():
    s = load_scene(SCENES / "hopper_ch4.toml")
    assert (s.geometry.height, s.geometry.top_radius, s.geometry.outlet_radius) == (2.64, 1.2, 0.1)
    assert (s.material.density, s.material.youngs_modulus, s.material.friction_angle) == (1000.0, 5.5e5, 30.0)
    assert (s.fill.duration, s.store.duration, s.discharge.duration) == (10.0, 2.0, 60.0)
    assert s.wall.mu == 0.267
    v = load_scene(SCENES / "bin_hopper_ch7_dynamic.toml")  # inherits through base
    assert (v.wall.mu_static, v.wall.mu_kinetic, v.wall.decay) == (0.67, 0.3, 2.0)
    assert v.geometry.hopper_half_angle == 20.0 and v.material.friction_angle == 40.0


def test_defaults_and_overrides():
    s = load_scene(scene_dict(HOPPER), ["material.density=1500", "geometry.shape=hopper",
                                        "numerics.bulk_viscosity=[0, 0]"])
    assert s.material.density == 1500.0
    assert s.numerics.bulk_viscosity == [0.0, 0.0]
    assert s.geometry.fill_height == 2.64  # derived: full
    assert s.geometry.element_size == 0.06  # derived: r_max / 20
    assert s.numerics.time_step_scale == 0.8
    assert len(s.output.stations) == 10


def test_keys_of_another_variant_are_ignored_with_a_warning():
    d = scene_dict(HOPPER, wall={"friction": "none", "mu": 0.3})
    s = load_scene(d)
    assert "mu" not in s.wall and any("mu" in w for w in s.warnings)


# ------------------------------------------------------------------ one test per bad-input class
def test_unknown_key_with_suggestion():
    err = refused(scene_dict(HOPPER, material={**DP, "densty": 1000.0}))
    assert_names(err, "material.densty", "unknown key", "Did you mean 'density'")


def test_unknown_section():
    d = scene_dict(HOPPER)
    d["materail"] = {"x": 1}
    assert_names(refused(d), "materail.(section)", "unknown section", "Did you mean 'material'")


def test_unknown_top_level_key():
    d = scene_dict(HOPPER)
    d["tilte"] = "x"
    assert_names(refused(d), "tilte", "unknown top-level key", "'title'")


def test_wrong_type():
    err = refused(scene_dict(HOPPER, material={**DP, "density": "heavy"}))
    assert_names(err, "material.density", "'heavy'", "wrong type", "number")


def test_boolean_is_not_a_number():
    assert_names(refused(scene_dict(HOPPER, material={**DP, "density": True})), "material.density", "wrong type")


def test_missing_required_key():
    d = scene_dict(HOPPER, material={k: v for k, v in DP.items() if k != "friction_angle"})
    assert_names(refused(d), "material.friction_angle", "missing", "drucker_prager", "friction_angle = 30")


def test_missing_required_section():
    d = scene_dict(HOPPER)
    del d["wall"]
    assert_names(refused(d), "wall.(section)", "missing section")


@pytest.mark.parametrize("value", [-1000.0, 0.0])
def test_non_positive_density(value):
    assert_names(refused(scene_dict(HOPPER, material={**DP, "density": value})),
                 "material.density", f"= {value:g}", "> 0 kg/m³")


@pytest.mark.parametrize("nu", [0.5, -1.0, 0.7])
def test_poisson_ratio_out_of_range(nu):
    assert_names(refused(scene_dict(HOPPER, material={**DP, "poisson_ratio": nu})),
                 "material.poisson_ratio", f"= {nu:g}", "(-1, 0.5)")


@pytest.mark.parametrize("key,value,text", [("friction_angle", 75.0, "(0, 70)"),
                                            ("friction_angle", -5.0, "(0, 70)"),
                                            ("friction_angle", 0.0, "(0, 70)"),
                                            ("friction_angle", 65.0, "(0, 60]"),
                                            ("dilation_angle", 40.0, "exceeds friction_angle"),
                                            ("cone", "drucker_prager", "'compression'")])
def test_angles_out_of_range(key, value, text):
    assert_names(refused(scene_dict(HOPPER, material={**DP, key: value})), f"material.{key}", text)


def test_friction_angles_are_mohr_coulomb_by_default():
    """φ, ψ are Mohr-Coulomb angles, mapped by material.cone (default compression: 30° → β
    50.19°, ψ 10° → 20.24°); cone = "beta" takes them as the slopes themselves (up to 70°,
    where a Mohr-Coulomb 65° is refused); the resolved TOML names both readings and reloads."""
    import tomllib

    s = load_scene(scene_dict(HOPPER, material=DP))
    c = s.cone
    assert (s.material.cone, c["friction_angle"]) == ("compression", 30.0)
    assert (round(c["beta"], 2), round(c["psi_dp"], 2)) == (50.19, 20.24)
    assert "Drucker-Prager β = 50.19°" in s.to_toml().splitlines()[0]
    lit = load_scene(scene_dict(HOPPER, material={**DP, "friction_angle": 65.0, "cone": "beta"}))
    assert (lit.cone["beta"], lit.cone["psi_dp"]) == (65.0, 10.0)
    assert load_scene(tomllib.loads(lit.to_toml())).to_dict() == lit.to_dict()
    assert load_scene(SCENES / "hopper_ch4_literal_beta.toml").cone["beta"] == 30.0
    assert load_scene(SCENES / "flat_bottom_ch6.toml").material.max_dilation == 0.05  # critical state by default
    assert load_scene(scene_dict(HOPPER, material={**DP, "model": "elastic"})).cone is None


def test_mohr_coulomb_model_takes_the_angles_as_they_are():
    """model = "mohr_coulomb": φ, ψ are the pyramid's own angles (no cone key; a given cone is
    reported as unused); φ beyond 60° and ψ > φ are refused naming the key; the law built is
    the Mohr-Coulomb one with those angles, and the resolved line names both corner cones."""
    from silo_dolfinx.materials import MohrCoulomb, make_material

    mc = {k: v for k, v in DP.items() if k != "cone"} | {"model": "mohr_coulomb"}
    s = load_scene(scene_dict(HOPPER, material=mc))
    assert "cone" not in s.material and s.cone["cone"] is None
    law = make_material(s.material)
    assert isinstance(law, MohrCoulomb) and (law.friction_angle, law.dilation_angle) == (30.0, 10.0)
    assert "50.19° and 40.60°" in s.to_toml().splitlines()[0]
    assert_names(refused(scene_dict(HOPPER, material={**mc, "friction_angle": 65.0})), "material.friction_angle",
                 "(0, 60]")
    assert_names(refused(scene_dict(HOPPER, material={**mc, "dilation_angle": 40.0})), "material.dilation_angle",
                 "exceeds friction_angle")


def test_hopper_half_angle_out_of_range():
    g = {"shape": "bin_hopper", "radius": 0.35, "bin_height": 4.0, "hopper_half_angle": 90.0, "outlet_radius": 0.05}
    assert_names(refused(scene_dict(g)), "geometry.hopper_half_angle", "(0, 90)")


def test_unknown_choice():
    assert_names(refused(scene_dict({**HOPPER, "shape": "hoper"})), "geometry.shape", "'hoper'", "'hopper'")


@pytest.mark.parametrize("geometry", [
    {**HOPPER, "outlet_radius": 1.2},
    {"shape": "flat_bottom", "radius": 0.35, "height": 4.0, "outlet_radius": 0.4},
    {"shape": "bin_hopper", "radius": 0.35, "bin_height": 4.0, "hopper_half_angle": 20.0, "outlet_radius": 0.35},
    {"shape": "profile", "wall": [[0.1, 0.0], [0.3, 1.0]], "outlet_radius": 0.2},
], ids=["hopper", "flat_bottom", "bin_hopper", "profile"])
def test_outlet_not_narrower_than_silo(geometry):
    assert_names(refused(scene_dict(geometry)), "geometry.outlet_radius", f"= {geometry['outlet_radius']:g}")


def test_fillet_that_does_not_fit():
    g = {"shape": "bin_hopper", "radius": 0.35, "bin_height": 4.0, "hopper_half_angle": 20.0,
         "outlet_radius": 0.05, "fillet_radius": 6.0}
    err = refused(scene_dict(g))
    # tangent length 6 tan 10° = 1.058 m > hopper wall length 0.3/sin 20° = 0.877 m
    assert_names(err, "geometry.fillet_radius", "does not fit", "1.058", "fillet_radius < 4.975")


def test_profile_not_monotone_in_z():
    g = {"shape": "profile", "wall": [[0.1, 0.0], [0.5, 1.0], [0.5, 0.8], [0.5, 2.0]], "outlet_radius": 0.1}
    assert_names(refused(scene_dict(g)), "geometry.wall", "point 2", "not monotone in z")


def test_profile_that_self_intersects():
    # z never decreases, but the horizontal ledge folds back over itself.
    g = {"shape": "profile", "wall": [[0.1, 0.0], [0.5, 1.0], [0.8, 1.0], [0.6, 1.0], [0.6, 2.0]],
         "outlet_radius": 0.1, "mesh": "unstructured"}
    assert_names(refused(scene_dict(g)), "geometry.wall", "intersect")


def test_profile_on_the_axis():
    g = {"shape": "profile", "wall": [[0.1, 0.0], [0.0, 1.0]], "outlet_radius": 0.1}
    assert_names(refused(scene_dict(g)), "geometry.wall", "r ≤ 0")


def test_diverging_column_that_closes():
    g = {"shape": "column", "base_radius": 0.5, "height": 5.0, "half_angle": -10.0}
    assert_names(refused(scene_dict(g)), "geometry.half_angle", "closes", "−5.711")


def test_fill_above_the_wall():
    assert_names(refused(scene_dict({**HOPPER, "fill_height": 3.0})), "geometry.fill_height", "= 3", "≤ 2.64")


def test_element_size_that_would_explode_the_mesh():
    err = refused(scene_dict({**HOPPER, "element_size": 1e-4}))
    assert_names(err, "geometry.element_size", "max_cells")


def test_kinetic_friction_above_static():
    err = refused(scene_dict(HOPPER, wall={"friction": "velocity_dependent", "mu_static": 0.3,
                                           "mu_kinetic": 0.5, "decay": 2.0}))
    assert_names(err, "wall.mu_kinetic", "exceeds mu_static")


def test_a_memory_of_friction_on_a_smooth_wall():
    err = refused(scene_dict(HOPPER, wall={"friction": "none", "regularisation_length": 1e-4}))
    assert_names(err, "wall.regularisation_length", "smooth wall", "Fix:")
    sc = load_scene(scene_dict(HOPPER, wall={"friction": "coulomb", "mu": 0.4, "regularisation_length": 1e-4}))
    assert (sc.wall.regularisation_length, sc.wall.regularisation_speed) == (1e-4, 0.01)  # v*'s default


def test_rezone_quality_not_above_the_discharge_floor():
    err = refused(scene_dict(HOPPER, ale={"rezone_min_quality": 0.1}, discharge={"mode": "free", "duration": 1.0}))
    assert_names(err, "ale.rezone_min_quality", "not above discharge.min_mesh_quality = 0.1")


def test_bad_override_syntax_and_unknown_override_key():
    assert_names(refused(scene_dict(HOPPER), ["material.density"]), "--set", "section.key=value")
    assert_names(refused(scene_dict(HOPPER), ["material.poisson=0.2"]), "material.poisson",
                 "Did you mean 'poisson_ratio'")


def test_station_outside_the_wall():
    err = refused(scene_dict(HOPPER, output={"stations": [1.0, 3.0]}))
    assert_names(err, "output.stations", "3 m", "[0, 2.64]")


def test_station_labels_one_per_station():
    """Names for the stations: one per station (the default ten included), strings only."""
    err = refused(scene_dict(HOPPER, output={"stations": [1.0, 2.0], "station_labels": ["A"]}))
    assert_names(err, "output.station_labels", "1 names for 2 stations", "one name per station")
    err = refused(scene_dict(HOPPER, output={"station_labels": ["A", "B"]}))  # ten derived stations
    assert_names(err, "output.station_labels", "2 names for 10 stations")
    err = refused(scene_dict(HOPPER, output={"stations": [1.0], "station_labels": [5]}))
    assert_names(err, "output.station_labels", "list of short strings")
    s = load_scene(scene_dict(HOPPER, output={"stations": [1.0, 2.0], "station_labels": ["D", ""]}))
    assert s.output.station_labels == ["D", ""]


def test_circular_base(tmp_path):
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text('base = "b.toml"\n')
    b.write_text('base = "a.toml"\n')
    assert_names(refused(a), "base", "circular")


def test_toml_syntax_error(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("[geometry\nshape = 'hopper'\n")
    assert_names(refused(p), "syntax", "bad.toml")


def test_all_problems_reported_at_once():
    d = scene_dict(HOPPER, material={**DP, "density": -1.0, "poisson_ratio": 0.6})
    err = refused(d)
    assert {"material.density", "material.poisson_ratio"} <= set(err.keys)


def test_geometry_alone_validates():
    g = load_geometry(copy.deepcopy(HOPPER))
    assert g["fill_height"] == 2.64
    with pytest.raises(SceneError):
        load_geometry({**HOPPER, "height": -1.0})


def test_docs_match_schema():
    """docs/scene.md is generated from the schema; regenerate with
    `silo schema > docs/scene.md`."""
    assert (ROOT / "docs" / "scene.md").read_text() == markdown()


# Keys of the sections that hold approximations - [geometry], [fill], [store], [numerics], [ale] -
# that are not accuracy knobs, and why (every other key of those sections must be one: a new key
# there is either measured by benchmarks/accuracy_cost.py or says here why it needs no table). The
# other sections are the solid, the wall, the loads, the outlet's operation and what is recorded.
SILO = "the silo itself, not an approximation of it"
NOT_KNOBS = {
    **{f"geometry.{k}": SILO for k in ("shape", "fill_height", "height", "top_radius", "outlet_radius", "radius",
                                       "bin_height", "hopper_half_angle", "fillet_radius", "base_radius",
                                       "half_angle", "wall")},
    "geometry.mesh_file": "a mesh made elsewhere: its resolution is the user's (the mesh knobs do not apply)",
    "geometry.max_cells": "a guard against a typo in element_size",
    "fill.k0": "physics: the lateral pressure ratio of a geostatic start",
    "numerics.min_time_step_fraction": "a guard: where a run stops with a diagnosis, not how it approximates",
    "numerics.max_steps": "a guard against a scene that would never finish",
    "ale.max_surface_slope": "physics: the solid's angle of repose at its free surface, not an approximation",
    "ale.tracer_rows": "output: material points for flow patterns (their cost: benchmarks/effects_cost.py)",
    "ale.tracer_columns": "output, as tracer_rows",
}


def _accuracy_benchmark():
    import importlib.util
    import sys

    spec = importlib.util.spec_from_file_location("accuracy_cost", ROOT / "benchmarks" / "accuracy_cost.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # (its dataclasses look their module up)
    spec.loader.exec_module(module)
    return module


def test_every_accuracy_knob_has_its_table_and_every_table_its_knob():
    """The user asked for a measured accuracy-vs-wall-clock table for every accuracy knob: the
    schema's map of knobs (whose docs name the command) and benchmarks/accuracy_cost.py's tables
    are the same set, each table varies the key the map gives it, every key of the sections that
    hold approximations is a knob or says why not, and every row of every table is a scene the loader accepts (a
    table that cannot run is caught here, not after half an hour of benchmark)."""
    from silo_dolfinx.scene.schema import ACCURACY_KNOBS, SECTION_BY_NAME

    bench = _accuracy_benchmark()
    by_table = {t: key for key, tables in ACCURACY_KNOBS.items() for t in tables}
    assert set(by_table) == set(bench.KNOBS), "tables without a knob, or knobs without a table"
    for table, (problem, key, values, ref) in bench.KNOBS.items():
        assert key == by_table[table], f"{table} varies {key}, the schema says {by_table[table]}"
        for value in (ref, *values):  # the overrides the benchmark runs; raises SceneError on a bad row
            load_scene(SCENES / bench.PROBLEMS[problem].scene, bench.overrides(problem, key, value, 2.0))
    for dotted in ACCURACY_KNOBS:
        section, name = dotted.split(".")
        assert name in SECTION_BY_NAME[section].all_key_names(), f"{dotted} is not a scene key"
    for section in ("geometry", "fill", "store", "numerics", "ale"):
        for name in SECTION_BY_NAME[section].all_key_names():
            dotted = f"{section}.{name}"
            assert (dotted in ACCURACY_KNOBS) != (dotted in NOT_KNOBS), f"{dotted}: a knob, or say why not"
    assert "accuracy_cost.py --knobs smoothing_frequency" in (ROOT / "docs" / "scene.md").read_text()


CH4 = SCENES / "hopper_ch4.toml"


@pytest.mark.parametrize("overrides,key,fragments", [
    (["material.youngs_modulus=5.5e3"], "material.youngs_modulus",  # 1000·9.81·2.64/5.5e3 = 4.71
     ("compress by 4.71 of its height", "Fix: check the units")),
    (["loads.top_surcharge=1e6"], "loads.top_surcharge", ("compress by 1.87",)),  # (25898 + 1e6)/5.5e5
    (["material.density=1e-3"], "numerics.max_steps",  # c_d = 27210 m/s, Δt ≈ 0.8 · 0.0155/2 / c_d, 72 s
     ("about 3.16e+08 time steps", "Δt ≈ 2.28e-07 s")),
    (["discharge.duration=1e5"], "discharge.duration", ("about 4.39e+08 time steps",)),  # 100012 s / 2.28e-4 s
    (["discharge.mode=controlled", "discharge.velocity=10"], "discharge.velocity",
     ("0.368 of the solid's wave speed c_d = 27.2 m/s", "velocity ≤ 2.72 m/s")),
    (["material.cohesion=1e6"], "material.cohesion", ("could never yield",)),
], ids=["modulus", "surcharge", "density", "duration", "drive", "cohesion"])
def test_scenes_that_cannot_run_are_refused_before_meshing(overrides, key, fragments):
    """What the keys imply - self-weight strain, step count, drive against the wave speed - is
    checked before anything is meshed; each figure in the message is the closed form in the
    comment (ch. 4: ρ 1000, E 5.5e5, ν 0.3, c_d 27.21 m/s, h 0.0155, 72 s of fill, store and
    discharge)."""
    assert_names(refused(CH4, overrides), key, *fragments)



def test_a_bin_hopper_gets_a_station_at_its_transition():
    """The default stations of a bin-hopper include its transition, named so (evenly spaced
    ones step over the switch stress): the abrupt corner's height (0.25/tan 20° = 0.6869 m),
    a fillet's middle, the corner's wall arclength (0.25/sin 20° = 0.7310 m) by arclength;
    a scene's own labels are kept, and other shapes keep ten stations."""
    import math

    bin_ = {"shape": "bin_hopper", "radius": 0.35, "bin_height": 2.0, "hopper_half_angle": 20.0,
            "outlet_radius": 0.1, "element_size": 0.05}
    s = load_scene(scene_dict(bin_)).output
    assert len(s.stations) == 11 and s.station_labels.count("transition") == 1
    zt = s.stations[s.station_labels.index("transition")]
    assert abs(zt - 0.25 / math.tan(math.radians(20.0))) < 1e-6 and s.stations == sorted(s.stations)
    fillet = load_scene(scene_dict(dict(bin_, fillet_radius=0.3))).output
    zf = fillet.stations[fillet.station_labels.index("transition")]
    # the arc's middle: its centre is a tangent length R_f tan(α/2) above the corner, the middle
    # R_f sin(α/2) below the centre
    assert abs(zf - zt - 0.3 * (math.tan(math.radians(10.0)) - math.sin(math.radians(10.0)))) < 1e-6
    by_s = load_scene(scene_dict(bin_, output={"station_coordinate": "s"})).output
    assert abs(by_s.stations[by_s.station_labels.index("transition")] - 0.25 / math.sin(math.radians(20.0))) < 1e-6
    named = load_scene(scene_dict(bin_, output={"station_labels": [str(k) for k in range(11)]})).output
    assert named.station_labels == [str(k) for k in range(11)]
    assert len(load_scene(scene_dict(HOPPER)).output.stations) == 10


def test_a_flat_bottomed_discharge_is_told_what_holds_its_flow_before_it_runs():
    """A flat-bottomed silo's free discharge without recompaction and the surface slump decays or
    ends on a pit (docs/guide/your-silo.md, section 5: 174 -> 82 kg/s in 12 s); `silo check`
    says so before any step, naming exactly the keys that are missing - and nothing once they are
    set, for a controlled outlet, or for a hopper."""
    def advice(path, overrides=()):
        return [w for w in load_scene(SCENES / path, list(overrides)).warnings if "flat-bottomed" in w]

    both = advice("flat_bottom_ch6.toml")
    assert len(both) == 1 and "material.recompaction = true" in both[0] and "ale.max_surface_slope = 35" in both[0]
    one = advice("flat_bottom_ch6.toml", ["ale.max_surface_slope=35"])
    assert len(one) == 1 and "material.recompaction" in one[0] and "max_surface_slope" not in one[0]
    assert advice("flat_bottom_ch6.toml", ["ale.max_surface_slope=35", "material.recompaction=true"]) == []
    assert advice("flat_bottom_ch6_discharge.toml") == []  # sets both
    assert advice("flat_bottom_ch6.toml", ['discharge.mode="controlled"', "discharge.velocity=0.05"]) == []
    assert advice("hopper_ch4.toml") == []


def test_a_refined_outlet_on_a_structured_floor_is_told_it_makes_needles():
    """On a structured mesh with a floor the outlet's column of cells runs the silo's height, so
    outlet_size_factor 0.125 at h 0.02 m on the ch. 6 silo (outlet radius 0.02 m) makes 8 cells
    2.5 mm wide under rows 20 mm tall: 8× needles (58 % of the cells beyond 3×, meshed), which
    speed its discharge up by a third (docs/validation/ch6.md). `silo check` says so before any
    step with the element size that would keep max_aspect_ratio - and nothing at the factor that
    keeps 2× (0.5), on an unstructured mesh, without a discharge, or on a hopper."""
    def advice(path, overrides=()):
        return [w for w in load_scene(SCENES / path, list(overrides)).warnings if "needles" in w]

    quick = ["geometry.element_size=0.02"]
    eight = advice("flat_bottom_ch6_discharge.toml", quick + ["geometry.outlet_size_factor=0.125"])
    assert len(eight) == 1 and "8 cells" in eight[0] and "8.0× taller" in eight[0]
    assert "element_size ≤ 0.005 m" in eight[0] and 'geometry.mesh = "unstructured"' in eight[0]
    four = advice("flat_bottom_ch6_discharge.toml", quick + ["geometry.outlet_size_factor=0.25"])
    assert len(four) == 1 and "4.0× taller" in four[0]
    assert advice("flat_bottom_ch6_discharge.toml", quick + ["geometry.outlet_size_factor=0.5"]) == []
    assert advice("flat_bottom_ch6_discharge.toml", quick + ["geometry.outlet_size_factor=0.125",
                                                             'geometry.mesh="unstructured"']) == []
    assert advice("flat_bottom_ch6_discharge.toml", quick + ["geometry.outlet_size_factor=0.125",
                                                             'discharge.mode="none"']) == []
    assert advice("flat_bottom_ch6_discharge.toml") == []  # the scene as shipped: 2 cells of 10 mm, 1×
    assert advice("hopper_ch4.toml", ["geometry.outlet_size_factor=0.125", 'geometry.mesh="structured"']) == []
