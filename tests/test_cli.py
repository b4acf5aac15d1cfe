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
