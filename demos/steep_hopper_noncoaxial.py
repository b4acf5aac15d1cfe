# # Non-coaxial plasticity in a discharging steep hopper (thesis ch. 8.4)
#
# During discharge the principal stresses rotate; a coaxial Drucker–Prager solid cannot
# respond plastically to a stress rotation at constant stress ratio, a non-coaxial
# (yield-vertex) one can. The thesis finds that the extra plastic strain leaves the filling
# pressures unchanged and raises the discharge wall pressures, most at low heights.
#
# The same steep hopper (half-angle 10°, ~1,300 cells) is filled by a gravity ramp, stored
# and discharged freely with ALE, once with coaxial Drucker–Prager and once with the
# non-coaxial model (H_nc/G = 0.263, Table 8-2's ratio). Wall normal pressure profiles are
# compared at the end of filling and averaged over the discharge. As in every scene, the
# friction angle (35°) is a Mohr–Coulomb angle mapped to the cone matched in compression
# (β = 54.81°): the fill then stays elastic ("the solid does not yield until some time after
# discharge", as the thesis says); the trend of the discharge pressures is not reproduced
# with the data the thesis gives (docs/validation/ch8.md).
#
# Run it with
#
#     mpirun -n 2 python demos/steep_hopper_noncoaxial.py           # the two runs (~1 min)
#     mpirun -n 2 python demos/steep_hopper_noncoaxial.py --sweep   # and smaller H_nc (~2 more min)
#     mpirun -n 2 python demos/steep_hopper_noncoaxial.py --table-8-2   # and Table 8-2's material (~8 more min)
#     mpirun -n 2 python demos/steep_hopper_noncoaxial.py --flat-bottom # and the flat-bottomed silo (~12 more min)
#
# Results go to `results/steep_hopper_ch8_*`, `results/flat_bottom_ch8_*` and
# `results/steep_hopper_ch8.png`, `results/flat_bottom_ch8.png`.

# +
import argparse
from pathlib import Path

import numpy as np
from mpi4py import MPI

import silo_dolfinx  # noqa: F401  (imports dolfinx_solver first where it exists)
from silo_dolfinx.output import read_csv
from silo_dolfinx.scene import load_scene
from silo_dolfinx.simulation import run

HERE = Path(__file__).parent
OUT = Path("results")
comm = MPI.COMM_WORLD
CASES = ("steep_hopper_ch8_coaxial", "steep_hopper_ch8_noncoaxial")
ap = argparse.ArgumentParser()
ap.add_argument("--sweep", action="store_true", help="also run H_nc = 1e4 and 3e3 Pa (H_nc/G = 0.047, 0.014)")
ap.add_argument("--flat-bottom", dest="flat", action="store_true",
                help="also run the ch. 8.4 flat-bottomed silo pair (~12 min)")
ap.add_argument("--table-8-2", dest="table82", action="store_true",
                help="also run both with Table 8-2's material at its own moduli (G 3.8e7 Pa, H_nc 1e7 Pa)")
args = ap.parse_args()


def profile(path):
    """Wall profile (z, p_n) of a stage off the floor (a flat bottom's z = 0), sorted by height."""
    w = read_csv(path)
    off = w["z"] > 1e-3
    z, p = w["z"][off], w["p_n"][off]
    k = np.argsort(z)
    return z[k], p[k]


def discharge_mean(path, t_from):
    """Time-averaged p_n at each wall station over t ≥ t_from (eq. 4-9)."""
    h = read_csv(path)
    late = h["t"] >= t_from
    st = sorted(set(h["station"][late]))
    z = np.array([h["z"][late & (h["station"] == k)].mean() for k in st])
    p = np.array([h["p_n"][late & (h["station"] == k)].mean() for k in st])
    return z, p
# -

