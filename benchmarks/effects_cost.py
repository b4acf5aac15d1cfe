"""What each effect of a scene costs: the discharge step with every effect on, against the same
step with one effect switched off (or made cheaper), as ratios measured in one run.

    python benchmarks/effects_cost.py                 # serial, median of 5 (≈ 1.5 min)
    mpirun -n 2 python benchmarks/effects_cost.py --repeat 1

The test problem is the ch. 4 hopper's scene at h 0.04 m (1,076 cells; until 2026-12-05 the
ch. 3 mesh, `hopper_ch3_ale.toml` at h 0.08, whose outlet arches from K0 on the default cone:
benchmarks/accuracy_cost.py) started from a K0 state and discharged freely for ``--discharge``
s. A Lagrangian mesh of it tangles within 0.07 s, so the "ALE" row's Lagrangian step is the
all-on run's wall-clock less ALE's own timers (smoothing, remap, rebuild). "All on" is the most expensive scene:
non-coaxial plasticity with recompaction and a relaxation time (τ 0.1 ms; 1 ms's overstress held a
free discharge of the ch. 7 section back, tests/test_hard_cases.py), eq. 7-1 wall friction with the limit's memory, bulk viscosity, ALE every 10
steps with the surface slump (30°), the scene's re-meshing triggers and 120 tracers, wall and
interior-point histories at 200 Hz and field output every 0.1 s. Each row switches one of them
off (or to its cheaper setting) and reports the discharge stage's wall-clock per step (output
included) and the effect's share of the all-on step, 1 − t_without / t_all_on. A share near 0
(within the run-to-run noise, the spread column) means an effect that costs nothing when off
and little when on; what a scene switches off is never constructed
(tests/test_simulation.py::test_an_effect_that_is_off_is_not_built checks every effect).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import silo_dolfinx  # noqa: F401  (imports dolfinx_solver first where it exists)

HERE = Path(__file__).resolve().parents[1]
SCENE = HERE / "demos" / "scenes" / "hopper_ch4.toml"
MESH = ["geometry.element_size=0.04"]  # 1,076 cells: flows from K0 (the ch. 3 mesh, h 0.08, arches: accuracy_cost.py)

ALL_ON = ['material.model="non_coaxial"', "material.noncoaxial_modulus=5.6e4", 'wall.friction="velocity_dependent"',
          "wall.mu_static=0.3", "wall.mu_kinetic=0.2", "wall.decay=2.0", "wall.regularisation_length=5e-4", "numerics.bulk_viscosity=[0.06, 1.2]",
          "ale.enabled=true", "ale.frequency=10", "ale.tracer_rows=10", "ale.tracer_columns=12",
          "output.history_rate=200.0", "output.field_interval=0.1", "material.recompaction=true",
          "ale.max_surface_slope=30.0", "material.relaxation_time=1e-4"]

# effect -> (what it becomes, the overrides that switch it)
EFFECTS = {
    "non-coaxial term": ("coaxial Drucker-Prager", ['material.model="drucker_prager"']),
    "plasticity": ("elastic", ['material.model="elastic"']),
    "solid relaxation time (τ 0.1 ms)": ("rate-independent", ["material.relaxation_time=0.0"]),
    "friction memory (L 0.5 mm)": ("Coulomb's instantaneous limit", ["wall.regularisation_length=0.0"]),
    "eq. 7-1 friction": ("Coulomb", ['wall.friction="coulomb"', "wall.mu=0.3"]),
    "wall friction": ("smooth wall", ['wall.friction="none"', "wall.regularisation_length=0.0"]),
    "bulk viscosity": ("off", ["numerics.bulk_viscosity=[0.0, 0.0]"]),
    "ALE every 10 steps": ("every 40", ["ale.frequency=40"]),
    # a Lagrangian mesh of this hopper tangles within 0.07 s (138 steps): its step is the all-on
    # run's without ALE's own timers (smoothing, remap, rebuild), not a run of its own
    "ALE": ("Lagrangian (all on less ALE's timers)", None),
    "recompaction": ("off", ["material.recompaction=false"]),
    "surface slump (30°)": ("off", ["ale.max_surface_slope=0.0"]),
    "re-meshing triggers (the scene's)": ("off", ["ale.rezone_dt_fall=0.0", "ale.rezone_min_quality=0.0"]),
    "tracers (120)": ("none", ["ale.tracer_rows=0"]),
    "interior points (5, the scene's)": ("none", ["output.points=[]"]),
    "histories at 200 Hz": ("at 10 Hz", ["output.history_rate=10.0"]),
    "wall stations (10)": ("none", ["output.stations=[]"]),
    "field output every 0.1 s": ("none", ["output.field_interval=0.0"]),
    "shear-zone bands (20)": ("none", ["output.zone_bands=0"]),
}


def step_cost(sets: list[str], discharge: float, comm) -> tuple[float, float]:
    """Wall-clock per step of the discharge stage, and of it without ALE's own timers (s)."""
    from silo_dolfinx.scene import load_scene
    from silo_dolfinx.simulation import run

    sc = load_scene(SCENE, ['fill.method="k0"', "store.duration=0.0", f"discharge.duration={discharge}",
                            *MESH, *ALL_ON, *sets])
    out = Path(comm.bcast(tempfile.mkdtemp(prefix="fx_") if comm.rank == 0 else None, root=0))
    summary = run(sc, out, comm, progress_every=1e9)
    d = next(st for st in summary["stages"] if st["name"] == "discharge")
    ale = sum(d["ale"]["seconds"].values()) if "ale" in d else 0.0
    return d["wall_clock_s"] / d["steps"], (d["wall_clock_s"] - ale) / d["steps"]


def main() -> None:
    from mpi4py import MPI

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--discharge", type=float, default=1.0, help="seconds of free discharge")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    t0 = time.perf_counter()
    step_cost([], 0.05, comm)  # compile everything once
    cases = {"all on": []} | {k: v[1] for k, v in EFFECTS.items() if v[1] is not None}
    times = {k: [] for k in EFFECTS} | {"all on": []}
    for _ in range(args.repeat):  # interleaved, so that drifts of the machine hit every case alike
        for name, sets in cases.items():
            t, without_ale = step_cost(sets, args.discharge, comm)
            times[name].append(t)
            if name == "all on":
                times["ALE"].append(without_ale)
    if comm.rank:
        return
    base = statistics.median(times["all on"])
    spread = (max(times["all on"]) - min(times["all on"])) / base if len(times["all on"]) > 1 else 0.0
    print(f"\n{SCENE.name}: K0 start, {args.discharge:g} s free discharge, {comm.size} rank(s), median of "
          f"{args.repeat}; all on: {1e3 * base:.3f} ms/step (run-to-run spread {100 * spread:.0f} %)")
    print("| effect (all on →) | switched to | ms/step | share of the all-on step |")
    print("|---|---|---|---|")
    for name, (to, _) in EFFECTS.items():
        t = statistics.median(times[name])
        print(f"| {name} | {to} | {1e3 * t:.3f} | {100 * (1 - t / base):+.0f} % |")
    print(f"\n(total {time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
