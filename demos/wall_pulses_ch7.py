# # Thesis ch. 7, beyond it: why the upper bin's wall pressure pulses with a constant μ
#
# The ch. 7 silo (a 0.7-m cylinder on a 20° hopper, 5 m of fill, wall μ 0.67, the discharge
# solid the Drucker-Prager cone matched in extension; `demos/bin_hopper_ch7.py`) pulses in
# discharge: from ~3 s after the opening the wall pressure of the upper bin swings at ~8 Hz, the
# fill's second longitudinal mode (c/H), between ~0 and two to three times its mean, and the wall
# sticks and slips with it - with a *constant* μ, i.e. without the velocity weakening (eq. 7-1)
# the thesis offers as the cause of slip-stick. This demo asks what sets it, one thing changed at
# a time:
#
# * the numerics: Δt halved, bulk viscosity doubled, one-point integration, the mesh halved - a
#   physical instability does not care;
# * the wall: μ 0.3 to 1.0 and a smooth wall, the threshold's two sides again with Δt halved and
#   on meshes h/2 and h/4; the solid: ψ 0 and Mohr-Coulomb's pyramid; the outlet velocity halved;
# * in the cell beside the wall (a fixed interior point at 3.6 m): how often the solid there is at
#   yield, the Mohr-Coulomb angle it mobilises (`analysis.mobilised_friction_angle`), and the
#   shear it carries on the wall's plane, |σ_rz|/σ_rr, against the most the cone admits at its
#   normal stresses (`analysis.wall_shear_capacity`): a wall rougher than that cannot slide
#   before the solid beside it yields.
#
# The answer it measures (docs/validation/ch7.md, "Why the upper bin pulses"): above a critical
# μ (0.55-0.575 on the 0.04-m mesh, lower on finer meshes) the wall's steady sliding is itself
# unstable - the pulses grow while the wall slides throughout, and the sticking follows the grown
# pulses (the flutter of sliding under Coulomb friction, Martins et al. 1995); below it they
# decay. They are worst where μ is near what the solid beside the wall can carry on the wall's
# plane (~0.67 here), where the wall alternates between slip and stick.
#
# Last, the wall's friction with a memory (`wall.regularisation_length`, the simplified
# Prakash-Clifton law): does a limit that follows the normal force over milliseconds, which makes
# sliding well-posed, make the pulses converge with the mesh? (Docs: "The wall's friction with a
# memory".)
#
# And the solid's side: a Drucker-Prager solid without a length of its own shears beside the wall
# in a band one element wide, whatever the element. `material.relaxation_time` τ (Duvaut-Lions
# viscoplasticity) gives it one, ~ c_s τ; the same μ 0.67 discharge with τ 0.1-2 ms, the 0.25-,
# 1- and 2-ms ones on h, h/2, h/4, says whether the pulses' drift with the mesh is the solid's. (Docs:
# "A solid with a relaxation time".)
#
# What the longer τ leave, a 28-36-Hz oscillation, is measured in space: its shape across the
# section at 3.6 m against the section's vertical shear mode (`theory.axial_shear_frequency`), and
# up the hopper and the bin as a travelling wave (`analysis.mode_shape`, `analysis.travelling_wave`):
# a longitudinal wave from the outlet zone that climbs the fill and grows as the ch. 5 waves do.
# (Docs: "The faster oscillation".)
#
#     mpirun -n 2 python demos/wall_pulses_ch7.py --quick    # h 0.05 m, 6 s, 4 variants (~4 min)
#     mpirun -n 2 python demos/wall_pulses_ch7.py            # h 0.04 m, 10 s, every variant (49 runs, ~6 h 30 min; each h/4 32-41 min)
#     ... --variants mu067 mu05 --reuse                       # measure what is there
#
# Results: `results/wall_pulses_ch7[_quick]/VARIANT/`, the table in `table.md` and the figure
# `wall_pulses.png` next to them (and, for the relaxation times, `relaxation_time.png`; for the faster
# oscillation `fast_mode.md` and `fast_mode.png`).

# +
import argparse
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

import silo_dolfinx  # noqa: F401  (imports dolfinx_solver first where it exists)
from silo_dolfinx import analysis, theory
from silo_dolfinx.output import read_csv, read_summary
from silo_dolfinx.scene import load_scene
from silo_dolfinx.simulation import run
from silo_dolfinx.solver import InstabilityError

SCENE = Path(__file__).parent / "scenes" / "bin_hopper_ch7_abrupt.toml"
comm = MPI.COMM_WORLD
# name: (overrides, what it changes); "hN" and "*_hN" also divide the element size by N