# Both runs: fill (gravity ramp 5 s), store 1 s, free discharge 3 s, with ALE. Stations every
# 0.25 m up the wall. Filling: the same within a few per cent (non-coaxiality only acts where
# the principal axes rotate while yielding). Discharge: averaged over t ≥ 1 s after opening.

# +
def oscillation(path, t_from):
    """Median over the stations in the lower 80 % of the wall of std(p_n)/mean(p_n) for
    t ≥ t_from: how strongly the wall pressures pulse in discharge."""
    h = read_csv(path)
    late = h["t"] >= t_from
    st = sorted(set(h["station"][late]))
    z = np.array([h["z"][late & (h["station"] == k)].mean() for k in st])
    p = [h["p_n"][late & (h["station"] == k)] for k in st]
    cv = np.array([x.std() / max(x.mean(), 1e-9) for x in p])
    return float(np.median(cv[z < 0.8 * z.max()]))


def run_pair(cases, stations):
    """Run a coaxial / non-coaxial scene pair; {name: (summary, t_open)}."""
    out = {}
    for name in cases:
        summary = run(load_scene(HERE / "scenes" / f"{name}.toml", stations), OUT / name, comm)
        out[name] = (summary, next(s["t_start"] for s in summary["stages"] if s["name"] == "discharge"))
    comm.barrier()
    return out


def compare(cases, results, figure, title):
    """Filling profiles and discharge means of a pair, drawn side by side and printed by
    station height; returns (filling: mean |Δp_n| / mean p_n, discharge means {name: (z, p)})."""
    if comm.rank != 0:
        return None, None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 5), sharey=True)
    fill, dis = {}, {}
    for name, style in zip(cases, ("k-", "r--")):
        fill[name] = profile(OUT / name / "wall_profile_fill.csv")
        dis[name] = discharge_mean(OUT / name / "wall_history.csv", results[name][1] + 1.0)
        a1.plot(fill[name][1] / 1e3, fill[name][0], style, label=name.split("_")[-1])
        a2.plot(dis[name][1] / 1e3, dis[name][0], style + "o", ms=3, label=name.split("_")[-1])
    a1.set_title(f"{title}: end of filling")
    a2.set_title("discharge, mean from 1 s after opening")
    for a in (a1, a2):
        a.set_xlabel("wall normal pressure p_n (kPa)")
        a.grid(alpha=0.3)
        a.legend()
    a1.set_ylabel("height above outlet z (m)")
    fig.tight_layout()
    fig.savefig(OUT / figure, dpi=130)

    co, nc = cases
    z_top = min(fill[co][0][-1], fill[nc][0][-1])
    zf = np.linspace(0.05 * z_top, 0.9 * z_top, 30)  # below the free surface, where p_n is not ~0
    pf_co = np.interp(zf, *fill[co])
    pf_nc = np.interp(zf, *fill[nc])
    fill_diff = float(np.mean(np.abs(pf_nc - pf_co)) / np.mean(pf_co))
    ratio = dis[nc][1] / np.maximum(dis[co][1], 1e-9)
    print(f"{title} filling: mean |Δp_n| / mean p_n = {100 * fill_diff:.2f} % (thesis: unchanged; bar 2 %)")
    print("discharge mean p_n, non-coaxial / coaxial, by station height:")
    for z, r, pc, pn in zip(dis[co][0], ratio, dis[co][1], dis[nc][1]):
        print(f"  z = {z:5.2f} m: {pc / 1e3:7.3f} kPa → {pn / 1e3:7.3f} kPa  ({r:5.3f})")
    print(f"mean over the stations: {np.mean(dis[nc][1]) / np.mean(dis[co][1]):.3f}")
    for name in cases:
        o = read_csv(OUT / name / "outlet.csv")
        late = o["t"] >= results[name][1] + 1.0
        osc = oscillation(OUT / name / "wall_history.csv", results[name][1] + 1.0)
        print(f"{name}: mass flow from 1 s after opening {np.mean(o['mass_flow_rate'][late]):.1f} kg/s; wall "
              f"pressure std/mean {osc:.2f} (median of the stations in the lower 80 % of the wall)")
    print(f"figure: {OUT / figure}")
    return fill_diff, dis


