"""Hard cases stay numerically stable — or stop cleanly, saying why — serially and on 2 ranks.

Each case is a coarse, short version of a scene that is hard for an explicit scheme: abrupt and
filleted transitions, rough and velocity-dependent walls, sudden and near-instant openings, a
stiff and near-cohesionless solid, non-coaxial plasticity, a profile wall with a ledge. Each
asserts the checks of the hard-case issue, measured by :func:`silo_dolfinx.analysis.run_health`
(the same checks ``benchmarks/soak.py`` prints for the long versions): the run completes,
energy balance < 1 %, mass balance < 0.5 %, no cell below a scaled Jacobian of 0.2 at any sample
(the solver itself stops on an inverted cell at any step), nothing non-finite in any output,
wall pressures below 3 ρ g H, and the silo discharged. The discharges use the cone matched in
extension (material.cone), the one with which the ch. 7 solid flows; on the scenes' default
cone, matched in compression, an arch holds over the outlet - the last case shows that run
stopping within its stage with its diagnosis (docs/reliability.md has both cones' figures).

Sizes: the ch. 7 section with a 1-m bin at h 0.05 m (245 cells), K0 start, 0.2 s of storage,
1 s of discharge (0.5 s for the stiff and the steep cases, whose Δt is 3× smaller or whose mesh is
larger): 3-8 s a case serially, about 40 s per CI leg for the six. The long discharge (30 s of
the ch. 3 hopper at h 0.1 m) takes 18 s serially, 24 s on 2 ranks."""

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from silo_dolfinx.analysis import run_health
from silo_dolfinx.output import read_csv
from silo_dolfinx.scene import load_scene
from silo_dolfinx.simulation import run
from silo_dolfinx.solver import InstabilityError

from conftest import SCENES, subprocess_env

SHORT = ['fill.method="k0"', "store.duration=0.2", "discharge.duration=1.0", "output.field_interval=100",
         "output.points=[]", 'material.cone="extension"']
BIN = ["geometry.element_size=0.05", "geometry.bin_height=1.0", "output.stations=[0.3, 0.687, 1.0, 1.5]"]
LEDGE = ['geometry.shape="profile"', "geometry.wall=[[0.1, 0.0], [0.4, 0.8], [0.6, 0.8], [0.6, 1.6]]",
         'geometry.mesh="unstructured"', "geometry.element_size=0.06", "output.stations=[0.4, 0.9, 1.3]",
         'discharge.mode="free"']

# name: (scene, overrides, what it stresses and what was measured serially)
CASES = {
    "abrupt_rough_sudden": ("bin_hopper_ch7_abrupt", BIN + ["wall.mu=1.0", 'discharge.mode="free"'],
                            "abrupt corner, wall μ 1.0 (rougher than the issue's 0.9), free discharge opened at once "
                            "from a full store"),
    "fillet_fast_ramp": ("bin_hopper_ch7_fillet02", BIN + ["discharge.ramp_time=0.01"],
                         "0.2-m fillet, outlet driven to 1 m/s in 0.01 s: a velocity jump the solid must follow "
                         "through a wave"),
    "eq_7_1_friction": ("bin_hopper_ch7_dynamic", BIN,
                        "velocity-dependent wall friction (eq. 7-1: μs 0.67 → μk 0.3, ϖ 2 s/m), controlled"),
    "stiff_near_cohesionless": ("bin_hopper_ch7_abrupt", BIN + ["material.youngs_modulus=2.0e7", "material.cohesion=0.01",
                                                                'discharge.mode="free"', "discharge.duration=0.5"],
                                "E × 10 (Δt 3.2× smaller) and cohesion 0.01 Pa: the stretched cells over the outlet "
                                "and at the surface return to the cone's apex"),
    "viscoplastic_rough": ("bin_hopper_ch7_abrupt", BIN + ["material.relaxation_time=1e-3"],
                           "the solid's plastic flow delayed by τ 1 ms (Duvaut-Lions: the stress outside the cone "
                           "by its overstress) against the abrupt corner's μ 0.67 wall, controlled discharge (the "
                           "overstress, τ G γ̇ ~ 8 kPa at the outlet's 10 s⁻¹, holds a free discharge back)"),
    "non_coaxial_steep": ("steep_hopper_ch8_noncoaxial", ["geometry.element_size=0.06", "discharge.duration=0.5"],
                          "non-coaxial (yield-vertex) plasticity, ch. 8 steep hopper (10°), free discharge"),
    "profile_ledge": ("hopper_ch4", LEDGE, "a user's profile wall with a 0.2-m horizontal ledge (unstructured "
                      "mesh), free discharge"),
}