def MEMORY(length, speed=0.01):  # noqa: N802  (reads as a constant's name in the table)
    return [f"wall.regularisation_length={length}", f"wall.regularisation_speed={speed}"]


VARIANTS = {
    "mu067": ([], "μ 0.67 (the reference)"),
    "mu05": (["wall.mu=0.5"], "μ 0.5"),
    "mu03": (["wall.mu=0.3"], "μ 0.3"),
    "mu055": (["wall.mu=0.55"], "μ 0.55"),
    "mu0575": (["wall.mu=0.575"], "μ 0.575"),
    "mu06": (["wall.mu=0.6"], "μ 0.6"),
    "mu08": (["wall.mu=0.8"], "μ 0.8"),
    "mu055_dt05": (["wall.mu=0.55", "numerics.time_step_scale=0.4"], "μ 0.55, Δt × 0.5"),
    "mu0575_dt05": (["wall.mu=0.575", "numerics.time_step_scale=0.4"], "μ 0.575, Δt × 0.5"),
    "mu05_h2": (["wall.mu=0.5"], "μ 0.5, h / 2"),
    "mu05_h4": (["wall.mu=0.5"], "μ 0.5, h / 4"),
    "mu055_h2": (["wall.mu=0.55"], "μ 0.55, h / 2"),
    "mu0575_h2": (["wall.mu=0.575"], "μ 0.575, h / 2"),
    "smooth": (['wall.friction="none"'], "smooth wall"),
    "mu10": (["wall.mu=1.0"], "μ 1.0"),
    "mohr_coulomb": (['material.model="mohr_coulomb"'], "Mohr-Coulomb's pyramid, φ 40°"),
    "psi0": (["material.dilation_angle=0"], "ψ 0"),
    "u05": (["discharge.velocity=0.5"], "u0/2"),
    "dt05": (["numerics.time_step_scale=0.4"], "Δt × 0.5"),
    "bulk2": (["numerics.bulk_viscosity=[0.12, 2.4]"], "bulk viscosity × 2"),
    "reduced": (['numerics.integration="reduced"'], "one-point integration"),
    "h2": ([], "h / 2"),
    "h4": ([], "h / 4"),
    # the wall friction's memory (wall.regularisation_length L, v* 0.01 m/s): the limit follows
    # the normal force over L/(|v_slip| + v*) - 8 ms at 0.05 m/s of slip for L 0.5 mm, 2 ms for
    # 0.1 mm; the pulses' period is 114 ms, the mesh's shortest shear periods h/c_s 0.5-2 ms
    "mu067_L05": (MEMORY(5e-4), "μ 0.67, memory L 0.5 mm"),
    "mu067_L05_h2": (MEMORY(5e-4), "μ 0.67, memory L 0.5 mm, h / 2"),
    "mu067_L05_h4": (MEMORY(5e-4), "μ 0.67, memory L 0.5 mm, h / 4"),
    "mu067_L01": (MEMORY(1e-4), "μ 0.67, memory L 0.1 mm"),
    "mu067_L01_h2": (MEMORY(1e-4), "μ 0.67, memory L 0.1 mm, h / 2"),
    "mu067_L01_h4": (MEMORY(1e-4), "μ 0.67, memory L 0.1 mm, h / 4"),
    "mu055_L05": (["wall.mu=0.55", *MEMORY(5e-4)], "μ 0.55, memory L 0.5 mm"),
    "mu055_L05_h2": (["wall.mu=0.55", *MEMORY(5e-4)], "μ 0.55, memory L 0.5 mm, h / 2"),
    "mu055_L01": (["wall.mu=0.55", *MEMORY(1e-4)], "μ 0.55, memory L 0.1 mm"),
    "mu055_L05v10": (["wall.mu=0.55", *MEMORY(5e-4, 0.1)], "μ 0.55, memory L 0.5 mm, v* 0.1 m/s"),
    "mu055_L01_h2": (["wall.mu=0.55", *MEMORY(1e-4)], "μ 0.55, memory L 0.1 mm, h / 2"),
    # the solid with a relaxation time τ (material.relaxation_time, Duvaut-Lions): its shear bands
    # get a width ~ c_s τ (c_s 22 m/s: 2.2 cm for 1 ms, 4.5 cm for 2 ms) instead of one element's
    "mu067_vp1": (["material.relaxation_time=1e-3"], "μ 0.67, solid τ 1 ms"),
    "mu067_vp1_h2": (["material.relaxation_time=1e-3"], "μ 0.67, solid τ 1 ms, h / 2"),
    "mu067_vp1_h4": (["material.relaxation_time=1e-3"], "μ 0.67, solid τ 1 ms, h / 4"),
    "mu067_vp2": (["material.relaxation_time=2e-3"], "μ 0.67, solid τ 2 ms"),
    "mu067_vp2_h2": (["material.relaxation_time=2e-3"], "μ 0.67, solid τ 2 ms, h / 2"),
    "mu067_vp2_h4": (["material.relaxation_time=2e-3"], "μ 0.67, solid τ 2 ms, h / 4"),
    "mu067_vp025": (["material.relaxation_time=2.5e-4"], "μ 0.67, solid τ 0.25 ms"),
    "mu067_vp025_h2": (["material.relaxation_time=2.5e-4"], "μ 0.67, solid τ 0.25 ms, h / 2"),
    "mu067_vp025_h4": (["material.relaxation_time=2.5e-4"], "μ 0.67, solid τ 0.25 ms, h / 4"),
    "mu067_vp01": (["material.relaxation_time=1e-4"], "μ 0.67, solid τ 0.1 ms"),
    "mu067_vp1_dt05": (["material.relaxation_time=1e-3", "numerics.time_step_scale=0.4"], "μ 0.67, solid τ 1 ms, Δt × 0.5"),
    # what feeds the climbing wave (the faster oscillation): without wall friction, and with a wall that sticks
    "smooth_vp1": (['wall.friction="none"', "material.relaxation_time=1e-3"], "smooth wall, solid τ 1 ms"),
    "mu10_vp1": (["wall.mu=1.0", "material.relaxation_time=1e-3"], "μ 1.0, solid τ 1 ms"),
    # τ 2 ms on h/4 ended at 4.34 s on the mesh-quality floor (a cell at the outlet's axis): the same, re-meshed there
    "mu067_vp2rz_h4": (["material.relaxation_time=2e-3", "ale.rezone_min_quality=0.3"],
                       "μ 0.67, solid τ 2 ms, h / 4, re-meshed below quality 0.3"),
    "mu067_vp1_psi40": (["material.dilation_angle=40", "material.relaxation_time=1e-3"], "μ 0.67, solid τ 1 ms, ψ = φ (associated)"),
}
QUICK = ("mu067", "mu05", "mu10", "dt05")
ap = argparse.ArgumentParser()
ap.add_argument("--quick", action="store_true", help="h 0.05 m, 6 s of discharge, variants " + " ".join(QUICK))
ap.add_argument("--variants", nargs="+", choices=tuple(VARIANTS), help="variants to run and measure")
ap.add_argument("--reuse", action="store_true", help="run nothing: measure the results already there")
args, _ = ap.parse_known_args()
h, duration = (0.05, 6.0) if args.quick else (0.04, 10.0)
window = (duration / 2, duration) if args.quick else (4.0, duration)  # s after the opening: the grown pulses
variants = args.variants or (QUICK if args.quick else tuple(VARIANTS))
ROOT = Path("results") / ("wall_pulses_ch7" + ("_quick" if args.quick else ""))
STATIONS = (2.0, 3.6, 4.4)  # m: mid-bin, the upper bin, near the surface
R_WALL = 0.35
RADII = (0.01, 0.05, 0.15, 0.2, 0.25, 0.3)  # m, with 0.1 and the two wall cells: nine radii at 3.6 m
HEIGHTS = (0.8, 1.0, 1.2, 1.4, 1.6, 1.8, 2.2, 2.4, 2.6, 2.8, 3.0, 3.2, 3.4, 3.8, 4.0, 4.2)  # m, with 2.0, 3.6, 4.4
HOPPER = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7)  # m (the transition at 0.687 m), at r 0.05 m


