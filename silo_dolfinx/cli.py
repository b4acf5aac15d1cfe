"""The ``silo`` command.

    silo check SCENE [--set section.key=value ...]     validate, print the resolved scene
    silo mesh SCENE -o meshes/NAME.msh [--show]        write the gmsh mesh (and a PNG of it)
    silo run SCENE --out results/NAME [--set ...]      run the scene, write the results folder
    silo run --resume results/NAME                     continue a killed run from its last checkpoint
    silo report results/NAME [--movie]                 figures + report.md from a results folder
    silo report results/NAME --ensemble results/N2 ...  wall spectra over realisations of one scene
    silo shear --out results/shear [--cone thesis]     the ch. 8 simple-shear study (Table 8-1)
    silo schema [--results]                            print the scene (or results-file) reference

Bad input is reported before any meshing or time-stepping, one line per problem naming the
key, its value, what is allowed and a fix; the exit status is then 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from silo_dolfinx import theory
from silo_dolfinx.scene import SceneError, load_scene


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="silo", description="Granular flow and wall pressure in silos.")
    sub = p.add_subparsers(dest="command", required=True)

    def scene_args(sp):
        sp.add_argument("scene", help="scene file (TOML)")
        sp.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="override a scene key (repeatable), e.g. --set material.density=1500")

    sp = sub.add_parser("check", help="validate a scene and print it with all defaults resolved")
    scene_args(sp)
    sp.add_argument("--cost", action="store_true", help="also mesh it and estimate what it costs: the stable Δt and "
                    "the cell that sets it, the steps, the wall-clock on 1 and 2 ranks (and --ranks)")
    sp.add_argument("--ranks", type=int, default=None, help="with --cost: also estimate the wall-clock on this many ranks")
    sp = sub.add_parser("mesh", help="mesh a scene's geometry with gmsh")
    scene_args(sp)
    sp.add_argument("-o", "--output", required=True, help="output .msh file")
    sp.add_argument("--show", action="store_true", help="also write a PNG of the mesh next to it")
    sp = sub.add_parser("run", help="run a scene into a results folder")
    sp.add_argument("scene", nargs="?", help="scene file (TOML); not with --resume")
    sp.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                    help="override a scene key (repeatable), e.g. --set material.density=1500")
    sp.add_argument("--out", help="results folder (created; an earlier run's results in it are replaced)")
    sp.add_argument("--resume", metavar="FOLDER",
                    help="continue the killed run in FOLDER from its last checkpoint (its own scene.toml; as many "
                    "ranks as wrote it)")
    sp.add_argument("--progress", type=float, default=5.0, metavar="SECONDS",
                    help="seconds between progress lines on rank 0 (default 5)")
    sp = sub.add_parser("report", help="figures and report.md from a results folder")
    sp.add_argument("folder", help="results folder written by silo run")
    sp.add_argument("--times", type=float, nargs="+", metavar="T",
                    help="simulated times (s) of the stress-field figure (default: end of filling, opening, "
                         "2 s into the discharge, its end)")
    sp.add_argument("--movie", action="store_true",
                    help="also discharge.gif: speed, tracers and q/p through the discharge, a frame per field snapshot")
    sp.add_argument("--ensemble", nargs="+", metavar="OTHER",
                    help="instead: the wall spectra over realisations - FOLDER and these results folders of the same "
                         "scene with an immaterial change (e.g. --set numerics.time_step_scale=0.792): "
                         "ensemble_spectra.csv/.png in FOLDER")
    sp = sub.add_parser("shear", help="thesis ch. 8 simple shear, Table 8-1, coaxial vs non-coaxial")
    sp.add_argument("--out", required=True, help="folder for CSV and PNG files")
    sp.add_argument("--cone", "--matching", dest="cone", default="plane_strain",
                    choices=tuple(c for c in theory.CONES if c != "beta") + ("thesis",),
                    help="Drucker-Prager β from φ, as the scenes' material.cone: plane_strain (default; "
                    "the ch. 8 closed forms are plane-strain ones), compression, extension, or the thesis' "
                    "own choice tan β = √3 sin φ (thesis = plane_strain_zero_dilation)")
    sp.add_argument("--gamma", type=float, default=0.1, help="final shear strain (default 0.1)")
    sp = sub.add_parser("schema", help="print the scene file reference (Markdown)")
    sp.add_argument("--results", action="store_true", help="the results-file reference instead (docs/results.md)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.command == "schema":
            if args.results:
                from silo_dolfinx.output.schema import markdown
            else:
                from silo_dolfinx.scene.schema import markdown
            print(markdown(), end="")
            return 0
        if args.command == "check":
            return _check(args)
        if args.command == "mesh":
            return _mesh(args)
        if args.command == "run":
            return _run(args)
        if args.command == "report":
            return _report(args)
        if args.command == "shear":
            return _shear(args)
    except SceneError as e:
        _error(str(e))
        return 2
    except _user_errors() as e:
        _error(f"error: {e}")
        return 2
    except KeyboardInterrupt as e:  # Ctrl-C, or SIGTERM during a run (simulation.RunInterrupted)
        _error(f"interrupted ({e or 'SIGINT'}): the results folder keeps everything written so far; its summary.json "
               "says where the run was, and silo run --resume FOLDER continues it from its last checkpoint.")
        return 130
    except Exception:
        _abort_other_ranks()
        raise
    return 1  # pragma: no cover - argparse guarantees a command


def _user_errors():
    from silo_dolfinx.geometry.mesher import MeshingError
    from silo_dolfinx.checkpoint import CheckpointError
    from silo_dolfinx.output.writer import ResultsFolderBusy
    from silo_dolfinx.solver import InstabilityError

    return (MeshingError, InstabilityError, CheckpointError, ResultsFolderBusy)


def _abort_other_ranks() -> None:
    """An unexpected error on one rank would leave the others waiting in a collective
    forever: print it with its rank and abort the whole job (the CSVs written so far stay
    readable; summary.json keeps status "running")."""
    try:
        from mpi4py import MPI
    except ImportError:  # pragma: no cover
        return
    comm = MPI.COMM_WORLD
    if comm.size > 1:
        import traceback

        print(f"[rank {comm.rank}] unexpected error; aborting all ranks:", file=sys.stderr)
        traceback.print_exc()
        sys.stderr.flush()
        comm.Abort(1)


def _rank() -> int:
    try:
        from mpi4py import MPI

        return MPI.COMM_WORLD.rank
    except ImportError:  # pragma: no cover
        return 0


def _error(msg: str) -> None:
    if _rank() == 0:
        print(msg, file=sys.stderr)


def _check(args) -> int:
    scene = load_scene(args.scene, args.overrides)
    if _rank() == 0:
        for w in scene.warnings:
            print(f"# warning: {w}", file=sys.stderr)
        print(f"# {args.scene}: valid. Resolved scene (defaults filled in):")
        print(scene.to_toml(), end="")
        print(f"# material: {scene.cone_text()}")
        ol = scene.outline
        print(f"# silo volume {ol.volume():.6g} m³, mass {ol.volume() * scene.material.density:.6g} kg, "
              f"fill height {ol.fill_height:g} m, wall length {ol.wall.length:.6g} m")
        if args.cost:
            from mpi4py import MPI

            from silo_dolfinx.cost import describe, estimate
            from silo_dolfinx.geometry.mesher import mesh_scene

            ranks = tuple(sorted({1, 2} | ({args.ranks} if args.ranks else set())))
            for line in describe(scene, estimate(scene, mesh_scene(scene, MPI.COMM_SELF)), ranks):
                print(f"# {line}")
    return 0


def _mesh(args) -> int:
    from mpi4py import MPI

    from silo_dolfinx.geometry.mesher import mesh_scene
    from silo_dolfinx.geometry.plot import plot_mesh
    from silo_dolfinx.geometry.quality import quality_report

    scene = load_scene(args.scene, args.overrides)
    out = Path(args.output)
    sm = mesh_scene(scene, MPI.COMM_WORLD, msh_path=out)
    q = quality_report(sm.mesh)
    vol = sm.volume_of_revolution()
    n_out = sm.outlet_cells()
    if args.show:
        plot_mesh(sm, out.with_suffix(".png"), title=f"{scene.title}: {q['cells']} cells")
    if _rank() == 0:
        exact = scene.outline.volume()
        print(f"{out}: {q['cells']} quadrilaterals; volume of revolution {vol:.6g} m³ "
              f"(exact {exact:.6g}, {100 * (vol - exact) / exact:+.2e} %); corner angles "
              f"{q['min_angle_deg']:.1f}-{q['max_angle_deg']:.1f}°, max aspect ratio {q['max_aspect_ratio']:.2f}, "
              f"inverted {q['inverted']}; {n_out} cells across the outlet radius (a discharge wants about 8 or "
              "more: docs/guide/your-silo.md)")
        if args.show:
            print(f"{out.with_suffix('.png')}: picture of the mesh")
    return 0


def _report(args) -> int:
    if _rank() != 0:
        return 0
    from silo_dolfinx.report import ensemble_spectra, make_report

    try:
        path = (ensemble_spectra([args.folder, *args.ensemble]) if args.ensemble else
                make_report(args.folder, args.times, args.movie))
    except FileNotFoundError as e:
        _error(f"error: {e}")
        return 2
    print(f"{path}: written")
    return 0


def _shear(args) -> int:
    if _rank() != 0:
        return 0
    from silo_dolfinx.materials.driver import run_study

    rows = run_study(args.out, args.cone, args.gamma)
    print(f"{'case':>4} {'φ':>4} {'ψ':>4} {'E kPa':>8} {'k':>4} {'β_DP':>6} {'σx/σy':>7} {'τ/σy':>7} "
          f"{'peak Δ':>7} {'angle':>6}")
    for r in rows:
        print(f"{r['case']:4d} {r['phi']:4g} {r['psi']:4g} {r['E_kPa']:8g} {r['k']:4g} {r['beta_dp']:6.2f} "
              f"{r['ultimate_sx_over_sy']:7.4f} {r['ultimate_tau_over_sy']:7.4f} {r['peak_difference']:+7.3f} "
              f"{r['final_stress_angle']:6.1f}")
    print(f"CSV and PNG files in {args.out}/")
    return 0


def _run(args) -> int:
    from silo_dolfinx.simulation import run

    if args.resume:
        if args.scene or args.overrides or args.out:
            _error("error: silo run --resume FOLDER takes no scene, --set or --out: a run resumes with the scene it "
                   "was started with (FOLDER/scene.toml), into its own folder.")
            return 2
        from mpi4py import MPI

        from silo_dolfinx.checkpoint import load

        load(args.resume, MPI.COMM_WORLD)  # a folder that cannot be resumed is refused first, saying why
        args.out = args.resume
        scene = load_scene(Path(args.resume) / "scene.toml", [])
    elif not args.scene or not args.out:
        _error("error: silo run needs a scene and --out FOLDER (or --resume FOLDER to continue a killed run).")
        return 2
    else:
        scene = load_scene(args.scene, args.overrides)
    if _rank() == 0:
        for w in scene.warnings:
            print(f"warning: {w}", file=sys.stderr)
    summary = run(scene, args.out, progress_every=args.progress, resume=bool(args.resume))
    if _rank() == 0:
        print(f"{args.out}: {summary['status']}; {summary['steps']:,} steps, simulated {summary['simulated_time']:.4g} s "
              f"in {summary['wall_clock_s']:.1f} s ({summary['steps_per_second']:,.0f} steps/s); energy balance "
              f"error {100 * summary['energy_balance_error_max']:.3f} % (max)")
        for w in summary["warnings"][len(scene.warnings):]:
            print(f"warning: {w}", file=sys.stderr)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
