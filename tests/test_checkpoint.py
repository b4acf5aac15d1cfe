"""Checkpoints and resume (silo_dolfinx.checkpoint): a run that stops after a checkpoint and is
resumed ends with exactly the results of an uninterrupted run, wherever it stopped - in a
layered fill, in the store, in an ALE discharge with tracers, material points and field
output - and a run that cannot be resumed is refused with its reason before anything is
touched. (A run killed with SIGKILL and resumed by ``silo run --resume``, on 1 and 2 ranks:
tests/test_hard_cases.py.)

Here the "crash" is an exception raised right after a checkpoint is written (in-process, so
that the test runs on 1 and on 2 ranks alike); the state on disk is what a kill would leave,
plus the rows written after the checkpoint, which the resumed run must cut back and write
again. Equality is asserted byte for byte on every CSV and every field snapshot: the resumed
run repeats the same floating-point operations on the same partition, so anything less than
identical would be a piece of state the checkpoint does not carry."""

import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from silo_dolfinx import checkpoint
from silo_dolfinx.checkpoint import CheckpointError, Checkpoints
from silo_dolfinx.scene import load_scene
from silo_dolfinx.simulation import run

from conftest import SCENES

# a coarse ch. 7 section (245 cells) with everything a checkpoint must carry: three filling layers
# (gravity ramps), ALE with tracers, material points, stations, field snapshots, the wall friction's
# memory (per-node state; 1 mm over 0.01 m/s: 0.1 s, so a resume without it would differ)
SETS = ['fill.method="layers"', "fill.layers=3", "fill.duration=0.3", "store.duration=0.2", "discharge.duration=0.3",
        'material.cone="extension"', "geometry.element_size=0.05", "geometry.bin_height=1.0", "wall.mu=1.0",
        'discharge.mode="free"', "output.stations=[0.3, 0.687, 1.5]", "output.points=[[0.2, 0.5], [0.3, 1.2]]",
        'output.point_motion="material"', "output.field_interval=0.1", "ale.tracer_rows=4", "ale.tracer_columns=3",
        "wall.regularisation_length=1e-3", "output.checkpoint_interval=1e-9"]  # a checkpoint at every history sample


class Crash(Exception):
    """Stands for a kill: raised on every rank right after a checkpoint."""


def _scene(*extra):
    return load_scene(SCENES / "bin_hopper_ch7_abrupt.toml", SETS + list(extra))


def _crash_after_checkpoint_at(monkeypatch, t_crash: float) -> None:
    write = Checkpoints.write

    def write_then_crash(self):
        write(self)
        if self.model.solver.t > t_crash:
            raise Crash()

    monkeypatch.setattr(Checkpoints, "write", write_then_crash)


def _files(folder: Path) -> dict[str, bytes]:
    """Every CSV of a results folder, by name."""
    return {p.name: p.read_bytes() for p in sorted(folder.glob("*.csv"))}


@pytest.mark.parametrize("t_crash, stage", [(0.12, "fill"), (0.65, "discharge")])
def test_a_crashed_run_resumes_to_exactly_the_uninterrupted_results(shared_tmp, monkeypatch, comm, t_crash, stage):
    sc = _scene()
    ref = run(sc, shared_tmp / "reference", comm, progress_every=1e9)
    out = shared_tmp / "crashed"
    _crash_after_checkpoint_at(monkeypatch, t_crash)
    with pytest.raises(Crash):
        run(sc, out, comm, progress_every=1e9)
    monkeypatch.undo()
    comm.barrier()
    meta = json.loads((out / "checkpoint" / "checkpoint.json").read_text())
    killed = json.loads((out / "summary.json").read_text())
    assert killed["status"] == "failed" and killed["checkpoint"]["t"] == meta["t"]
    assert meta["records"] == [] if stage == "fill" else [r["name"] for r in meta["records"]] == ["fill", "store"]
    assert t_crash < meta["t"] < t_crash + 0.01  # the crash came right after this checkpoint

    resumed = run(load_scene(out / "scene.toml"), out, comm, progress_every=1e9, resume=True)
    assert resumed["status"] == "completed" and resumed["steps"] == ref["steps"]
    assert resumed["resumed"][0]["from_t"] == meta["t"]
    assert not (out / "checkpoint").exists()  # a completed run's checkpoints are removed
    if comm.rank == 0:
        a, b = _files(shared_tmp / "reference"), _files(out)
        assert set(a) == set(b) and {"outlet.csv", "tracers.csv", "point_history.csv"} <= set(a)
        assert all(a[k] == b[k] for k in a), [k for k in a if a[k] != b[k]]
        snaps = sorted((shared_tmp / "reference" / "fields").glob("snapshot_*.npz"))
        assert len(snaps) == len(list((out / "fields").glob("snapshot_*.npz"))) > 5
        for p in snaps:
            x, y = np.load(p), np.load(out / "fields" / p.name)
            assert all(np.array_equal(x[k], y[k], equal_nan=True) for k in x.files), p.name
        # VTX cannot append: the resumed part went to new files, the first part is kept
        assert {"nodes.bp", "cells.bp", "nodes_resumed1.bp", "cells_resumed1.bp"} <= {
            p.name for p in (out / "fields").iterdir()}
        for k in ("energy_balance_error_max", "simulated_time"):
            assert resumed[k] == ref[k]