def say(*a):
    if comm.rank == 0:
        print(*a, flush=True)


def scene_of(name):
    sets, _ = VARIANTS[name]
    last = name.split("_")[-1]
    hv = h / int(last[1:]) if last[0] == "h" and last[1:].isdigit() else h
    # the interior points: the centre of the cell beside the wall, one further in, and near the
    # axis, at each station's height (a fixed point reports the mean of the cell containing it)
    points = [[r, z] for z in STATIONS for r in (R_WALL - hv / 2, R_WALL - 1.5 * hv, 0.1)]
    points += [[r, 3.6] for r in RADII]  # across the section at 3.6 m: the shape of the faster mode
    points += [[0.1, z] for z in HEIGHTS]  # and up the fill at r 0.1 m: its wavelength
    points += [[0.05, z] for z in HOPPER]  # and in the hopper, near the axis: where it comes from
    return load_scene(SCENE, [f"geometry.element_size={hv}", f"discharge.duration={duration}", 'material.cone="extension"',
                              f"output.stations=[{', '.join(map(str, STATIONS))}]",
                              f"output.points={points}", "output.field_interval=5.0", *sets])


if not args.reuse:
    for name in variants:
        say(f"== {name}: {VARIANTS[name][1]}")
        start = time.perf_counter()
        try:
            run(scene_of(name), ROOT / name, comm, progress_every=60.0)
        except InstabilityError as err:
            say(f"   stopped: {err}")
        if comm.rank == 0:
            (ROOT / name / "wall_clock.txt").write_text(f"{time.perf_counter() - start:.1f}\n")
