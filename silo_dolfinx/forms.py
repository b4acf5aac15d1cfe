"""All UFL in one place: axisymmetric kinematics, internal force, lumped mass, tractions.

Coordinates are (r, z) with the axis at r = 0; the third direction is the hoop direction θ.
Stress and strain are stored as 4-vectors in the order (rr, zz, θθ, rz) with engineering
shear for strain (γ_rz = 2 ε_rz). Every integral carries the 2π r of a body of revolution,
so forces are in N, masses in kg and energies in J for the full 360°.

Everything is compiled once, before the time loop:

* the **quadrature** of the internal force: 2 × 2 Gauss points (``integration = "full"``) or
  one point per cell (``"reduced"``, the thesis' CAX4R; the hourglass modes it cannot see
  are resisted in :mod:`silo_dolfinx.kernels`). The velocity gradient at these points is a
  compiled kernel fed by the geometry and the dofmap (:func:`silo_dolfinx.kernels.gradients_q1`,
  checked against the UFL expression of the same quantity in the tests). The one-point cell
  is Flanagan & Belytschko's **uniform strain** cell: its strain rate is the mean over the
  cell's exact volume of revolution (:func:`silo_dolfinx.kernels.mean_gradients_q1`), σ̃ and ρ
  are cell constants (DG0 coefficients, packed as one point), and the force σ̃ : ∫ B_a 2πr dx
  and the mass ρ ∫ N_a 2πr dx are integrated exactly (2 × 2 points) - its work conjugate, so
  the pressure resists exactly the volume change the density (and the ALE remap) sees;
* the **internal force** ``f_int(w) = ∫ σ̃ : ε_axi(w) 2π r dx`` whose only coefficient is
  σ̃ at the quadrature points, supplied pre-packed (the stress kernels write it directly in
  DOLFINx's packed-coefficient layout, ``[cell, q·4 + component]``);
* the **lumped mass** (row sum of the consistent mass, ``∫ ρ N_a 2π r dx``, at the same
  quadrature points as the force: a geostatic state is then a discrete equilibrium);
* the **top surcharge** ``-∫ p n·w 2π r ds`` and the wall-node **tributary areas**
  ``∫ N_a 2π r ds``.

Integrals run over an explicit list of owned cells (the active layers), so inactive cells
cost nothing; changing the list rebuilds only the cheap DOLFINx Form object, not the code.
A moved ``mesh.geometry.x`` is seen by every compiled form without recompiling.
"""

from __future__ import annotations

import math

import basix
import basix.ufl
import numpy as np
import ufl
from dolfinx import fem

QUADRATURE_DEGREE = 2  # 2 × 2 Gauss points on Q1 quadrilaterals
INTEGRATION = {"full": 2, "reduced": 1}  # quadrature degree: 2 × 2 stress points, or one per cell
TWO_PI = 2.0 * math.pi


def jit_options() -> dict:
    """Compiler flags for the hot forms: -O3 -march=native with fast math but IEEE NaN/Inf
    kept (-fno-finite-math-only), so a blow-up still shows as NaN. This makes the internal-
    force kernel ~2.8× faster on these machines (benchmarks/step_cost.py). Kernels built for
    one CPU go to a cache directory of that CPU, so a shared home on a mixed cluster is safe.
    SILO_JIT_NATIVE=0 turns it off."""
    import hashlib
    import os
    import platform
    from pathlib import Path

    if os.environ.get("SILO_JIT_NATIVE", "1") == "0":
        return {}
    cpu = platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu += next((line for line in f if line.startswith(("model name", "flags"))), "")
    except OSError:  # pragma: no cover - not Linux
        pass
    tag = hashlib.sha1(cpu.encode()).hexdigest()[:10]
    return {"cffi_extra_compile_args": ["-O3", "-march=native", "-ffast-math", "-fno-finite-math-only"],
            "cache_dir": str(Path.home() / ".cache" / "fenics" / f"silo-native-{tag}")}


def strain_axi(w):
    """Axisymmetric strain of a vector field as (rr, zz, θθ, γ_rz)."""
    r = ufl.SpatialCoordinate(w.ufl_function_space().mesh)[0]
    return (w[0].dx(0), w[1].dx(1), w[0] / r, w[0].dx(1) + w[1].dx(0))


