"""Soak: the hard cases of tests/test_hard_cases.py, run long, with the same checks as a table.

    python benchmarks/soak.py                         # serial: every case, 10 s of discharge
    mpirun -n 2 python benchmarks/soak.py             # the same on 2 ranks, then 1-vs-2 rank columns
    python benchmarks/soak.py --cases long_discharge --cone compression
    python benchmarks/soak.py --discharge 1 --set numerics.integration='"reduced"' --tag reduced

The cases are the test file's (one list: ``CASES`` there), each with its discharge lengthened to
``--discharge`` s, plus two only a soak can afford: ``long_discharge`` (the ch. 3 hopper, 645
cells, 30 s of free discharge) and ``until_empty`` (a small hopper discharged for as long as it
takes to empty). ``--cone`` runs them on another cone than the tests' (``extension``), e.g. the
scenes' default ``compression``. Results go to ``results/soak/CASE_CONE_nRANKS/``; every row is
:func:`silo_dolfinx.analysis.run_health` of its folder (energy and mass balance errors are the
largest over the run; the worst cell over every sample). A run that stops early is a row too,
with its reason. When the folder of the other rank count exists (run the script serially, then
on 2 ranks), two more columns compare them: the largest relative difference of the end-of-store
wall pressures, and of the discharged mass.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import silo_dolfinx  # noqa: F401  (imports dolfinx_solver first where it exists)

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from test_hard_cases import CASES, SHORT  # noqa: E402  (the one list of hard cases)

SCENES = ROOT / "demos" / "scenes"
EXTRA = {
    "long_discharge": ("hopper_ch3_ale", ['discharge.mode="free"', "output.stations=[0.3, 1.0, 2.0]"], 30.0,
                       "the ch. 3 hopper (645 cells), 30 s of free discharge"),
    "until_empty": ("hopper_ch4", ["geometry.height=0.6", "geometry.top_radius=0.3", "geometry.outlet_radius=0.08",
                                   "geometry.element_size=0.03", 'geometry.mesh="structured"', 'discharge.mode="free"',
                                   "output.stations=[0.1, 0.3, 0.5]"], 10.0,
                    "a 0.6-m hopper (230 cells) discharged until it empties (~4 s)"),
}


def cases(discharge: float) -> dict[str, tuple[str, list[str], str]]:
    """name -> (scene, overrides, what it is), the test cases lengthened to ``discharge`` s."""
    out = {name: (scene, sets + [f"discharge.duration={discharge}"], what) for name, (scene, sets, what) in CASES.items()}
    out.update({name: (scene, sets + [f"discharge.duration={d}"], what) for name, (scene, sets, d, what) in EXTRA.items()})
    return out


def run_case(name: str, scene: str, sets: list[str], cone: str, comm, tag: str = "") -> tuple[Path, float]:
    from silo_dolfinx.scene import load_scene
    from silo_dolfinx.simulation import run

    out = ROOT / "results" / "soak" / f"{name}_{cone}{'_' + tag if tag else ''}_n{comm.size}"
    sc = load_scene(SCENES / f"{scene}.toml", SHORT + sets + [f'material.cone="{cone}"'])
    t0 = time.time()
    try:
        run(sc, out, comm, progress_every=30.0)
    except Exception as err:  # noqa: BLE001 - a case that stops is a row, with its reason
        if comm.rank == 0:
            print(f"  {name}: stopped: {err}", flush=True)
    return out, time.time() - t0


def rank_difference(out: Path, other: Path) -> tuple[float, float]:
    """(max relative difference of the end-of-store wall p_n, of the final discharged mass)."""
    from silo_dolfinx.output import read_csv

    a, b = (read_csv(f / "wall_profile_store.csv") for f in (out, other))
    oa, ob = (read_csv(f / "outlet.csv") for f in (out, other))
    if a is None or b is None or a["p_n"].size != b["p_n"].size:
        return np.nan, np.nan
    dp = float(np.max(np.abs(a["p_n"] - b["p_n"])) / max(np.abs(b["p_n"]).max(), 1e-300))
    dm = float(abs(oa["discharged_mass"][-1] - ob["discharged_mass"][-1]) / max(ob["discharged_mass"][-1], 1e-300)) \
        if oa is not None and ob is not None else np.nan
    return dp, dm


def main(argv=None) -> int:
    from mpi4py import MPI

    from silo_dolfinx.analysis import run_health

    all_cases = cases(10.0)
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--discharge", type=float, default=10.0, help="s of discharge for the test cases (default 10)")
    ap.add_argument("--cone", default="extension", help="material.cone for every case (default extension)")
    ap.add_argument("--cases", nargs="+", choices=sorted(all_cases), default=list(all_cases))
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                    help="an override for every case (repeatable), e.g. numerics.integration='\"reduced\"'")
    ap.add_argument("--tag", default="", help="suffix of the results folders (to keep variants apart)")
    args = ap.parse_args(argv)
    comm = MPI.COMM_WORLD
    chosen = {k: v for k, v in cases(args.discharge).items() if k in args.cases}
    rows = []
    for name, (scene, sets, what) in chosen.items():
        if comm.rank == 0:
            print(f"[soak] {name} ({args.cone} cone, {comm.size} rank(s)): {what}", flush=True)
        out, wall = run_case(name, scene, sets + args.set, args.cone, comm, args.tag)
        comm.barrier()
        if comm.rank == 0:
            h = run_health(out)
            other = out.with_name(out.name[:out.name.rindex("_n")] + f"_n{1 if comm.size > 1 else 2}")
            dp, dm = rank_difference(out, other) if other.is_dir() else (np.nan, np.nan)
            rows.append((name, h, wall, dp, dm))
    if comm.rank == 0:
        variant = "; " + " ".join(args.set) if args.set else ""
        print(f"\nHard cases, long ({args.cone} cone, {comm.size} rank(s){variant}; bars: energy < 1 %, mass < 0.5 %, "
              "min scaled Jacobian > 0.2, p_n < 3 ρgH)\n")
        print("| case | status | t (s) | energy err. max | mass err. max | min scaled Jacobian | p_n max / ρgH "
              "| discharged | steps | steps/s | Δt min (s) | 1 vs 2 ranks: p_n store | discharged |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for name, h, wall, dp, dm in rows:
            frac = h["discharged_mass"] / h["mass_at_opening"] if h["mass_at_opening"] > 0 else np.nan
            print(f"| {name} | {h['status']} | {h['simulated_time']:.3g} | {100 * h['energy_error_max']:.3f} % "
                  f"| {h['mass_error_max']:.1e} | {h['min_scaled_jacobian']:.2f} | {h['p_max_over_rho_g_h']:.2f} "
                  f"| {100 * frac:.1f} % | {h['steps']} | {h['steps'] / max(wall, 1e-9):.0f} | {h['dt_min']:.2g} "
                  f"| {dp:.1e} | {dm:.1e} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
