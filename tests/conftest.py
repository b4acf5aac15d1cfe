"""Shared fixtures. The suite runs twice: serially, and under ``mpirun -n 2`` (tests marked
``serial`` are deselected there: each says why it is serial-only)."""

from pathlib import Path

import pytest

import silo_dolfinx  # noqa: F401  (imports dolfinx_solver first: MPI ordering)
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "demos" / "scenes"


@pytest.fixture
def comm():
    return MPI.COMM_WORLD


@pytest.fixture
def shared_tmp(tmp_path):
    """A temporary directory seen by every rank (rank 0's ``tmp_path``)."""
    return Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0))


ELASTIC = {"model": "elastic", "density": 1000.0, "youngs_modulus": 1.0e6, "poisson_ratio": 0.3}


def scene_dict(geometry: dict, **sections) -> dict:
    """A minimal valid scene around ``geometry`` (sections override the defaults)."""
    d = {"geometry": dict(geometry), "material": dict(ELASTIC), "wall": {"friction": "none"}}
    d.update({k: dict(v) for k, v in sections.items()})
    return d


def slow_noise(t, seed: int, cutoff: float = 0.5):
    """A random signal with nothing above ``cutoff`` Hz at the uniform times ``t``, mean 0 and
    RMS 1: what the < 1 Hz part of a wall-pressure record or of a shear zone's failing looks
    like, with no period for a correlation search to alias on."""
    import numpy as np

    from silo_dolfinx import analysis

    x = analysis.low_pass(t, np.random.default_rng(seed).standard_normal(len(t)), cutoff)
    return (x - x.mean()) / x.std()


def subprocess_env() -> dict:
    """This environment without the MPI launcher's variables, for a test that starts its own
    (possibly mpirun) subprocess from inside an MPI-initialised pytest."""
    import os

    return {k: v for k, v in os.environ.items() if not k.startswith(("PMI_", "PMIX_", "HYDRA_", "MPIR_", "OMPI_"))}