def checked_run(out, comm, scene, sets):
    """Run a case and assert every hard-case check; returns the measured figures."""
    sc = load_scene(SCENES / f"{scene}.toml", SHORT + sets)
    run(sc, out, comm, progress_every=1e9)
    comm.barrier()
    h = run_health(out)
    assert h["status"] == "completed", h["error"]
    assert h["energy_error_max"] < 0.01
    assert h["mass_error_max"] < 5e-3
    assert h["min_scaled_jacobian"] > 0.2
    assert h["finite"]
    assert h["p_max_over_rho_g_h"] < 3.0
    assert h["discharged_mass"] > 0.005 * h["mass_at_opening"]  # it flowed (the least: 1.4 % in 1 s)
    return h


@pytest.mark.parametrize("case", CASES, ids=list(CASES))
def test_hard_case_runs_within_the_bounds(shared_tmp, comm, case):
    scene, sets, _ = CASES[case]
    checked_run(shared_tmp / case, comm, scene, sets)


def test_one_and_two_ranks_agree_over_the_first_thousand_steps(shared_tmp, comm):
    """The abrupt, rough, sudden case cut to ~1,000 steps (0.2 s of storage from K0, then 0.05 s
    of free discharge through the opening and five ALE remaps) on COMM_SELF and on COMM_WORLD:
    the same steps, and every wall-history sample (p_n, p_s, slip velocity at every station)
    and the energies equal to 1e-8 of their largest magnitude - the partition changes only the
    order of sums. On one rank this checks that a run is deterministic. (Later, plastic flow
    amplifies round-off: soak.py compares the end-of-store profiles and discharged mass.)"""
    from mpi4py import MPI

    scene, sets, _ = CASES["abrupt_rough_sudden"]
    sc = load_scene(SCENES / f"{scene}.toml", SHORT + sets + ["discharge.duration=0.05"])
    par = run(sc, shared_tmp / "ranks_world", comm, progress_every=1e9)
    ser = run(sc, shared_tmp / f"ranks_self{comm.rank}", MPI.COMM_SELF, progress_every=1e9)
    comm.barrier()
    assert ser["steps"] == par["steps"] and par["steps"] > 1000
    for k, v in ser["energy"].items():
        assert abs(v - par["energy"][k]) <= 1e-8 * max(abs(x) for x in ser["energy"].values()), k
    a, b = read_csv(shared_tmp / "ranks_world" / "wall_history.csv"), read_csv(shared_tmp / f"ranks_self{comm.rank}" / "wall_history.csv")
    for col in ("p_n", "p_s", "slip_velocity"):
        assert a[col].shape == b[col].shape
        assert np.max(np.abs(a[col] - b[col])) <= 1e-8 * np.abs(b[col]).max(), col