class AxisymmetricForms:
    """Compiled forms and expressions on one mesh (built once, reused every step)."""

    def __init__(self, mesh, integration: str = "full"):
        self.mesh = mesh
        self.integration = integration
        degree = INTEGRATION[integration]
        self.V = fem.functionspace(mesh, ("Lagrange", 1, (2,)))
        self.S = fem.functionspace(mesh, ("Lagrange", 1))  # scalar nodal quantities (lumped mass)
        if not np.array_equal(self.S.dofmap.list, self.V.dofmap.list):  # DOLFINx numbers both alike
            raise RuntimeError("the scalar and vector P1 dofmaps differ: nodal masses would be misplaced")
        cell = mesh.basix_cell()
        points, weights = basix.make_quadrature(cell, degree)
        self.points = np.ascontiguousarray(points, dtype=np.float64)
        self.weights = np.ascontiguousarray(weights, dtype=np.float64)
        self.nq = self.points.shape[0]
        if self.nq == 1:  # the uniform-strain cell: σ̃ and ρ constant on it, its integrals exact
            Q4, Q1 = (fem.functionspace(mesh, ("DG", 0, (4,))), fem.functionspace(mesh, ("DG", 0)))
            degree = QUADRATURE_DEGREE
        else:
            Q4, Q1 = (fem.functionspace(mesh, basix.ufl.quadrature_element(cell, value_shape=shape, degree=degree))
                      for shape in ((4,), ()))
        self.Q4 = Q4
        self._density = fem.Function(Q1, name="density")  # for the lumped mass
        self.velocity = fem.Function(self.V, name="velocity")
        self._stress = fem.Function(self.Q4, name="force_stress")  # placeholder: values are pre-packed
        self._w = ufl.TestFunction(self.V)
        x = ufl.SpatialCoordinate(mesh)
        self.r = x[0]
        self._metadata = {"quadrature_degree": degree}
        self._facet_metadata = {"quadrature_degree": QUADRATURE_DEGREE}  # tractions, tributary areas: exact

    def velocity_gradient_expression(self) -> fem.Expression:
        """The UFL expression of what :func:`silo_dolfinx.kernels.gradients_q1` computes at the
        quadrature points (∂v_r/∂r, ∂v_r/∂z, ∂v_z/∂r, ∂v_z/∂z, v_r/r, r·|det J|): its reference."""
        v = self.velocity
        J = ufl.JacobianDeterminant(self.mesh)
        return fem.Expression(ufl.as_vector([v[0].dx(0), v[0].dx(1), v[1].dx(0), v[1].dx(1), v[0] / self.r,
                                             self.r * abs(J)]), self.points)

    # ------------------------------------------------------------------ forms on a cell list
    def _dx(self, cells: np.ndarray):
        return ufl.Measure("dx", domain=self.mesh, subdomain_data=[(1, np.asarray(cells, np.int32))],
                           metadata=self._metadata)(1)

    def internal_force(self, cells: np.ndarray) -> tuple[fem.Form, tuple]:
        """Form for ∫ σ̃ : ε_axi(w) 2π r dx over ``cells``, and its packed-coefficient key."""
        e = strain_axi(self._w)
        s = self._stress
        form = fem.form(sum(s[i] * e[i] for i in range(4)) * TWO_PI * self.r * self._dx(cells),
                        jit_options=jit_options())
        (key,) = fem.pack_coefficients(form).keys()
        return form, key

    def mass_form(self, cells: np.ndarray) -> tuple[fem.Form, tuple]:
        """Form for the row-sum lumped mass ∫ ρ N_a 2π r dx over ``cells`` on the scalar P1
        space (same node numbering as the velocity's blocks), with ρ at the quadrature points
        supplied pre-packed. Compiled like the internal force: the ALE rebuild assembles it
        after every remap."""
        form = fem.form(ufl.TestFunction(self.S) * self._density * TWO_PI * self.r * self._dx(cells),
                        jit_options=jit_options())
        (key,) = fem.pack_coefficients(form).keys()
        return form, key

    def lumped_mass(self, density_q: np.ndarray, cells: np.ndarray, form=None, out=None) -> np.ndarray:
        """Row-sum lumped mass per node (owned + ghost entries, ghosts accumulated).

        ``density_q`` is the density at the quadrature points, shape (len(cells), nq);
        ``form``, if given, is :meth:`mass_form` of ``cells`` (built once by the caller);
        ``out``, if given, a scalar ``la.Vector`` on the nodes to assemble into (no allocation:
        the ALE rebuild after every remap). Returns the nodal masses: a copy, or ``out.array``
        itself.
        """
        form, key = self.mass_form(cells) if form is None else form
        coeffs = {key: np.ascontiguousarray(density_q, dtype=np.float64)}
        if out is None:
            b = fem.assemble_vector(form, coeffs=coeffs)
        else:
            b = out
            b.array[:] = 0.0
            fem.assemble_vector(b.array, form, constants=np.zeros(0), coeffs=coeffs)
        b.scatter_reverse(_add())
        b.scatter_forward()
        return b.array if out is not None else b.array.copy()

    def surcharge_form(self, facet_tags, tag: int, pressure: fem.Constant) -> fem.Form:
        """Form for the nodal force of a normal pressure on the facets tagged ``tag``."""
        ds = ufl.Measure("ds", domain=self.mesh, subdomain_data=facet_tags, metadata=self._facet_metadata)
        n = ufl.FacetNormal(self.mesh)
        return fem.form(-pressure * ufl.inner(n, self._w) * TWO_PI * self.r * ds(tag))

    def tributary_area_form(self, facet_tags, tag: int) -> fem.Form:
        """Form whose vector holds ∫ N_a 2π r ds over facets ``tag`` (both components)."""
        ds = ufl.Measure("ds", domain=self.mesh, subdomain_data=facet_tags, metadata=self._facet_metadata)
        return fem.form(ufl.inner(self._w, ufl.as_vector([1.0, 1.0])) * TWO_PI * self.r * ds(tag))


def _add():
    from dolfinx import la

    return la.InsertMode.add