stations = [f"output.stations=[{', '.join(f'{z:.2f}' for z in np.arange(0.15, 2.5, 0.25))}]"]
results = run_pair(CASES, stations)
fill_diff, dis = compare(CASES, results, "steep_hopper_ch8.png", "steep hopper")
# -

# ## How much non-coaxiality does the thesis' trend need?
#
# The text gives no H_nc for the hopper (Yang et al. 2011). With `--sweep` the non-coaxial run
# is repeated with smaller moduli, i.e. a larger non-coaxial compliance 2G/(H_nc + 2G) for
# stress rotation at yield. The table gives the discharge ratio by station and, at the end of
# the run, the mass flow of the last 2 s, the lowest cell density, the largest equivalent
# plastic strain and the worst cell. Measured (2 ranks, 3 s discharge): H_nc/G = 0.263
# changes the discharge pressures by 1-2 % (slightly lower; also over an 8 s discharge);
# 0.047 lowers them by up to 6 % at the lowest station; 0.014 raises them by 4-20 % between
# 0.4 and 1.4 m (the thesis' trend, though not at the lowest station, 0.78) — but there the
# flow slows (28.7 against 37.5 kg/s) because the material at the outlet shears without end
# (ε̄p 17-18 against 3.6 coaxial) and, dilating at ψ = 10°, thins to 41-45 kg/m³; 0.005 (not run
# here) tears the outlet region apart. The thesis' trend comes with an outlet region that no
# granular solid would show.

# +
def end_state(name):
    """(mass flow of the last 2 s (kg/s), min cell density, max ε̄p, min scaled Jacobian)."""
    o = read_csv(OUT / name / "outlet.csv")
    w = float(np.mean(o["mass_flow_rate"][o["t"] >= o["t"][-1] - 2.0]))
    snap = np.load(sorted((OUT / name / "fields").glob("snapshot_*.npz"))[-1])
    sj = float(read_csv(OUT / name / "mesh_quality.csv")["min_scaled_jacobian"][-1])
    return w, float(snap["cell_density"].min()), float(snap["cell_eqps"].max()), sj


if args.sweep:
    G = 5.5e5 / (2 * 1.3)
    runs = [("coaxial", CASES[0], results[CASES[0]][0]), (f"{5.57e4 / G:.3f}", CASES[1], results[CASES[1]][0])]
    for H in (1.0e4, 3.0e3):
        name = f"steep_hopper_ch8_hnc_{H:.0e}"
        scene = load_scene(HERE / "scenes" / "steep_hopper_ch8_noncoaxial.toml",
                           stations + [f"material.noncoaxial_modulus={H}", f'title="{name}"'])
        runs.append((f"{H / G:.3f}", name, run(scene, OUT / name, comm)))
    comm.barrier()
    if comm.rank == 0:
        z, pc = dis[CASES[0]]
        print("discharge mean p_n / coaxial by station height (m); end state: W (kg/s), min ρ (kg/m³), "
              "max ε̄p, min scaled Jacobian")
        print("H_nc/G   " + " ".join(f"{zz:5.2f}" for zz in z) + "      W   min ρ  ε̄p    SJ")
        for label, name, summary in runs:
            t_open = next(s["t_start"] for s in summary["stages"] if s["name"] == "discharge")
            _, pn = discharge_mean(OUT / name / "wall_history.csv", t_open + 1.0)
            w, rho, eqps, sj = end_state(name)
            print(f"{label:8s} " + " ".join(f"{r:5.3f}" for r in pn / np.maximum(pc, 1e-9))
                  + f"   {w:5.1f} {rho:6.0f} {eqps:5.1f} {sj:5.3f}")
# -

