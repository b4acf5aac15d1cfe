"""The ``silo`` command: check, mesh, schema; bad input exits 2 naming the key."""

import tomllib

from conftest import SCENES

from silo_dolfinx.cli import main


def test_check_prints_the_resolved_scene(capsys, comm):
    assert main(["check", str(SCENES / "hopper_ch4_stiff.toml"), "--set", "numerics.time_step_scale=0.5"]) == 0
    out = capsys.readouterr().out
    if comm.rank == 0:
        resolved = tomllib.loads(out)  # the comment lines are TOML comments
        assert resolved["material"]["youngs_modulus"] == 5.5e6  # from the variant
        assert resolved["geometry"]["top_radius"] == 1.2  # from its base
        assert resolved["numerics"]["time_step_scale"] == 0.5  # from --set
        assert resolved["numerics"]["bulk_viscosity"] == [0.06, 1.2]  # default
        assert "silo volume 4.34042 m³" in out  # π h (R0² + R0 Rt + Rt²)/3
        assert "# material: Mohr-Coulomb friction_angle φ = 30°, dilation_angle ψ = 10° -> Drucker-Prager " \
            "β = 50.19°, ψ_DP = 20.24°" in out  # what the angles resolve to


def test_check_refuses_bad_input_with_exit_2(capsys, comm):
    assert main(["check", str(SCENES / "hopper_ch4.toml"), "--set", "material.density=-1"]) == 2
    err = capsys.readouterr().err
    if comm.rank == 0:
        assert "[material] density: = -1 is out of range: must be > 0 kg/m³" in err


def test_mesh_writes_msh_and_picture(shared_tmp, capsys, comm):
    out = shared_tmp / "m" / "steep.msh"
    assert main(["mesh", str(SCENES / "steep_hopper_ch8_coaxial.toml"), "-o", str(out), "--show"]) == 0
    comm.barrier()
    assert out.is_file() and out.with_suffix(".png").is_file()
    if comm.rank == 0:
        text = capsys.readouterr().out
        assert "1275 quadrilaterals" in text and "inverted 0" in text
        # structured, no floor: every row has ceil(0.5655 m / 0.04 m) = 15 cells, the outlet's too
        assert "; 15 cells across the outlet radius" in text


def test_schema_is_markdown(capsys, comm):
    assert main(["schema"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("# Scene file reference") and "`friction_angle`" in out


def test_results_reference_is_the_schema(capsys, comm):
    """docs/results.md is generated from silo_dolfinx.output.schema; regenerate with
    `silo schema --results > docs/results.md`. Every column the writers use is documented."""
    from pathlib import Path

    from silo_dolfinx.output import schema

    assert main(["schema", "--results"]) == 0
    out = capsys.readouterr().out
    assert out == (Path(__file__).resolve().parents[1] / "docs" / "results.md").read_text()
    for f in schema.FILES:
        assert all(f"| `{c}` |" in out for c in f.names), f.pattern


def test_progress_eta_follows_the_recent_pace():
    """A run that simulated 10 s at 1 s per wall-clock second and then slows to 0.1 s per
    second: after a few lines at the slow pace the ETA for the last 10 s is ~100 s (the recent
    pace), not the ~20 s the average since the start would give. Clock and time are fed in."""
    import io

    from mpi4py import MPI

    from silo_dolfinx.output import writer

    clock = [0.0]
    real = writer.time.time
    writer.time.time = lambda: clock[0]
    try:
        out = io.StringIO()
        p = writer.Progress(MPI.COMM_SELF, 30.0, every=1.0, stream=out)
        t = 0.0
        for _ in range(10):  # fast: 1 s simulated per second
            p("fill", t, int(t * 100), 0.01)
            clock[0] += 1.0
            t += 1.0
        for _ in range(10):  # slow: 0.1 s per second
            p("discharge", t, int(t * 100), 0.001)
            clock[0] += 1.0
            t += 0.1
        p("discharge", t, int(t * 100), 0.001)
    finally:
        writer.time.time = real
    eta = out.getvalue().strip().splitlines()[-1].split("ETA ")[1]
    assert eta.startswith("3m"), eta  # (30 − 11) s at 0.1 s/s = 190 s; since the start: 0m34s


def test_check_cost_finds_the_solvers_stable_dt_and_the_steps_a_run_takes(shared_tmp, capsys, comm):
    """`silo check --cost` estimates a scene's cost from its mesh before it runs. Its Δt is the
    solver's own at rest (the same kernel over every cell: equal to round-off, and the same cell),
    and its steps are those a short K0 run takes: at rest Δt does not move, and in 0.2 s of
    discharge it falls by a few per cent at most (the estimate is a lower bound; 10 % allowed)."""
    from mpi4py import MPI

    from silo_dolfinx.cost import estimate
    from silo_dolfinx.geometry.mesher import mesh_scene
    from silo_dolfinx.scene import load_scene
    from silo_dolfinx.simulation import build_model, run

    sets = ['fill.method="k0"', "store.duration=0.1", "discharge.duration=0.2", "geometry.element_size=0.06",
            "output.field_interval=0"]
    scene = load_scene(SCENES / "hopper_ch4.toml", sets)
    cost = estimate(scene, mesh_scene(scene, MPI.COMM_SELF))
    solver = build_model(scene, comm).solver
    assert abs(cost.dt - solver.dt_crit) < 1e-12 * solver.dt_crit
    where = solver.limiting_cell()
    assert abs(cost.where[0] - where["r"]) < 1e-9 and abs(cost.where[1] - where["z"]) < 1e-9
    summary = run(scene, shared_tmp / "cost", comm, progress_every=1e9)
    estimated = sum(cost.steps.values())
    assert estimated <= summary["steps"] <= 1.1 * estimated, (estimated, summary["steps"])

    capsys.readouterr()
    assert main(["check", str(SCENES / "first_silo.toml"), "--cost", "--ranks", "4"]) == 0
    out = capsys.readouterr().out
    if comm.rank == 0:  # a structured hopper mesh: its outlet cells set Δt, and the user is told why
        assert "# cost: 480 cells" in out and "on 4 ranks" in out
        assert "(0.12 × element_size)" in out and 'geometry.mesh = "unstructured"' in out
    assert main(["check", str(SCENES / "hopper_ch4.toml"), "--cost"]) == 0
    out = capsys.readouterr().out
    if comm.rank == 0:  # unstructured: its smallest cell is 0.59 of the element size, nothing to say
        assert "# cost: 7,814 cells" in out and "every step pays for it" not in out