def test_a_long_discharge_stays_within_the_bounds_and_steady(shared_tmp, comm):
    """The ch. 3 hopper (H 2.64 m, outlet radius 0.1 m) coarse (unstructured, h 0.1 m: 194 cells,
    the outlet two cells wide) discharged freely for 30 s on the extension cone: every hard-case
    check holds over 37,000 steps and ~1,700 remaps, and the mass flow stays steady - a hopper's
    rate hardly depends on the head (Beverloo), and the critical state keeps the flowing solid
    from dilating without end. Measured serially: 43 % out, energy 0.05 %, mass 1e-7, worst cell
    0.60; the rate 63.7 kg/s over 3.2-13.2 s, 59.8 over the last 10 s (0.94; bar 0.85: a
    drop of 15 % would be a solid dilating without end). 18 s serially, 24 s on 2 ranks. (On
    the compression cone this mesh arches over its two-cell outlet; there the remap used to
    create mass at the outlet - 0.74 % in 30 s - tests/test_ale.py.)"""
    from silo_dolfinx.analysis import windowed_mass_flow

    out = shared_tmp / "long"
    sets = ['geometry.mesh="unstructured"', "geometry.element_size=0.1", 'discharge.mode="free"',
            "discharge.duration=30", "output.stations=[0.3, 1.0, 2.0]"]
    h = checked_run(out, comm, "hopper_ch3_ale", sets)
    assert h["simulated_time"] >= 30.0 and h["discharged_mass"] > 0.3 * h["mass_at_opening"]
    o = read_csv(out / "outlet.csv")
    early = windowed_mass_flow(o["t"], o["discharged_mass"], 10.0, t_start=3.2)[1][0]
    late = windowed_mass_flow(o["t"], o["discharged_mass"], 10.0, t_start=20.2)[1][0]
    assert late >= 0.85 * early, (early, late)


def test_a_rough_wall_discharge_keeps_its_top_with_the_surface_slump(shared_tmp, comm):
    """The ch. 7 silo with eq. 7-1 wall friction (μs 0.67 → μk 0.3, controlled at 1 m/s; h 0.04 m,
    1,107 cells, K0 start) for 6 s of discharge with ale.max_surface_slope = 40° (the solid's φ):
    every hard-case check holds over the whole discharge - measured serially worst cell 0.76,
    mass 2e-9, energy 0.17 %, 7.8 % out. Without the slump the full-fill scene (10 layers) still
    ends on discharge.min_mesh_quality after 5.65 s of discharge (2026-12-05, 2 ranks: the
    top-corner node at the wall runs ahead of the surface beside it; docs/validation/ch7.md);
    this K0 version did too (at 5.25 s) until the outlet-edge fix, and now runs its 6 s either
    way, so here the slump is checked for what it must not break. ~25 s serially."""
    out = shared_tmp / "slump"
    sets = ["geometry.element_size=0.04", "store.duration=0.5", "discharge.duration=6.0",
            "output.stations=[1.0, 3.0, 4.5]", "ale.max_surface_slope=40.0"]
    h = checked_run(out, comm, "bin_hopper_ch7_dynamic", sets)
    assert h["simulated_time"] >= 6.5 - 1e-9  # the whole discharge: no early end on the quality floor
    assert h["min_scaled_jacobian"] > 0.5


EMPTYING = ["geometry.height=0.45", "geometry.top_radius=0.25", "geometry.outlet_radius=0.08", "geometry.element_size=0.05",
            'geometry.mesh="structured"', 'discharge.mode="free"', "discharge.duration=10", "output.stations=[0.1, 0.3]",
            'material.cone="compression"', "ale.rezone_dt_fall=0", "ale.rezone_min_quality=0"]  # the fixed mesh's end


