"""What accuracy costs in time: one table per accuracy knob.

    python benchmarks/accuracy_cost.py                      # every knob (≈ 45 min on one core)
    python benchmarks/accuracy_cost.py --knobs time_step_scale remap_order
    python benchmarks/accuracy_cost.py --knobs table_3_2    # the thesis' Table 3-2 (≈ 2 min)
    python benchmarks/accuracy_cost.py --knobs table_3_2 --realisations 5   # each row a median of 5 (≈ 3 min)
    python benchmarks/accuracy_cost.py --knobs table_3_2_beyond   # its scales past 1.0 (≈ 4 min)
    python benchmarks/accuracy_cost.py --knobs table_3_2_filled   # on the thesis' mesh, filled (≈ 35 min)
    python benchmarks/accuracy_cost.py --knobs integration integration_filling   # ≈ 3 min

Every accuracy knob of a scene - a key that changes how closely a run approximates the same silo
and solid, and what it costs (``ACCURACY_KNOBS`` in silo_dolfinx/scene/schema.py, whose docs
name the command) - has a table here; tests/test_scene.py holds the two lists to each other and
loads every row's scene. Each knob is run on one of a few small test problems and compared with
its most accurate setting (the reference row, marked *), or, where no setting is more accurate by
construction (smoothing sweeps, weights, objective, predictor, hourglass viscosity, fill ramp,
re-meshing), with the default:

* **discharge** — the ch. 4 hopper (its scene, unstructured, coarsened to h 0.04 m: 1,076
  cells) from a K0 state, stored 0.3 s and discharged freely for ``--discharge`` s with ALE. p̄_w: the wall normal pressure at the
  output stations averaged over the second half of the discharge, error = mean over stations
  of |p̄ − p̄_ref| / mean p̄_ref; W: the mean mass flow over the second half, error
  |W − W_ref| / W_ref; E: the run's own energy-balance error.
  Variants of it: on a structured mesh (``max_aspect_ratio`` acts only there), with the outlet
  refined (``refinement_distance``), and for 60 s (the re-meshing knobs: with the scene's settings
  it re-meshes from ~46 s, never re-meshing it ends on the mesh's quality; p̄_w and W over the
  second half of what ran).
* **bin_hopper** — the ch. 7 abrupt bin-hopper at h 0.04 m from K0 on Mohr–Coulomb's pyramid
  (on the scene's cone an arch holds over its outlet at this mesh), its outlet opened to 1 m/s
  over 0.5 s: ``transition_size_factor`` acts at its corner (a wall station is there). Its flow is
  prescribed, so W is no measure; p̄_w is.
* **snapshot** (Table 3-2) — the same hopper and mesh, 0.5 s into the discharge: S0 of eq. 3-13,
  √(mean((P_i − P_i0)/P_i0)²), over the wall nodes, P_i0 from the scale-0.01 run (the thesis'
  reference), at one instant as the thesis defines it. Nodes where P_i0 is below 5 % of its
  largest value (the free surface and the outlet edge, where the relative deviation of a
  near-zero pressure is meaningless) are left out.
* **filling** (Fig. 3-19 and the filling knobs) — the ch. 4 hopper on a coarse mesh (h 0.04
  m, 1,219 cells) filled in layers, stored 1 s and discharged 2 s: S0 (eq. 3-13, same node
  selection) of the wall-pressure profile at the end of filling, 2 s into the discharge (an
  instant, as Fig. 3-19(b)), and of the station pressures averaged over those 2 s (eq. 4-9).

**Why not the thesis' ch. 3 mesh** (`hopper_ch3_ale.toml`: the same hopper, 15 × 50
structured cells, h 0.08 m; these problems ran on it until 2026-12-05). From a K0 state, under
the scenes' compression-matched cone with 2 × 2 points, its outlet - 1.25 cells across the
radius - arches: measured serially, 3.6 kg out in the first 0.25 s, 4.7 kg by 0.5 s, 5.5 kg by
10 s. At h 0.06 (1,180 cells) it flows, but not regularly: 2-s flows of 29.0-36.3 kg/s and
station pressures 4-34 % apart between time-step scales 0.2-0.9 (scale 0.4: 14 % off in flow,
34 % in pressure), and frequency 5 arched (7.1 kg/s). A table of such a problem measures when
an arch closes, not what a knob buys. The ch. 4 scene's own mesh, coarsened to 0.04 m, flows
regularly: 33.16 / 33.56 / 33.68 kg/s at scales 0.8 / 0.4 / 0.2, 33.64 and 34.19 at
frequencies 5 and 1, station pressures within a few per cent. (On Mohr–Coulomb's pyramid the
ch. 3 mesh flows regularly too, 42.9-43.6 kg/s; filled in layers it flows on the cone, 34.5
kg/s: the arch is the K0 start's on the circumscribed cone.) The mesh row keeps h 0.08 to show
an arching row (``arched`` beside its flow).

The snapshot and filling problems also give S0 of the wall pressure averaged over the
``WINDOW`` (0.05 s) before the instant - 60 wall stations sampled as interval means (the
``history_sampling = "mean"`` default), the last sample being that window - over the whole
wall and above the outlet zone: the thesis' instant with its step-to-step chatter averaged
out (a few hundred steps), which the thesis does not define but which says whether a knob
moves the pressure or only the chatter.

The instantaneous pressure of a flowing solid is chaotic: a change that should not matter
moves it. So the snapshot and filling tables carry a **floor** row — the reference setting
with Δt × 0.99 (time_step_scale 0.792 for the default 0.8; 0.0099 in Table 3-2) — the deviation an immaterial
perturbation causes; a knob's deviation below its floor is not resolved by the measure. The
outlet-edge and free-surface wall nodes (the profile's ends, stress singularities where the
wall meets the outlet and the top) are left out of S0 with the near-zero pressures. In the
lowest fifth of the fill the solid accelerates into the outlet and the wall pressure swings
most (on the arching ch. 3 mesh, 0.05–0.5 s after opening, scale 0.01: standard deviation /
mean 1.5 at z = 0.1 m, out of contact 24 % of the time, and 0.9 at 0.33 m; 0.08 and 0.05 at
0.66 and 0.99 m): an instant there is a sample of contact chatter, and it dominates S0 over
the whole wall; a second S0 column leaves that zone out.

Wall-clock is the whole run (meshing excluded), serial, median of ``--repeat`` runs. Mass
scaling changes the physics it speeds up (inertia): its error column says by how much.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import silo_dolfinx  # noqa: F401

HERE = Path(__file__).resolve().parents[1]
SCENES = HERE / "demos" / "scenes"
RELEVANT = 0.05  # S0 leaves out nodes whose reference pressure is below this fraction of its largest
OUTLET_ZONE = 0.2  # the lowest fifth of the fill: the flowing zone at the outlet (see the docstring)
WINDOW = 0.05  # s: Table 3-2's S0 also of the wall pressures averaged over this window before the instant


@dataclass(frozen=True)
class Problem:
    scene: str
    overrides: tuple[str, ...]
    flow: bool = False  # measured by its mass flow and mean station pressures (else by S0 of profiles)


PROBLEMS = {
    "discharge": Problem("hopper_ch4.toml", ('fill.method="k0"', "store.duration=0.3", "geometry.element_size=0.04",
                                             "discharge.duration={discharge}"), flow=True),
    # the same with one-point cells: the hourglass control's knobs act only there
    "discharge_reduced": Problem("hopper_ch4.toml", ('fill.method="k0"', "store.duration=0.3", "geometry.element_size=0.04",
                                                     'numerics.integration="reduced"', "discharge.duration={discharge}"),
                                 flow=True),
    # Table 3-2 on the thesis' own ch. 3 mesh, filled in its ten layers and stored (it flows then)
    "snapshot_filled": Problem("hopper_ch3_ale.toml", ("discharge.duration=0.5",)),
    "snapshot": Problem("hopper_ch4.toml", ('fill.method="k0"', "store.duration=0.3", "geometry.element_size=0.04",
                                            "discharge.duration=0.5")),
    "filling": Problem("hopper_ch4.toml", ("geometry.element_size=0.04", "fill.layers=5", "fill.duration=5.0",
                                           "store.duration=1.0", "discharge.duration=2.0")),
    # the discharge problem on a structured mesh (max_aspect_ratio acts only there) and with its
    # outlet refined (refinement_distance acts only there)
    "discharge_structured": Problem("hopper_ch4.toml", ('fill.method="k0"', "store.duration=0.3",
                                                        "geometry.element_size=0.04", 'geometry.mesh="structured"',
                                                        "discharge.duration={discharge}"), flow=True),
    "discharge_refined": Problem("hopper_ch4.toml", ('fill.method="k0"', "store.duration=0.3",
                                                     "geometry.element_size=0.04", "geometry.outlet_size_factor=0.5",
                                                     "discharge.duration={discharge}"), flow=True),
    # the re-meshing knobs' problem: 60 s of the discharge problem (with the scene's re-meshing it
    # re-meshes from ~46 s, when the draining fill has squeezed its top rows; measured over 30-60 s).
    # Never re-meshing is no reference: the run then ends on discharge.min_mesh_quality (a top cell)
    "discharge_long": Problem("hopper_ch4.toml", ('fill.method="k0"', "store.duration=0.3",
                                                  "geometry.element_size=0.04", "discharge.duration=60.0"), flow=True),
    # a silo with a transition (transition_size_factor acts only there): the ch. 7 abrupt bin-hopper
    # at h 0.04 m from K0, its outlet opened to the scene's 1 m/s over 0.5 s (the flow is prescribed,
    # so W is not a measure here; p_w is, with a station at the corner). On Mohr-Coulomb's pyramid:
    # on the scene's cone (φ 40° > 36.87°) an arch holds over the outlet at this mesh and the cell
    # under it empties (1.0 s after opening from K0, 0.56 s after it was filled in the scene's layers)
    "bin_hopper": Problem("bin_hopper_ch7_abrupt.toml", ('fill.method="k0"', "store.duration=0.3",
                                                         "geometry.element_size=0.04", 'material.model="mohr_coulomb"',
                                                         "discharge.ramp_time=0.5", "discharge.duration={discharge}"),
                          flow=True),
}

# knob -> (problem, scene key, values, reference value); the reference is the most accurate setting
KNOBS = {
    "time_step_scale": ("discharge", "numerics.time_step_scale", [0.9, 0.8, 0.6, 0.4], 0.2),
    "table_3_2": ("snapshot", "numerics.time_step_scale", [0.1, 0.3, 0.5, 0.8, 1.0], 0.01),
    "table_3_2_filled": ("snapshot_filled", "numerics.time_step_scale", [0.1, 0.3, 0.5, 0.8, 1.0], 0.01),
    # Table 3-2 carried past 1.0, towards the estimate's stability limit (benchmarks/stable_dt.py: 1-1.5)
    "table_3_2_beyond": ("snapshot", "numerics.time_step_scale", [1.0, 1.1, 1.2, 1.3, 1.4, 1.5], 0.01),
    "mesh_size": ("discharge", "geometry.element_size", [0.08, 0.06, 0.04], 0.03),
    # cells across the outlet radius (0.1 m at h 0.04: 2.5 / 5 / 10 / 20)
    "outlet_size_factor": ("discharge", "geometry.outlet_size_factor", [1.0, 0.5, 0.25], 0.125),
    "smoothing_frequency": ("discharge", "ale.frequency", [50, 20, 10, 5], 1),
    "remap_order": ("discharge", "ale.remap_order", [1], 2),
    # where the smoothing starts the interior (no setting is more accurate by construction: the
    # reference is the long-standing default)
    "smoothing_predictor": ("discharge", "ale.predictor", ['"stretched"', '"current"'], '"previous"'),
    "mass_scaling": ("discharge", "numerics.mass_scaling", [100.0, 25.0, 4.0], 1.0),
    "bulk_viscosity": ("filling", "numerics.bulk_viscosity", [[0.0, 0.0], [0.12, 2.4]], [0.06, 1.2]),
    "fill_layers": ("filling", "fill.layers", [2, 5, 10], 20),
    "fill_duration": ("filling", "fill.duration", [1.0, 2.0, 5.0], 10.0),
    "fill_damping": ("filling", "fill.damping", [0.05, 0.1, 0.3], 0.0),
    # one point + hourglass control against 2 × 2 points; the stiffness form against none
    "integration": ("discharge", "numerics.integration", ['"reduced"'], '"full"'),
    "integration_filling": ("filling", "numerics.integration", ['"reduced"'], '"full"'),
    "hourglass_stiffness": ("discharge_reduced", "numerics.hourglass_stiffness", [0.05, 0.01], 0.0),
    "hourglass_viscosity": ("discharge_reduced", "numerics.hourglass_viscosity", [0.3, 0.03], 0.1),
    # the mesh: structured against the scene's unstructured one; the aspect cap of a structured
    # mesh; how far the outlet's refinement reaches; the transition's refinement
    "mesh_type": ("discharge", "geometry.mesh", ['"structured"'], '"unstructured"'),
    "max_aspect_ratio": ("discharge_structured", "geometry.max_aspect_ratio", [4.0, 2.0], 1.0),
    "refinement_distance": ("discharge_refined", "geometry.refinement_distance", [0.075, 0.15], 0.3),
    "transition_size_factor": ("bin_hopper", "geometry.transition_size_factor", [1.0, 0.5], 0.25),
    # the ALE: none at all (a Lagrangian mesh tangles); smoothing sweeps, weights and objective
    # (comparisons with the default: more smoothing is not more accurate by construction);
    # re-meshing (comparisons with the ch. 4 scene's settings)
    "lagrangian": ("discharge", "ale.enabled", ["false"], "true"),
    "smoothing_sweeps": ("discharge", "ale.sweeps", [2, 4], 1),
    "laplacian_weight": ("discharge", "ale.laplacian_weight", [0.0, 0.25], 0.5),
    "mid_area_weight": ("discharge", "ale.mid_area_weight", [0.0, 0.25], 0.5),
    "smoothing_objective": ("discharge", "ale.smoothing_objective", ['"uniform"'], '"graded"'),
    "rezone_dt_fall": ("discharge_long", "ale.rezone_dt_fall", [0.0, 0.02, 0.1], 0.05),
    "rezone_min_quality": ("discharge_long", "ale.rezone_min_quality", [0.0, 0.5], 0.3),
    # how the initial state is made: a geostatic start or a gravity ramp against layers; the
    # layers' ramp share; storage (the reference stores longest)
    "fill_method": ("filling", "fill.method", ['"k0"', '"ramp"'], '"layers"'),
    "fill_ramp_fraction": ("filling", "fill.ramp_fraction", [1.0, 0.25], 0.5),
    "store_duration": ("filling", "store.duration", [0.3, 1.0], 2.0),
    "store_kinetic_energy_tol": ("filling", "store.kinetic_energy_tol", [1e-4, 1e-5, 1e-6], 0.0),
}


def profile(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(z, p_n) of a wall profile, sorted by height."""
    from silo_dolfinx.output import read_csv

    d = read_csv(path)
    order = np.argsort(d["z"])
    return d["z"][order], d["p_n"][order]