def test_a_run_that_cannot_be_resumed_is_refused_naming_why(shared_tmp, monkeypatch, comm):
    sc = _scene("discharge.duration=0.05")
    done = shared_tmp / "done"
    run(sc, done, comm, progress_every=1e9)
    with pytest.raises(CheckpointError, match="completed; there is nothing to resume"):
        run(sc, done, comm, resume=True)
    with pytest.raises(CheckpointError, match="no scene.toml"):
        run(sc, shared_tmp / "nowhere", comm, resume=True)

    out = shared_tmp / "crashed"
    _crash_after_checkpoint_at(monkeypatch, 0.4)
    with pytest.raises(Crash):
        run(sc, out, comm, progress_every=1e9)
    monkeypatch.undo()
    ck = out / "checkpoint" / "checkpoint.json"
    comm.barrier()
    good = ck.read_text()

    def edited(**changes):
        comm.barrier()
        if comm.rank == 0:
            ck.write_text(json.dumps(json.loads(good) | changes))
        comm.barrier()

    edited(ranks=comm.size + 1)
    with pytest.raises(CheckpointError, match=f"mpirun -n {comm.size + 1} silo run --resume"):
        run(sc, out, comm, resume=True)
    mesh = json.loads(good)["mesh"]
    edited(mesh=[[n + 1, c, x] for n, c, x in mesh])
    with pytest.raises(CheckpointError, match="meshes differently"):
        run(sc, out, comm, resume=True)
    edited()
    comm.barrier()
    if comm.rank == 0:
        shutil.rmtree(out / "checkpoint")
    comm.barrier()
    with pytest.raises(CheckpointError, match="no checkpoint"):
        run(sc, out, comm, resume=True)


@pytest.mark.serial  # argument handling of the command line; nothing parallel in it
def test_silo_run_resume_takes_only_the_folder(tmp_path, capsys):
    from silo_dolfinx.cli import main

    assert main(["run", str(SCENES / "first_silo.toml"), "--resume", str(tmp_path)]) == 2
    assert "takes no scene, --set or --out" in capsys.readouterr().err
    assert main(["run", str(SCENES / "first_silo.toml")]) == 2
    assert "needs a scene and --out" in capsys.readouterr().err
    assert main(["run", "--resume", str(tmp_path)]) == 2  # not a results folder
    assert "no scene.toml" in capsys.readouterr().err


@dataclass
class _Level:
    sig: np.ndarray
    state: dict


class _Holder:
    CHECKPOINT = ("level", "n", "grown")

    def __init__(self, view_of: np.ndarray):
        self.level = _Level(view_of.reshape(-1, 2), {"eqps": np.zeros(3)})
        self.n, self.grown = 0, np.zeros(1)


def test_restore_writes_arrays_in_place_and_assigns_the_rest():
    """The views that compiled forms and kernels hold (the velocity Function's array, the
    packed coefficients) must stay the arrays they read: same-shaped arrays are restored in
    place, through dataclasses and dicts; scalars and resized arrays are assigned."""
    base = np.arange(6.0)
    h = _Holder(base)
    assert set(checkpoint.capture(h)) == {"level", "n", "grown"}
    saved = {"level": checkpoint._Fields(sig=np.full((3, 2), 7.0), state={"eqps": np.ones(3)}), "n": 5,
             "grown": np.arange(4.0)}
    view, eqps = h.level.sig, h.level.state["eqps"]
    checkpoint.restore(h, saved)
    assert h.level.sig is view and np.all(base == 7.0)  # through the view into its base
    assert h.level.state["eqps"] is eqps and np.all(eqps == 1.0)
    assert h.n == 5 and h.grown.size == 4


def test_a_checkpoint_that_cannot_be_written_stops_checkpoints_not_the_run(shared_tmp, monkeypatch, comm):
    """A load amplitude that is a closure cannot be pickled (nor can a full disk take a file):
    the run goes on without checkpoints and says so in summary.json."""
    from silo_dolfinx.simulation import model

    monkeypatch.setattr(model, "SmoothRamp", lambda t0, duration: (lambda t: 1.0))
    summary = run(_scene("discharge.duration=0.05"), shared_tmp / "out", comm, progress_every=1e9)
    assert summary["status"] == "completed"
    assert any("checkpoints stopped at t =" in w and "could not write state" in w for w in summary["warnings"])
    assert "checkpoint" not in summary