def test_a_discharge_until_nearly_empty_ends_cleanly(shared_tmp, comm):
    """A small hopper (0.45 m, 42 kg, ~90 cells) discharged for longer than it takes to empty: the
    mesh keeps all its rows, so as the crater reaches the outlet the last rows over it distort;
    the discharge ends - the run completes - once the worst cell's scaled Jacobian falls below
    discharge.min_mesh_quality (0.1), saying so in the stage record and the summary's warnings,
    naming the fix for a surface cell (the slump), with the mass balance intact; and with that fix
    applied (ale.max_surface_slope = φ = 30°) the hopper empties further. On the scenes' default
    cone (matched in compression), where the energy balance of a discharge used to drift to 1.8 %
    (docs/reliability.md). Measured: without the slump it ends at 2.02 s with 33.1 of 41.9 kg
    (79 %) out, with it at 2.30 s with 37.3 kg (89 %; the rest sits on the shoulders); mass
    balance 1e-7, energy 0.01 %. (Before the free surface kept its volume, 2026-12-04, the run
    without the slump reached 87 %: the surface's placement bridged the crater with volume the
    material did not have.)"""
    ends = {}
    for slope in (0.0, 30.0):
        out = shared_tmp / f"emptying_{slope:g}"
        sc = load_scene(SCENES / "hopper_ch4.toml", SHORT + EMPTYING + [f"ale.max_surface_slope={slope}"])
        summary = run(sc, out, comm, progress_every=1e9)
        comm.barrier()
        h = run_health(out)
        d = summary["stages"][-1]
        assert summary["status"] == "completed" and d["ended_on"] == "mesh quality"
        assert d["t_end"] < 5.0 and any("min_mesh_quality" in w for w in summary["warnings"])
        assert ("ale.max_surface_slope" in d["ended_because"]) == (slope == 0.0)  # the fix, named where it is off
        assert "across its radius" not in d["ended_because"]  # 5 cells, but most of it out: no pipe
        assert h["mass_error_max"] < 1e-6 and h["finite"]
        assert 0.0 < h["min_scaled_jacobian"] < 0.1  # ended on the floor, never inverted
        assert h["energy_error_max"] < 0.01
        ends[slope] = h["discharged_mass"] / h["mass_at_opening"]
    assert ends[0.0] > 0.7  # most of it out before the crater reaches the outlet
    assert ends[30.0] > 0.8 and ends[30.0] > ends[0.0] + 0.05  # nearly empty with the named fix



PIPE = {"geometry": {"shape": "flat_bottom", "radius": 0.6, "height": 2.4, "outlet_radius": 0.06, "element_size": 0.03},
        "material": {"model": "drucker_prager", "density": 1600.0, "youngs_modulus": 1.0e7, "friction_angle": 32.0},
        "wall": {"friction": "coulomb", "mu": 0.4}, "fill": {"method": "k0"}, "store": {"duration": 0.3},
        "discharge": {"mode": "free", "duration": 1.0}, "output": {"stations": [0.3, 1.2], "field_interval": 100.0}}


def test_a_flow_down_a_pipe_one_outlet_wide_names_the_outlets_resolution(shared_tmp, comm):
    """A flat-bottomed silo of sand (R 0.6 m, 2.4 m, outlet radius 0.06 m) meshed at h 0.03 m has
    two cells across its outlet radius: the flow falls down a pipe two cells wide to the surface
    and the discharge ends on the quality floor within a second, with under a tenth of the fill
    out (measured: 0.6 s, 8.6 kg of 4,343). The stage record names the outlet's resolution and
    the keys that fix it; with that fix (an unstructured mesh, outlet_size_factor 0.25: 8 cells;
    refined on the structured mesh the outlet's column would be needles up the silo) the same
    discharge runs its whole second. ~30 s serial (both runs)."""
    ends = {}
    for factor in (1.0, 0.25):
        out = shared_tmp / f"pipe_{factor:g}"
        d = {k: dict(v) for k, v in PIPE.items()}
        d["geometry"]["outlet_size_factor"] = factor
        if factor < 1.0:
            d["geometry"]["mesh"] = "unstructured"
        summary = run(load_scene(d), out, comm, progress_every=1e9)
        comm.barrier()
        st = summary["stages"][-1]
        assert summary["status"] == "completed" and run_health(out)["mass_error_max"] < 1e-6
        ends[factor] = st
    early = ends[1.0]
    assert early["ended_on"] == "mesh quality" and early["t_end"] < 1.3 - 1e-9
    assert "The outlet is 2 cell(s) across its radius" in early["ended_because"]
    assert 'Fix: geometry.mesh = "unstructured" and geometry.outlet_size_factor = 0.25 (' in early["ended_because"]
    assert ends[0.25]["ended_on"] == "duration" and ends[0.25]["t_end"] == pytest.approx(1.3)


