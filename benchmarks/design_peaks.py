"""How far to trust a discharge's peaks: the design-pressure ratios of ``silo report``
(``design_pressures.csv``: per wall station the discharge's mean over its first 10 s, its 99th
percentile and its largest p_n, each over EN 1991-4's load) against what a run chooses - the
mesh, the history rate, how a sample is taken - and against a perturbation that should not
matter (the realisation).

    python benchmarks/design_peaks.py                             # the README's first silo, 2 ranks (~8 min)
    python benchmarks/design_peaks.py --finest                    # and h / 4 (~+25 min)
    python benchmarks/design_peaks.py --finest --variants "h / 4"  # only that one beside the scene as given
    python benchmarks/design_peaks.py --scene my_silo.toml --set discharge.duration=6 --ranks 2

Each variant is the scene as given with one change, run with ``silo run`` under ``mpirun -n
--ranks`` and reported with :meth:`silo_dolfinx.report.Report.design_pressures`:

* **realisations** - Δt × 0.99 and × 0.98 (``numerics.time_step_scale``): the flow of a
  granular solid through an outlet is chaotic, an immaterial change moves its instants, and the
  spread of these rows is the floor below which a difference is not resolved;
* **the history** - 1000 Hz instead of the scene's rate (each sample the mean over 1 ms
  instead of 5 ms), and instants at the scene's rate (``output.history_sampling = "instant"``:
  the step at the sample, unfiltered);
* **the mesh** - ``geometry.element_size`` halved (and quartered with ``--finest``).

The first table gives per variant its cost and, for the mean, the 99th percentile and the
largest, the largest ratio over the stations and where, and the median over stations of the
ratio's relative change against the scene as given; the second gives the 99th-percentile and
largest ratios station by station. What the rows say for the first silo is in
docs/guide/your-silo.md ("How far to trust the peaks").
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parents[1]
SCENE = HERE / "demos" / "scenes" / "first_silo.toml"
MEASURES = (("mean", "mean_over_en"), ("p99", "p99_over_en"), ("max", "max_over_en"))


def variants(scene_path: Path, sets: list[str], finest: bool) -> dict[str, list[str]]:
    """Name -> the overrides of that variant (after ``sets``)."""
    from silo_dolfinx.scene import load_scene

    scene = load_scene(scene_path, sets)
    scale, h, rate = scene.numerics.time_step_scale, scene.geometry.element_size, scene.output.history_rate
    v = {"as given": [],
         "Δt × 0.99": [f"numerics.time_step_scale={0.99 * scale:.6g}"],
         "Δt × 0.98": [f"numerics.time_step_scale={0.98 * scale:.6g}"],
         "histories 1000 Hz": ["output.history_rate=1000.0"],
         f"instants at {rate:g} Hz": ['output.history_sampling="instant"'],
         f"h / 2 ({h / 2:.4g} m)": [f"geometry.element_size={h / 2:.6g}"]}
    if finest:
        v[f"h / 4 ({h / 4:.4g} m)"] = [f"geometry.element_size={h / 4:.6g}"]
    return v


def one_run(scene_path: Path, ranks: int, sets: list[str]) -> dict:
    """Run the scene with ``sets``, report its design pressures; cost and the CSV's columns."""
    from silo_dolfinx.output import read_csv, read_summary
    from silo_dolfinx.report import Report

    out = Path(tempfile.mkdtemp(prefix="design_peaks_"))
    silo = Path(sys.executable).with_name("silo")
    mpirun = Path(sys.executable).with_name("mpirun")
    cmd = [str(mpirun) if mpirun.exists() else "mpirun", "-n", str(ranks), str(silo), "run", str(scene_path),
           "--out", str(out), "--progress", "1e9", "--set", "output.field_interval=0",
           *sum((["--set", s] for s in sets), [])]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, env=os.environ.copy())
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{done.stderr[-2000:]}")
    Report(out).design_pressures()
    s = read_summary(out)
    return {"cells": s["cells"], "steps": s["steps"], "wall": wall, "d": read_csv(out / "design_pressures.csv")}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", type=Path, default=SCENE)
    ap.add_argument("--set", dest="sets", action="append", default=[], help="scene overrides of every variant")
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--finest", action="store_true", help="also the element size quartered")
    ap.add_argument("--variants", nargs="+", metavar="START",
                    help="only the variants whose names start so (besides the scene as given), e.g. 'h / 4'")
    args = ap.parse_args()
    runs = {}
    for name, extra in variants(args.scene, args.sets, args.finest).items():
        if args.variants and name != "as given" and not any(name.startswith(v) for v in args.variants):
            continue
        runs[name] = one_run(args.scene, args.ranks, args.sets + extra)
        print(f"# {name}: {runs[name]['wall']:.0f} s", file=sys.stderr, flush=True)
    ref = runs["as given"]["d"]
    print(f"\nDesign-pressure ratios of {args.scene.name} ({', '.join(args.sets) or 'as given'}), {args.ranks} ranks: "
          "each ratio over EN 1991-4's load (the larger of filling and discharge); 'largest' is over the stations; "
          "'change' the median over stations of |ratio - ratio as given| / ratio as given\n")
    head = ["variant", "cells", "steps", "wall s"] + sum(
        ([f"{m}: largest (z m)", f"{m}: change"] for m, _ in MEASURES), [])
    print("| " + " | ".join(head) + " |\n|" + "---|" * len(head))
    for name, r in runs.items():
        d = r["d"]
        cols = [name, f"{r['cells']:,}", f"{r['steps']:,}", f"{r['wall']:.0f}"]
        for _, col in MEASURES:
            x = d[col]
            i = int(np.nanargmax(x))
            # stations sit at the same heights whatever the mesh: compare them one by one
            change = np.nanmedian(np.abs(x - ref[col]) / ref[col])
            cols += [f"{x[i]:.2f} ({d['z'][i]:.2f})", "-" if r is runs["as given"] else f"{100 * change:.0f} %"]
        print("| " + " | ".join(cols) + " |")
    for m, col in MEASURES[1:]:
        print(f"\n{m} over EN 1991-4 by station\n")
        print("| z (m) | " + " | ".join(runs) + " |\n|" + "---|" * (len(runs) + 1))
        for k, z in enumerate(ref["z"]):
            print(f"| {z:.3f} | " + " | ".join(f"{r['d'][col][k]:.2f}" for r in runs.values()) + " |")


if __name__ == "__main__":
    main()