comm.barrier()
# -

# ## Measuring each variant
#
# Over the window (s after the opening): at each station the mean and standard deviation of
# p_n, its dominant frequency in 1-40 Hz, the fraction of the samples in which the wall node
# slides (|v_slip| > 0.1 mm/s, `analysis.slip_fraction`); the standard deviation at 3.6 m in
# 1-s windows from the opening (growth or decay); in the cell beside the wall at 3.6 m, the
# fraction of the samples at yield - q/p within 3 % of the cone's tan β (Drucker-Prager) or
# φ_mob within 3 % of φ (Mohr-Coulomb) -, the median φ_mob and b, the median |σ_rz|/σ_rr and the
# median shear capacity of the wall's plane there (Drucker-Prager only): where μ exceeds it the
# solid yields before the wall slides.

# +
YIELD_MARGIN = 0.97  # "at yield": within 3 % of the strength (the cell means of 2x2 points sit just inside it)


def measure(name):
    out = ROOT / name
    summary = read_summary(out)
    if summary.get("status") != "completed":
        return {"name": name, "failed": summary.get("error", summary.get("status", "not run"))}
    sc = load_scene(out / "scene.toml")
    stages = {s["name"]: s for s in summary["stages"]}
    t_open = stages["discharge"]["t_start"]
    wall = read_csv(out / "wall_history.csv")
    t_w, z_w, P = analysis.station_matrix(wall, "station", "p_n")
    _, _, V = analysis.station_matrix(wall, "station", "slip_velocity")
    in_w = (t_w >= t_open + window[0]) & (t_w <= t_open + window[1])
    ended = stages["discharge"]["t_end"] - t_open  # a run that stopped early (e.g. on mesh quality) says so
    res = {"name": name, "energy": summary["energy_balance_error_max"],
           "wall_clock": float((out / "wall_clock.txt").read_text()) if (out / "wall_clock.txt").exists() else np.nan,
           "label": VARIANTS[name][1] + (f" (ended at {ended:.2f} s)" if ended < window[1] - 1e-6 else "")}
    for k, z in enumerate(z_w):
        p = P[k, in_w]
        sp = analysis.spectrum(t_w[in_w], p)
        band = (sp.frequency > 1.0) & (sp.frequency < 40.0)
        res[f"z{k}"] = dict(z=z, mean=p.mean(), std=p.std(), p99=np.percentile(p, 99),
                            f=sp.frequency[band][np.argmax(sp.amplitude[band])], slides=analysis.slip_fraction(V[k, in_w]))
    k36 = int(np.argmin(np.abs(z_w - 3.6)))
    edges = np.arange(0.0, window[1] + 1e-9, 1.0)
    # the 8-Hz mode's share of the std at 3.6 m and what lies above it (Parseval over a plain,
    # mean-removed spectrum: std² = Σ amplitude²/2)
    sp = analysis.spectrum(t_w[in_w], P[k36, in_w], detrend="constant", window=None)
    res["bands"] = [np.sqrt(0.5 * np.sum(sp.amplitude[(sp.frequency >= lo) & (sp.frequency < hi)] ** 2))
                    for lo, hi in ((4.0, 15.0), (15.0, np.inf))]
    res["growth"] = [P[k36, (t_w >= t_open + a) & (t_w < t_open + a + 1.0)].std() for a in edges[:-1]]
    pts = read_csv(out / "point_history.csv")
    m = (pts["point"] == 3) & (pts["t"] >= t_open + window[0]) & (pts["t"] <= t_open + window[1])  # wall cell, 3.6 m
    sig = np.stack([pts[c][m] for c in ("stress_rr", "stress_zz", "stress_tt", "stress_rz")], axis=1)
    phi, b = analysis.mobilised_friction_angle(sig)
    mat = sc.material
    capacity, over = np.full(len(sig), np.nan), np.nan
    if mat.model == "mohr_coulomb":
        at_yield = phi >= YIELD_MARGIN * mat.friction_angle
    else:
        tan_beta = np.tan(np.radians(theory.drucker_prager_cone(mat.friction_angle, mat.dilation_angle, mat.cone)[0]))
        at_yield = pts["q_over_p"][m] >= YIELD_MARGIN * tan_beta
        capacity = analysis.wall_shear_capacity(sig, tan_beta)
        over = np.nanpercentile(pts["q_over_p"][m] / tan_beta, 95)  # > 1: outside the cone (a viscoplastic overstress)
    res["wall_cell"] = dict(at_yield=float(np.mean(at_yield)), phi=float(np.nanmedian(phi)), b=float(np.nanmedian(b)),
                            shear=float(np.median(np.abs(sig[:, 3]) / np.maximum(-sig[:, 0], 1e-9))),
                            capacity=float(np.nanmedian(capacity)) if np.isfinite(capacity).any() else np.nan,
                            over=float(over))
    res["trace"] = (t_w[in_w] - t_open, P[k36, in_w])
    res["mode"] = fast_mode(pts, t_w, P[k36], (t_open + window[0], t_open + window[1]))
    if res["mode"]:
        res["mode"]["mu"] = sc.wall.get("mu", 0.0) if sc.wall.friction == "coulomb" else 0.0  # eq. 5-1's (none: smooth)
    return res