def test_a_rezoned_discharge_until_nearly_empty_ends_cleanly(shared_tmp, comm):
    """The same small hopper with rezoning on as the ch. 4 scene ships it (rezone_dt_fall 0.05,
    rezone_min_quality 0.3): as it empties every fresh mesh is soon as distorted as the last, and
    before the fresh-mesh guard (a quality rezone only if the last fresh mesh was above the
    trigger) this rezoned at every remap for 40 min without ending. Now it ends on the quality
    floor as the fixed mesh does, saying it was meshed again, with every rezone conserving the
    mass. Measured: 32 rezones (the Δt trigger: the thin fill's cells shrink), ends at 2.12 s
    with 36.9 of 41.9 kg (88 %) out, mass balance 1.6e-7, in ~5 s of stepping."""
    out = shared_tmp / "emptying_rezoned"
    sc = load_scene(SCENES / "hopper_ch4.toml", SHORT + EMPTYING + ["ale.rezone_dt_fall=0.05", "ale.rezone_min_quality=0.3"])
    summary = run(sc, out, comm, progress_every=1e9)
    comm.barrier()
    h = run_health(out)
    d = summary["stages"][-1]
    assert summary["status"] == "completed" and d["ended_on"] == "mesh quality" and d["t_end"] < 5.0
    assert "Meshed again" in d["ended_because"] and len(d["rezones"]) >= 1
    for r in d["rezones"]:
        assert r["mass_after"] == pytest.approx(r["mass_before"], rel=1e-12) and r["uncovered_mass"] == 0.0
    assert h["mass_error_max"] < 1e-6 and h["finite"] and 0.0 < h["min_scaled_jacobian"] < 0.1
    assert h["discharged_mass"] / h["mass_at_opening"] > 0.8  # as far as the fixed mesh gets (79-89 %)

def test_an_arch_over_the_outlet_stops_cleanly_with_its_cause(shared_tmp, comm):
    """The same abrupt, rough, sudden case on the scenes' default cone (matched in compression,
    φ 40°: it carries equal-biaxial compression without cohesion): an arch holds over the outlet,
    the cells below it empty and Δt falls. Before the Δt guard this ran on at ever smaller steps
    (the ch. 7 scene: 5e-8 s after 1 s); now it stops within the discharge, naming the emptied
    cell and the fix, with everything written so far readable and finite."""
    out = shared_tmp / "arch"
    sc = load_scene(SCENES / "bin_hopper_ch7_abrupt.toml",
                    SHORT + BIN + ["wall.mu=0.9", 'discharge.mode="free"', 'material.cone="compression"',
                                   "numerics.min_time_step_fraction=0.05"])  # Δt/20: the density /400, sooner
    with pytest.raises(InstabilityError, match=r"It has emptied.*material.cone = \"extension\""):
        run(sc, out, comm, progress_every=1e9)
    comm.barrier()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and "min_time_step_fraction" in summary["error"]
    h = run_health(out)
    assert h["finite"]
    o = read_csv(out / "outlet.csv")
    assert o["t"][-1] - o["t"][0] < 1.0  # stopped within the discharge, not at its end
    assert abs(summary["t_reached"] - o["t"][-1]) < 0.01  # where it stopped (outlet rows every 5 ms)


def mpirun(ranks: int) -> list[str]:
    """The launcher beside this Python (the wheel's MPICH), else the one on PATH."""
    exe = Path(sys.executable).parent / "mpirun"
    return [str(exe) if exe.exists() else "mpirun", "-n", str(ranks)]