def s0(z, p, z_ref, p_ref, ends: bool = False, z_min: float = -np.inf) -> float:
    """Eq. 3-13 against the reference profile, on the reference's nodes above z_min that carry
    pressure (without the profile's two end nodes unless ``ends``)."""
    from silo_dolfinx.analysis import representative_deviation

    keep = (p_ref > RELEVANT * p_ref.max()) & (z_ref > z_min)
    keep[[0, -1]] &= ends  # the outlet edge and the free-surface edge
    return representative_deviation(np.interp(z_ref[keep], z, p), p_ref[keep])


def overrides(problem: str, key: str, value, discharge: float, extra: tuple[str, ...] = ()) -> list[str]:
    """The scene overrides of one row: the problem's, no field output, 100-Hz histories, the knob's
    value, then ``extra``."""
    text = str(value).lower() if not isinstance(value, list) else "[" + ", ".join(map(str, value)) + "]"
    return [o.format(discharge=discharge) for o in PROBLEMS[problem].overrides] + [
        "output.field_interval=0", "output.history_rate=100.0", f"{key}={text}", *extra]


def run_case(problem: str, key: str, value, discharge: float, extra: tuple[str, ...] = ()) -> dict:
    from mpi4py import MPI

    from silo_dolfinx.output import read_csv
    from silo_dolfinx.scene import load_scene
    from silo_dolfinx.simulation import run

    pr = PROBLEMS[problem]
    sets = overrides(problem, key, value, discharge, extra)
    if not pr.flow:  # 60 wall stations sampled as 0.05-s means: the last is the window before the instant
        top = load_scene(SCENES / pr.scene, sets).outline.fill_height
        sets += [f"output.stations=[{', '.join(f'{z:.4f}' for z in np.linspace(0.01, 0.99, 60) * top)}]",
                 f"output.history_rate={1.0 / WINDOW}"]
    scene = load_scene(SCENES / pr.scene, sets)
    out = Path(tempfile.mkdtemp(prefix="acc_"))
    t0 = time.perf_counter()
    summary = run(scene, out, MPI.COMM_SELF, progress_every=1e9)
    r = {"wall": time.perf_counter() - t0, "steps": summary["steps"], "cells": summary["cells"],
         "energy": summary["energy_balance_error_max"], "outlet_zone": OUTLET_ZONE * scene.geometry.fill_height}
    h = read_csv(out / "wall_history.csv")
    d = next(st for st in summary["stages"] if st["name"] == "discharge")
    if pr.flow:
        late = h["t"] >= 0.5 * (d["t_start"] + d["t_end"])  # the second half, as the flow below
        r["p"] = np.array([h["p_n"][late & (h["station"] == k)].mean() for k in sorted(set(h["station"]))])
        r["flow"] = d.get("mean_mass_flow_rate_second_half", float("nan"))
        r["arched"] = any(w.startswith("[discharge] the flow stopped") for w in summary["warnings"])  # the run's own test
        r["remeshes"] = len(d.get("rezones", []))
        r["ended"] = d.get("ended_on", "duration")
    else:
        # a K0 start has no filling stage: its end of filling is the end of its storage
        files = {"fill": "store" if scene.fill.method == "k0" else "fill", "discharge": "discharge"}
        r["profiles"] = {stage: profile(out / f"wall_profile_{files[stage]}.csv")
                         for stage in (("fill", "discharge") if problem == "filling" else ("discharge",))}
    if not pr.flow:  # the stations' last interval mean: the 0.05 s before the instant
        last = np.isclose(h["t"], h["t"].max())
        order = np.argsort(h["z"][last])
        r["profiles"]["window"] = (h["z"][last][order], h["p_n"][last][order])
    if problem == "filling":
        from silo_dolfinx.analysis import station_means

        r["profiles"]["mean"] = station_means(h, d["t_start"], d["t_end"])
    return r