def fast_mode(pts, t_w, p36, win):
    """The faster oscillation at 3.6 m: its peak in p_n over 15-45 Hz; across the section the
    shape of v_z that moves with the point nearest the axis in that peak's band ± 4 Hz
    (`analysis.mode_shape`; p_n at the wall, resampled onto the points' times, rides along for
    its coherence); up the fill at r 0.1 m (0.8-3.6 m, relative to 3.6 m) v_z and σ_zz as a
    travelling wave (`analysis.travelling_wave`). None for runs without these points."""
    where = {k: (pts["r"][pts["point"] == k][0], pts["z"][pts["point"] == k][0]) for k in np.unique(pts["point"]).astype(int)}
    section = sorted((r, k) for k, (r, z) in where.items() if abs(z - 3.6) < 1e-9)
    climb = sorted((z, k) for k, (r, z) in where.items() if (abs(r - 0.1) < 1e-9 and 0.7 < z < 3.6 + 1e-9)
                   or (abs(r - 0.05) < 1e-9 and z < 0.75))  # the bin at r 0.1 m, the hopper at r 0.05 m
    if len(section) < 6 or sum(z > 0.75 for z, _ in climb) < 6:  # (runs before 2026-12-07 have none; some no hopper points)
        return None
    t = pts["t"][pts["point"] == section[0][1]]
    keep = (t >= win[0]) & (t <= win[1])
    inw = (t_w >= win[0]) & (t_w <= win[1])
    sp = analysis.spectrum(t_w[inw], p36[inw])
    band = (sp.frequency > 15.0) & (sp.frequency < 45.0)
    f = float(sp.frequency[band][np.argmax(sp.amplitude[band])])
    band = (f - 4.0, f + 4.0)

    def series(column, k):
        return pts[column][pts["point"] == k][keep]

    m = analysis.mode_shape(t[keep], [series("v_z", k) for _, k in section] + [np.interp(t[keep], t_w, p36)], band)
    r = np.array([r for r, _ in section])
    z = np.array([z for z, _ in climb])
    bin_ = z > 0.75
    up = {}
    for column in ("v_z", "stress_zz"):
        mz = analysis.mode_shape(t[keep], [series(column, k) for _, k in climb], band, reference=len(climb) - 1)
        up[column] = (analysis.travelling_wave(z[bin_], mz.ratio[bin_], f), mz)
    outlet = (z > 0.05) & (z < 0.45)  # the outlet zone, 0.1-0.4 m
    spread = emerging = np.nan
    if outlet.sum() >= 3:
        spread = np.degrees(np.ptp(np.unwrap(np.angle(up["v_z"][1].ratio[outlet]))))
        emerging = abs(up["stress_zz"][1].ratio[np.argmin(abs(z - 0.2))] / up["stress_zz"][1].ratio[np.argmin(abs(z - 0.8))])
    # the lateral ratio the wave carries at the wall (eq. 5-1's k): δσ_rr over δσ_zz in the wall cell, in phase
    wall = section[-1][1]
    k = analysis.mode_shape(t[keep], [series("stress_zz", wall), series("stress_rr", wall)], band).in_phase[1]
    return dict(f=f, r=r, shape=m.in_phase[:-1], coherence=m.coherence[:-1], p_coherence=float(m.coherence[-1]),
                z=z, up=up, k=float(k), spread=float(spread), emerging=float(emerging))


R = {}
if comm.rank == 0:
    R = {n: measure(n) for n in variants}
# -

# ## The table and the figure