# ## At the thesis' own moduli
#
# The scenes keep Table 8-2's *ratio* H_nc/G on the ch. 4 solid (E 5.5e5 Pa). With
# `--table-8-2` both runs are repeated with Table 8-2's material itself: ρ 1500 kg/m³,
# G 3.8e4 kPa (E 1.0e5 kPa of Table 8-1's case 1, so ν = 0.316), H_nc 1.0e4 kPa — 180 times
# stiffer, so an 11 times smaller Δt. At yield the non-coaxial term adds the plastic
# strain Δs_t/H_nc, Δs_t the deviatoric stress change tangential to the cone; in the hopper
# that change is of the order of the stress itself (ρ g h, 5–10 kPa), so the extra strain is
# ~1e-3 — comparable to the strains of the first moments after opening and negligible against
# the strains of flow. In simple shear (σ_y = 100 kPa) the same H_nc matters because the whole
# test lives at strains of a few per cent. Measured (2 ranks, 3 s discharge): the ratio is
# 0.999–1.000 by station over the whole discharge and 1.000 over the last 2 s (serially, with
# the scene's stations: 0.984–1.004 in the first 0.5 s after opening, 0.999–1.001 later).
# The thesis' trend is therefore not a property of the non-coaxial model at Table 8-2's
# moduli; it needs H_nc near the stress level (the sweep above).

# +
if args.table82:
    t82 = ["material.density=1500", "material.youngs_modulus=1.0e8", "material.poisson_ratio=0.316"]
    means = {}
    for name in CASES:
        extra = t82 + (["material.noncoaxial_modulus=1.0e7"] if name.endswith("noncoaxial") else [])
        scene = load_scene(HERE / "scenes" / f"{name}.toml", stations + extra + [f'title="{name}_table82"'])
        summary = run(scene, OUT / f"{name}_table82", comm)
        t_open = next(s["t_start"] for s in summary["stages"] if s["name"] == "discharge")
        means[name] = [discharge_mean(OUT / f"{name}_table82" / "wall_history.csv", t0)[1]
                       for t0 in (t_open, t_open + 1.0)]
    comm.barrier()
    if comm.rank == 0:
        co, nc = CASES
        z = discharge_mean(OUT / f"{co}_table82" / "wall_history.csv", 0.0)[0]
        print("Table 8-2 material: discharge mean p_n, non-coaxial / coaxial, whole discharge and last 2 s")
        for k, zz in enumerate(z):
            print(f"  z = {zz:5.2f} m: {means[nc][0][k] / means[co][0][k]:6.3f}  {means[nc][1][k] / means[co][1][k]:6.3f}")
# -

# ## The flat-bottomed silo (ch. 8.4)
#
# "The same procedure and material are employed" for a flat-bottomed silo of 2,000 cells,
# whose dimensions the text does not give (Fig. 8-8b). `flat_bottom_ch8_*.toml` take the
# Edinburgh silo of ch. 6 (D 0.7 m, fill 4 m) with the steep hopper's solid and wall, an outlet
# of radius 0.125 m (the steep hopper's 0.1 m arches on a flat floor) and 8,960 cells: at the
# thesis' 2,000 (five cells across the outlet radius) the coaxial discharge shears a vertical
# pipe one cell wide over the outlet edge and the loosened core inside it falls freely until the
# mesh fails (the scene's comment has the measurements). The thesis reports "an overall similarity" with the steep hopper, less
# influence at the lowest level (in the stagnant zone), smaller oscillations and a larger
# increase of wall pressure.

# +
if args.flat:
    FLAT = ("flat_bottom_ch8_coaxial", "flat_bottom_ch8_noncoaxial")
    flat_stations = [f"output.stations=[{', '.join(f'{z:.2f}' for z in np.arange(0.2, 3.9, 0.4))}]"]
    flat = run_pair(FLAT, flat_stations)
    compare(FLAT, flat, "flat_bottom_ch8.png", "flat-bottomed silo")
# -