def errors(problem: str, r: dict, r0: dict) -> list[tuple[str, str]]:
    """(column, value) pairs of one row against the reference row."""
    if PROBLEMS[problem].flow:
        ep = float(np.mean(np.abs(r["p"] - r0["p"])) / np.mean(np.abs(r0["p"])))
        ew = abs(r["flow"] - r0["flow"]) / abs(r0["flow"])
        arched = " (arched)" if r["arched"] else ""
        early = f" (ended on {r['ended']})" if r["ended"] != "duration" else ""
        return [("p_w error", f"{100 * ep:.2f}%"), ("W kg/s", f"{r['flow']:.2f}{arched}{early}"),
                ("W error", f"{100 * ew:.2f}%"), ("E error", f"{100 * r['energy']:.2f}%"), ("re-meshes", f"{r['remeshes']}")]
    names = {"fill": "S0 end of fill", "discharge": "S0 discharge (instant)", "mean": "S0 discharge (mean)",
             "window": f"S0 of the {WINDOW:g}-s mean before the instant"}
    cols = [(names[st], f"{s0(*r['profiles'][st], *r0['profiles'][st], st == 'mean'):.4f}") for st in r0["profiles"]]
    cols.append(("S0 instant, above the outlet zone",
                 f"{s0(*r['profiles']['discharge'], *r0['profiles']['discharge'], z_min=r0['outlet_zone']):.4f}"))
    if "window" in r0["profiles"]:
        cols.append(("S0 of the mean, above the outlet zone",
                     f"{s0(*r['profiles']['window'], *r0['profiles']['window'], z_min=r0['outlet_zone']):.4f}"))
    return cols + [("E error", f"{100 * r['energy']:.2f}%")]


