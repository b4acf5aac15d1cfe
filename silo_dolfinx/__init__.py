"""silo_dolfinx: granular flow and dynamic wall pressure in silos on FEniCSx/DOLFINx.

Importing the package imports ``dolfinx_solver`` first when it is installed: that wheel
must load ``mpi4py.MPI`` before any DOLFINx/PETSc binding (see its documentation).
The scene and geometry layers import DOLFINx lazily, so ``silo check`` stays fast.
"""

from __future__ import annotations

try:  # MPI ordering for the dolfinx-solver-real wheel; absent on conda/distro installs.
    import dolfinx_solver  # noqa: F401
except ImportError:  # pragma: no cover - depends on the install
    pass

__version__ = "0.1.0"

from silo_dolfinx.scene import Scene, SceneError, load_scene  # noqa: E402

__all__ = ["Scene", "SceneError", "load_scene", "__version__"]
