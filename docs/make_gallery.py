"""Remake README's gallery (docs/img/*.png) from a run of the project itself.

    mpirun -n 2 python docs/make_gallery.py            # runs the quick ch. 4 hopper (~3 min), then copies
    mpirun -n 2 python docs/make_gallery.py --reuse    # copies from results/hopper_ch4_quick as it is

The run is the quick variant of the main demo (`./bootstrap demo`): the ch. 4 hopper on a 0.04-m
mesh, filled in ten layers, stored and discharged for 5 s; `silo report` draws the figures and
four of them become the gallery: the filled hopper's wall pressure with EN 1991-4 and Walker, the
discharge animated (speed with the material points, and q/p, over the whole silo), the spectra at
the wall stations, and the mesh.
"""

import argparse
import shutil
from pathlib import Path

from mpi4py import MPI

import silo_dolfinx  # noqa: F401  (imports dolfinx_solver first where it exists)
from silo_dolfinx.report import make_report
from silo_dolfinx.scene import load_scene
from silo_dolfinx.simulation import run

ROOT = Path(__file__).resolve().parents[1]
OUT = Path("results") / "hopper_ch4_quick"
GALLERY = {"wall_pressure.png": "wall_pressure_store.png", "discharge.gif": "discharge.gif",
           "spectrum.png": "spectra.png", "mesh.png": "mesh.png"}

ap = argparse.ArgumentParser()
ap.add_argument("--reuse", action="store_true", help="copy from the results already there")
args = ap.parse_args()
comm = MPI.COMM_WORLD
if not args.reuse:
    scene = load_scene(ROOT / "demos" / "scenes" / "hopper_ch4.toml",
                       ["discharge.duration=5.0", "geometry.element_size=0.04"])
    run(scene, OUT, comm)
comm.barrier()
if comm.rank == 0:
    make_report(OUT, movie=True)
    dest = ROOT / "docs" / "img"
    dest.mkdir(exist_ok=True)
    for name, source in GALLERY.items():
        shutil.copyfile(OUT / source, dest / name)
        print(f"{dest / name} <- {OUT / source}")