def realisation(key: str, value, j: int):
    """The j-th realisation of a row: (its value, extra overrides) with Δt × (1 + 0.01 k), k = 0,
    −1, +1, −2, +2, … - of the knob's own value for a Δt knob, else of the default scale 0.8."""
    k = (j + 1) // 2 * (1 if j % 2 == 0 else -1)
    if key == "numerics.time_step_scale":
        return round(value * (1 + 0.01 * k), 6), ()
    return value, ((f"numerics.time_step_scale={0.8 * (1 + 0.01 * k):.6g}",) if k else ())


def median_columns(columns: list[list[tuple[str, str]]]) -> list[tuple[str, str]]:
    """Column by column, the median over realisations of errors()' numbers (same formats)."""
    out = []
    for j, (name, text) in enumerate(columns[0]):
        pct = text.endswith("%")
        m = statistics.median(float(c[j][1].rstrip("%")) for c in columns)
        out.append((name, f"{m:.2f}%" if pct else f"{m:.4f}"))
    return out


def table(name: str, discharge: float, repeat: int, realisations: int = 1) -> None:
    problem, key, values, ref = KNOBS[name]
    rows = [(ref, ()), *((v, ()) for v in values)]
    if not PROBLEMS[problem].flow:  # the same setting with Δt × 0.99 (of the reference's step, for a Δt knob)
        scale = 0.99 * (ref if key == "numerics.time_step_scale" else 0.8)
        rows.append((f"floor: {ref}, Δt × 0.99", (f"numerics.time_step_scale={scale:.6g}",)))
    from silo_dolfinx.solver import InstabilityError

    results = []
    for v, extra in rows:
        try:
            runs = [run_case(problem, key, ref if extra else v, discharge, extra) for _ in range(repeat)]
        except InstabilityError as err:  # a setting past the stability limit: a row that says so
            results.append({"unstable": str(err)})
            continue
        results.append(runs[0] | {"wall": statistics.median(r["wall"] for r in runs)})
    r0 = results[0]
    if "unstable" in r0:  # no reference, no errors: say so and go on with the next table
        print(f"\n{name} ({key}, {problem} problem): the reference {ref} did not run: {r0['unstable']}", flush=True)
        return
    # S0 at an instant is one realisation of a chaotic flow: with ``realisations`` > 1 each
    # setting's row is the median over runs whose Δt differs by ±1 %, ±2 %, ... (not the
    # reference or the floor)
    several = realisations > 1 and not PROBLEMS[problem].flow
    for (v, extra), r in zip(rows[1:], results[1:]):
        if several and not extra and "unstable" not in r:
            runs = [run_case(problem, key, val, discharge, ex)
                    for val, ex in (realisation(key, v, j) for j in range(1, realisations))]
            r["columns"] = median_columns([errors(problem, x, r0) for x in [r, *runs]])
    print(f"\n{name} ({key}, {problem} problem); reference {ref}*"
          + (f"; each setting the median of {realisations} realisations (Δt ± 1 %, ± 2 %, ...)" if several else ""))
    head = ["value", "cells", "steps", "wall s", "speed-up"] + [c for c, _ in errors(problem, r0, r0)]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for (v, _), r in zip(rows, results):
        if "unstable" in r:
            print(f"| {v} | unstable: {r['unstable'][:160]} |" + " |" * (len(head) - 2), flush=True)
            continue
        cells = [f"{v}{'*' if r is r0 else ''}", f"{r['cells']}", f"{r['steps']:,}", f"{r['wall']:.1f}",
                 f"{r0['wall'] / r['wall']:.2f}x"] + [x for _, x in r.get("columns", errors(problem, r, r0))]
        print("| " + " | ".join(cells) + " |", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--knobs", nargs="+", default=list(KNOBS), choices=list(KNOBS))
    ap.add_argument("--discharge", type=float, default=2.0, help="seconds of discharge of the discharge problem")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--realisations", type=int, default=1,
                    help="S0 tables (Table 3-2, the filling knobs): each setting the median over this many runs whose "
                         "Δt differs by ±1 %%, ±2 %%, ... (an instant of a flowing solid is one realisation of chaos)")
    args = ap.parse_args()
    print("Accuracy against wall-clock, serial; test problems: " + "; ".join(
        f"{k} = {p.scene} with {', '.join(p.overrides).format(discharge=args.discharge)}" for k, p in PROBLEMS.items()))
    # compile (or load from numba's cache) the kernels before timing: the full and, if a table
    # needs them, the one-point ones
    for problem in ("discharge", "discharge_reduced"):
        if problem == "discharge" or any(KNOBS[k][0] == problem for k in args.knobs):
            run_case(problem, "numerics.time_step_scale", 0.8, 0.05)
    for k in args.knobs:
        table(k, args.discharge, args.repeat, args.realisations)


if __name__ == "__main__":
    main()