# +
if comm.rank == 0:
    rows = [f"# Why the upper bin pulses (h {h:g} m, {duration:g} s of discharge; window {window[0]:g}-{window[1]:g} s "
            "after the opening)", "",
            "| variant | p_n at 3.6 m: mean / std (kPa) | its frequency | std at 4.4 m / 2.0 m (kPa) | std at 3.6 m "
            "per 1-s window from the opening (kPa) | wall slides (3.6 m) | wall cell at 3.6 m: at yield / φ_mob / b / "
            "σ_rz/σ_rr / capacity | 99th pct. at 4.4 m (kPa) | energy error | wall-clock | wall cell's q/q_y, 95th pct. | std at 3.6 m in 4-15 Hz / above 15 Hz (kPa) |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for n, r in R.items():
        if "failed" in r:
            rows.append(f"| {VARIANTS[n][1]} | {r['failed']} |" + " |" * 10)
            continue
        a, b, c = r["z0"], r["z1"], r["z2"]
        w = r["wall_cell"]
        rows.append(f"| {r['label']} | {b['mean'] / 1e3:.2f} / {b['std'] / 1e3:.2f} | {b['f']:.1f} Hz | "
                    f"{c['std'] / 1e3:.2f} / {a['std'] / 1e3:.2f} | {' '.join(f'{g / 1e3:.2f}' for g in r['growth'])} | "
                    f"{b['slides']:.0%} | {w['at_yield']:.0%} / {w['phi']:.1f}° / {w['b']:.2f} / {w['shear']:.3f} / "
                    f"{w['capacity']:.3f} | {c['p99'] / 1e3:.2f} | "
                    f"{r['energy']:.3%} | {r['wall_clock']:.0f} s | {w['over']:.2f} | "
                    f"{r['bands'][0] / 1e3:.2f} / {r['bands'][1] / 1e3:.2f} |")
    ROOT.mkdir(parents=True, exist_ok=True)
    (ROOT / "table.md").write_text("\n".join(rows) + "\n")
    print("\n".join(rows))

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    # the growth or decay of the pulses: the μ sweep on the scene's mesh, then the threshold's two
    # sides with Δt halved and on finer meshes (the numerics and solid variants are in the table)
    SWEEP = ("smooth", "mu03", "mu05", "mu055", "mu0575", "mu06", "mu067", "mu08", "mu10")
    SIDES = ("mu055", "mu0575", "mu055_dt05", "mu0575_dt05", "mu05_h2", "mu055_h2", "mu0575_h2", "mu05_h4")
    # the pulses' size against the element size: Coulomb's limit and the limit's memory
    FAMILIES = {"μ 0.67, Coulomb": ("mu067", "h2", "h4"), "μ 0.67, L 0.5 mm": ("mu067_L05", "mu067_L05_h2", "mu067_L05_h4"),
                "μ 0.67, L 0.1 mm": ("mu067_L01", "mu067_L01_h2", "mu067_L01_h4"),
                "μ 0.55, Coulomb": ("mu055", "mu055_h2", None), "μ 0.55, L 0.5 mm": ("mu055_L05", "mu055_L05_h2", None),
                "μ 0.55, L 0.1 mm": ("mu055_L01", "mu055_L01_h2", None)}
    fig, ax = plt.subplots(2, 2, figsize=(13, 8))
    ax = ax.ravel()
    for k, (label, names) in enumerate(FAMILIES.items()):
        got = [(h / 2**j, R[n]["z1"]["std"] / 1e3) for j, n in enumerate(names) if n in R and "failed" not in R[n]]
        if got:
            ax[3].plot(*zip(*got), marker="o", ls="-" if "0.67" in label else "--", color=f"C{k % 3}", label=label)
    ax[3].set(xscale="log", xlabel="element size h (m)", ylabel="std of p_n at 3.6 m over the window (kPa)",
              title="the pulses' size against the mesh: Coulomb's limit and the limit's memory")
    for panel, names in ((ax[1], SWEEP), (ax[2], SIDES)):
        shown = [n for n in names if n in R and "failed" not in R[n]]
        for k, n in enumerate(shown):
            g = np.array(R[n]["growth"]) / 1e3
            panel.plot(np.arange(len(g)) + 0.5, g, marker="o", color=plt.cm.viridis(k / max(len(shown) - 1, 1)),
                       ls="--" if "_" in n else "-", label=VARIANTS[n][1])
    for n in ("mu055", "mu0575", "mu067"):
        if n in R and "failed" not in R[n]:
            t, p = R[n]["trace"]
            keep = t < window[0] + 1.5
            ax[0].plot(t[keep], p[keep] / 1e3, label=VARIANTS[n][1])
    ax[0].set(xlabel="time after the opening (s)", ylabel="p_n at 3.6 m (kPa)", title="the upper bin's wall pressure")
    for a, title in ((ax[1], "the pulses against the wall's μ"), (ax[2], "the threshold's sides: Δt and mesh")):
        a.set(xlabel="time after the opening (s)", ylabel="std of p_n at 3.6 m in 1-s windows (kPa)", title=title)
    for a in ax:
        if a.get_legend_handles_labels()[0]:
            a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(ROOT / "wall_pulses.png", dpi=110)
# -

# ## The faster oscillation: a mode of the section, or a wave up the fill?
#
# Where the 8-Hz pulses are gone (τ 1-2 ms) what remains oscillates at 28-36 Hz. A long column
# in a cylinder has an axisymmetric mode with no radial motion: vertical shear, u_z ∝ J0(ω r/c_s)
# (`theory.axial_shear_frequency`; the solver reproduces it to 0.2 %, tests/test_explicit.py). A
# wall that slides under Coulomb's limit does not change its shear traction (τ = μ p_n, and the
# mode leaves p_n alone), so the mode sees a shear-free wall: J1(kR) = 0, 39.1 Hz here, the axis
# against the wall (the wall at −0.40 of the axis beyond a node at 0.63 R); a stuck wall holds
# u_z: J0(kR) = 0, 24.5 Hz. Measured: the peak of p_n at 3.6 m in 15-45 Hz, the share of the
# window the wall slides there, the in-phase shape of v_z across the section at 3.6 m relative to
# the axis - and, since the section turns out to move as one, the oscillation up the hopper and
# the bin as a travelling wave (speed, growth against eq. 5-1 with the lateral ratio k the wave
# carries at the wall, how well its phases fit one wave), and in the outlet zone.

# +
if comm.rank == 0:
    modes = {n: r for n, r in R.items() if "failed" not in r and r.get("mode")}
    if modes:
        mat = load_scene(ROOT / next(iter(modes)) / "scene.toml").material
        f_slip, f_stick = (theory.axial_shear_frequency(mat.youngs_modulus, mat.poisson_ratio, mat.density, R_WALL, w)
                           for w in ("slip", "stick"))
        k_fill = mat.poisson_ratio / (1.0 - mat.poisson_ratio)  # the elastic fill's lateral ratio of increments
        c_p = theory.confined_wave_speed(mat.youngs_modulus, mat.poisson_ratio, mat.density)
        rows = [f"# The faster oscillation at 3.6 m (sliding-wall shear mode {f_slip:.1f} Hz, stuck {f_stick:.1f} Hz; "
                f"c_p {c_p:.1f} m/s)", "",
                "| variant | peak of p_n in 15-45 Hz | wall slides (3.6 m) | v_z at the wall cell / at the axis, in phase "
                "(shear mode: −0.40 sliding, 0.08 stuck) | coherence across the section, least / p_n's | up the fill at r 0.1 m "
                "(0.8-3.6 m): phase speed | growth of v_z / σ_zz | phase residual | coherence, least | "
                "the wave's k at the wall (δσ_rr/δσ_zz in phase) | eq. 5-1 with it, 2μk/D | the outlet zone (r 0.05 m, "
                "z 0.1-0.4 m): spread of v_z's phase / σ_zz at 0.2 m over σ_zz at 0.8 m |",
                "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for n, r in modes.items():
            m = r["mode"]
            (wv, mv), (ws, ms) = m["up"]["v_z"], m["up"]["stress_zz"]
            rows.append(f"| {r['label']} | {m['f']:.1f} Hz | {r['z1']['slides']:.0%} | {m['shape'][-1]:+.2f} | "
                        f"{m['coherence'].min():.2f} / {m['p_coherence']:.2f} | {wv.speed:+.1f} m/s | "
                        f"{wv.growth:.2f} / {ws.growth:.2f} /m | {np.degrees(wv.phase_residual):.0f}° | "
                        f"{min(mv.coherence.min(), ms.coherence.min()):.2f} | {m['k']:.2f} | "
                        + (f"{theory.wensrich_exponent(2 * R_WALL, m['mu'], m['k']):.2f} /m | " if m['k'] > 0 and m['mu'] > 0 else "– | ")
                        + (f"{m['spread']:.0f}° / {m['emerging']:.2f} |" if np.isfinite(m["spread"]) else "– (no points there) |"))
        mu_scene = load_scene(SCENE).wall.mu
        rows += ["", f"Eq. 5-1's growth for the bin (D {2 * R_WALL:g} m, the scene's μ {mu_scene:g}, k = ν/(1 − ν) = "
                 f"{k_fill:.2f}): {theory.wensrich_exponent(2 * R_WALL, mu_scene, k_fill):.2f} /m."]
        (ROOT / "fast_mode.md").write_text("\n".join(rows) + "\n")
        print("\n".join(rows))
        from scipy.special import j0

        fig, ax = plt.subplots(1, 3, figsize=(17, 4.2))
        x = np.linspace(0.0, 1.0, 101)
        ax[0].plot(x, j0(theory.J1_FIRST_ROOT * x), "k-", label=f"shear mode, sliding wall: J0(3.83 r/R), {f_slip:.1f} Hz")
        ax[0].plot(x, j0(theory.J0_FIRST_ROOT * x), "k--", label=f"shear mode, stuck wall: J0(2.40 r/R), {f_stick:.1f} Hz")
        # the figure: the solids with τ 1-2 ms, where the faster oscillation is what remains (all, if none ran)
        drawn = {n: r for n, r in modes.items() if "vp1" in n or "vp2" in n} or modes
        for k, (n, r) in enumerate(drawn.items()):
            m = r["mode"]
            ax[0].plot(m["r"] / R_WALL, m["shape"], marker="o", color=f"C{k}", label=f"{r['label']}: {m['f']:.1f} Hz")
            mv = m["up"]["v_z"][1]
            ax[1].plot(m["z"], np.degrees(np.unwrap(np.angle(mv.ratio[::-1]))[::-1]), marker="o", color=f"C{k}",
                       label=f"{r['label']}: {m['up']['v_z'][0].speed:+.1f} m/s")
            ax[2].semilogy(m["z"], np.abs(mv.ratio), marker="o", color=f"C{k}",
                           label=f"{r['label']}: {m['up']['v_z'][0].growth:.2f} /m")
        ax[0].axhline(0.0, color="0.7", lw=0.5)
        ax[0].set(xlabel="r / R", ylabel="v_z in the band, in phase with the axis", title="across the section at 3.6 m")
        for a in ax[1:]:
            a.axvline(0.687, color="0.6", lw=0.8, ls=":")  # the transition
        ax[1].set(xlabel="z (m): r 0.05 m in the hopper (left of the dotted transition), 0.1 m in the bin",
                  ylabel="phase of v_z against 3.6 m (°)", title=f"the phase falls as the wave climbs (c_p {c_p:.1f} m/s)")
        ax[2].set(xlabel="z (m), as left", ylabel="|v_z| against 3.6 m", title="and the wave grows as it climbs")
        for a in ax:
            a.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(ROOT / "fast_mode.png", dpi=110)
# -

# ## The solid with a relaxation time
#
# Against the element size: the std at 3.6 m, its 8-Hz band (4-15 Hz) and the 99th percentile
# at 4.4 m for the rate-independent solid and τ 0.25, 1 and 2 ms; and the pulses' growth, 1-s
# window by window, on the three meshes for τ 2 ms (whose h/4 run stopped at 4.3 s).

# +
SOLIDS = {"rate-independent": ("mu067", "h2", "h4"), "τ 0.25 ms": ("mu067_vp025", "mu067_vp025_h2", "mu067_vp025_h4"),
          "τ 1 ms": ("mu067_vp1", "mu067_vp1_h2", "mu067_vp1_h4"), "τ 2 ms": ("mu067_vp2", "mu067_vp2_h2", "mu067_vp2_h4")}
if comm.rank == 0 and any(n in R for names in list(SOLIDS.values())[1:] for n in names):
    fig, ax = plt.subplots(1, 4, figsize=(17, 4))
    measures = ((lambda r: r["z1"]["std"], "std of p_n at 3.6 m (kPa)"),
                (lambda r: r["bands"][0], "its 4-15 Hz part (kPa)"),
                (lambda r: r["z2"]["p99"], "99th percentile at 4.4 m (kPa)"))
    for k, (label, names) in enumerate(SOLIDS.items()):
        done = [(h / 2**j, R[n]) for j, n in enumerate(names) if n in R and "failed" not in R[n] and "ended" not in R[n]["label"]]
        for a, (get, ylabel) in zip(ax, measures):
            if done:
                a.plot([d[0] for d in done], [get(d[1]) / 1e3 for d in done], marker="o", color=f"C{k}", label=label)
            a.set(xscale="log", xlabel="element size h (m)", ylabel=ylabel)
    for j, n in enumerate(SOLIDS["τ 2 ms"]):
        if n in R and "failed" not in R[n]:
            g = np.array(R[n]["growth"]) / 1e3
            ax[3].plot(np.arange(len(g)) + 0.5, g, marker="o", color=plt.cm.viridis(j / 2), label=R[n]["label"])
    ax[3].set(xlabel="time after the opening (s)", ylabel="std of p_n at 3.6 m in 1-s windows (kPa)",
              title="τ 2 ms on three meshes")
    ax[0].set_title(f"window {window[0]:g}-{window[1]:g} s after the opening")
    for a in ax:
        if a.get_legend_handles_labels()[0]:
            a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(ROOT / "relaxation_time.png", dpi=110)
# -