RANK_LOCAL_ERROR = """
import sys
import silo_dolfinx  # noqa: F401
from mpi4py import MPI
import silo_dolfinx.simulation as sim
from silo_dolfinx.scene import load_scene
from silo_dolfinx.solver import ExplicitSolver

sim.RANK_ERROR_WAIT = 2.0
step = ExplicitSolver.step


def failing(self):
    if MPI.COMM_WORLD.rank == 1 and self.steps == 50:
        raise ValueError("a rank-local error")
    return step(self)


ExplicitSolver.step = failing
sc = load_scene(sys.argv[1], ["geometry.element_size=0.08", 'fill.method="k0"', "store.duration=0.5",
                              'discharge.mode="none"'])
sim.run(sc, sys.argv[2], progress_every=1e9)
"""


def test_no_checkerboard_of_q_over_p_above_the_outlet(shared_tmp, comm):
    """Issue 20, item 5: q/p above the outlet of a ch. 4 hopper (compression cone, φ 30°) used to
    alternate cell to cell between 0 and tan β. The cause: cells over the outlet, stretched in the
    free-fall zone, return to the cone's apex (q = 0, p = −c/tan β = −0.83 Pa) beside cells on the
    cone, and q/p of a cell with p ≤ 0 was written as 0. A stress-free cell's q/p is undefined
    (NaN, grey in the renders: invariants.stress_ratio); what remains above the outlet is one
    plastic zone, every defined cell on the cone. Asserted on the coarse, short version of the
    issue's run (0.04 m, 1,209 cells, 1.5 s of free discharge; 0.03 m / 6 s measured the same in
    docs/reliability.md): the outlet zone's cell-to-cell oscillation is within the issue's bar
    (≤ 2× the rest of the flowing region; measured 0.010×), and each of its defined cells has
    q/p = tan β + c/p within 2 % (the cone with its cohesion; without it the zone is not at yield).
    (On 0.05 m, two cells across the outlet, the cell at the outlet's edge separates from the
    wall and inverts at 0.35 s of the discharge since the mesh is relocated - as the unrelocated
    0.06-m mesh did before: a K0 start that coarse is not what this test is about.)"""
    from silo_dolfinx import analysis
    from silo_dolfinx.materials import make_material

    sc = load_scene(SCENES / "hopper_ch4.toml", ["geometry.element_size=0.04", 'fill.method="k0"', "store.duration=0.5",
                                                 "discharge.duration=1.5", "output.field_interval=1.0",
                                                 "output.points=[]", "output.stations=[0.5]"])
    out = shared_tmp / "ch4"
    run(sc, out, comm, progress_every=1e9)
    if comm.rank:
        return
    snap = dict(np.load(sorted((out / "fields").glob("snapshot_*.npz"))[-1]))
    assert float(snap["t"]) == pytest.approx(2.0)
    m = analysis.outlet_zone_oscillation(snap, sc.geometry.outlet_radius, zone=0.15)
    assert m["outlet_cells"] >= 6 and m["rest_cells"] >= 40  # the zones are populated
    assert m["ratio"] <= 2.0, m  # the bar
    c = snap["corners"].mean(axis=1)
    near = np.hypot(np.maximum(c[:, 0] - sc.geometry.outlet_radius, 0.0), c[:, 1]) < 0.15
    qp, p = snap["cell_q_over_p"][near], snap["cell_p"][near]
    mat = make_material(sc.material)
    on_cone = np.isfinite(qp)
    assert on_cone.sum() >= 3  # not vacuous: measured 14 of the 16 (2 stress-free); on 0.05 m 3 of 7 since the remap
    # lets out what the wall edges at the outlet's ends sweep past it (docs/reliability.md), 4 of 7 before
    assert np.allclose(qp[on_cone], mat.tan_beta + sc.material.cohesion / p[on_cone], rtol=0.02), qp
    assert np.all(p[~on_cone] <= 1e-3 * sc.material.density * sc.loads.gravity * sc.geometry.fill_height)


@pytest.mark.serial  # starts its own 2-rank job
def test_an_error_on_one_rank_never_hangs_the_others(tmp_path):
    """An exception on one rank alone (here injected at step 50 on rank 1) used to leave the other
    rank waiting for ever in its next collective (the ch. 7 study: a rank-local negative-mass check
    in the remap, 11 minutes of two ranks spinning until killed). Now the failed rank waits a
    while for the others (RANK_ERROR_WAIT, shortened to 2 s here), then prints the error and aborts
    every rank: the job ends, non-zero, naming the error."""
    script = tmp_path / "fail.py"
    script.write_text(RANK_LOCAL_ERROR)
    env = subprocess_env()
    done = subprocess.run([*mpirun(2), sys.executable, str(script),
                           str(SCENES / "hopper_ch3_ale.toml"), str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=120, env=env)
    assert done.returncode != 0
    assert "a rank-local error" in done.stderr and "aborting all ranks" in done.stderr


KILLED_RUN = """
import sys
import silo_dolfinx  # noqa: F401
from silo_dolfinx.output.writer import Results
from silo_dolfinx.scene import load_scene
from silo_dolfinx.simulation import run

Results.HEARTBEAT = 0.2  # s: often enough to be seen before the kill
sc = load_scene(sys.argv[2], sys.argv[3:])
run(sc, sys.argv[1], progress_every=1e9)
"""


def _stop_after_a_discharge_checkpoint(job, out, stop) -> None:
    """Wait (at most 120 s) until the job in ``out`` has written a checkpoint in its discharge
    (0.2 s of storage, then 0.05 s of discharge), then ``stop()`` it and wait for it to end; the
    job's process group is killed whatever happens."""
    import os
    import signal
    import time

    try:
        deadline = time.time() + 120
        while time.time() < deadline and job.poll() is None:
            s = json.loads((out / "summary.json").read_text()) if (out / "summary.json").is_file() else {}
            if s.get("checkpoint", {}).get("t", 0.0) > 0.25:
                break
            time.sleep(0.05)
        assert job.poll() is None, job.stderr.read().decode()[-2000:]
        stop()
        job.wait(timeout=60)
    finally:
        if job.poll() is None:
            os.killpg(job.pid, signal.SIGKILL)


@pytest.mark.serial  # starts its own jobs, on 1 and on 2 ranks, and kills them
@pytest.mark.parametrize("ranks", [1, 2])
def test_a_run_killed_mid_discharge_leaves_readable_results_and_resumes_to_the_same_end(tmp_path, ranks):
    """SIGKILL (no handler runs) to a run in its discharge, after its first checkpoint there: every
    CSV written so far has only complete rows, summary.json parses with status "running" and
    records the stage and time it had reached and its last checkpoint. ``silo run --resume`` on
    as many ranks then finishes it, and it ends as the same run uninterrupted does: the wall
    profile to 1e-8 (the issue's bar), and in fact every CSV byte for byte (same partition,
    same operations)."""
    import os
    import signal

    from silo_dolfinx.output import read_rows

    script = tmp_path / "killed.py"
    script.write_text(KILLED_RUN)
    scene, sets, _ = CASES["abrupt_rough_sudden"]
    # checkpoints every 0.1 s of wall-clock through a 1-s discharge: with 0.5 s and 0.5 s, a warm
    # machine (numba's cache filled) ran the whole discharge in 0.4 s and wrote no checkpoint in it
    args = [str(SCENES / f"{scene}.toml"), *SHORT, *sets, "discharge.duration=1.0", "output.checkpoint_interval=0.1"]
    launch = [*mpirun(ranks)] if ranks > 1 else []
    out = tmp_path / "out"
    job = subprocess.Popen([*launch, sys.executable, str(script), str(out), *args], env=subprocess_env(),
                           start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _stop_after_a_discharge_checkpoint(job, out, lambda: os.killpg(job.pid, signal.SIGKILL))
    csvs = sorted(out.glob("*.csv"))
    assert {"energy.csv", "outlet.csv", "wall_history.csv", "mesh_quality.csv"} <= {p.name for p in csvs}
    for path in csvs:
        text = path.read_text()
        assert text.endswith("\n"), path.name  # the last row is complete
        head, *rows = list(csv.reader(text.splitlines()))
        assert rows and all(len(r) == len(head) for r in rows), path.name
        read_rows(path)  # and the one reader takes it (header against the schema)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "running"
    assert summary["stage"] == "discharge" and summary["t_reached"] > 0.2 and summary["steps"] > 0
    assert summary["checkpoint"]["t"] > 0.25 and (out / "checkpoint" / "checkpoint.json").is_file()

    subprocess.run([*launch, sys.executable, "-m", "silo_dolfinx.cli", "run", "--resume", str(out), "--progress",
                    "1e9"], env=subprocess_env(), check=True, capture_output=True, timeout=300)
    reference = tmp_path / "reference"
    subprocess.run([*launch, sys.executable, str(script), str(reference), *args], env=subprocess_env(), check=True,
                   capture_output=True, timeout=300)
    done = json.loads((out / "summary.json").read_text())
    assert done["status"] == "completed" and done["resumed"][0]["from_t"] == summary["checkpoint"]["t"]
    a, b = (read_csv(f / "wall_profile_discharge.csv") for f in (reference, out))
    assert np.allclose(a["p_n"], b["p_n"], rtol=1e-8, atol=0.0)
    differ = [p.name for p in sorted(reference.glob("*.csv")) if p.read_bytes() != (out / p.name).read_bytes()]
    assert not differ, differ


@pytest.mark.serial  # starts its own 2-rank job and stops it
def test_a_run_stopped_by_sigterm_says_interrupted_and_resumes(tmp_path):
    """SIGTERM (what a batch system's time limit or ``kill`` sends) to mpirun during the
    discharge, after a checkpoint there: the run ends as Ctrl-C ends it - exit 130, summary.json
    with status "interrupted", the signal, the time reached (past the checkpoint) and how to
    resume; every CSV has only complete rows - and ``silo run --resume`` completes it. Before,
    SIGTERM killed the ranks outright and summary.json said "running"; acted on where it landed,
    one rank stopped while the other waited in a collective (30 s, then MPI_Abort): the signal
    now only asks, and the ranks stop together at the next history sample."""
    import signal

    from silo_dolfinx.output import read_rows

    scene, sets, _ = CASES["abrupt_rough_sudden"]
    out = tmp_path / "out"
    cli = [*mpirun(2), sys.executable, "-m", "silo_dolfinx.cli", "run"]
    sets = [*SHORT, *sets, "discharge.duration=1.0", "output.checkpoint_interval=0.1"]
    job = subprocess.Popen([*cli, str(SCENES / f"{scene}.toml"), "--out", str(out), "--progress", "1e9",
                            *(a for s in sets for a in ("--set", s))],
                           env=subprocess_env(), start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _stop_after_a_discharge_checkpoint(job, out, lambda: job.send_signal(signal.SIGTERM))  # mpirun forwards it
    assert job.returncode == 130, job.stderr.read().decode()[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted", summary
    assert "SIGTERM" in summary["error"] and "--resume" in summary["error"]
    assert summary["t_reached"] >= summary["checkpoint"]["t"] > 0.25
    for path in sorted(out.glob("*.csv")):
        text = path.read_text()
        assert text.endswith("\n"), path.name
        read_rows(path)
    subprocess.run([*cli, "--resume", str(out), "--progress", "1e9"], env=subprocess_env(), check=True,
                   capture_output=True, timeout=300)
    done = json.loads((out / "summary.json").read_text())
    assert done["status"] == "completed" and done["resumed"][0]["from_t"] == summary["checkpoint"]["t"]
