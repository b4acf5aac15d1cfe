"""Numba's on-disk cache and kernels that call across files (silo_dolfinx/_jit_cache.py).

Numba judges a cached kernel fresh by its own file: a kernel calling a function of another
file keeps its old machine code when only that file changes. The package-wide stamp must
recompile it. Shown on a two-file toy package in fresh processes (as a ``git pull`` in an
editable install would meet it), with stock numba beside it so that the test shows the
hazard is real (if numba one day tracks such changes itself, the stock assertion says so and
``_jit_cache`` can go)."""

import ast
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from silo_dolfinx import _jit_cache

PKG = Path(__file__).resolve().parents[1] / "silo_dolfinx"
pytestmark = pytest.mark.serial  # subprocesses and files: nothing parallel about it


def _toy(root: Path, increment: int) -> None:
    pkg = root / "toy"
    pkg.mkdir(exist_ok=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text(textwrap.dedent("""
        import numba
        from toy.b import g

        @numba.njit(cache=True)
        def f(x):
            return g(x)
    """))
    (pkg / "b.py").write_text(textwrap.dedent(f"""
        import numba

        @numba.njit(cache=True)
        def g(x):
            return x + {increment}
    """))


def _run(root: Path, stamped: bool) -> int:
    install = f"from silo_dolfinx import _jit_cache; _jit_cache.install({str(root / 'toy')!r}); " if stamped else ""
    code = f"import sys; sys.path.insert(0, {str(root)!r}); {install}from toy.a import f; print(f(1))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return int(out.stdout.split()[-1])


@pytest.mark.parametrize("stamped", [False, True], ids=["stock numba", "package stamp"])
def test_a_change_in_a_callee_file_recompiles_the_caller(tmp_path, stamped):
    _toy(tmp_path, 1)
    assert _run(tmp_path, stamped) == 2  # compiled and cached
    assert _run(tmp_path, stamped) == 2  # from the cache
    _toy(tmp_path, 2)  # only the callee's file changes
    if stamped:
        assert _run(tmp_path, stamped) == 3, "the cached caller was not recompiled"
    else:
        assert _run(tmp_path, stamped) == 2, "numba now tracks cross-file changes itself: _jit_cache can go"


def test_the_stamp_follows_content_not_touch(tmp_path):
    (tmp_path / "k.py").write_text("import numba\nX = 1\n")
    (tmp_path / "other.py").write_text("X = 1\n")  # no numba: not part of the stamp
    stamp = _jit_cache.source_stamp.__wrapped__
    s0 = stamp(str(tmp_path))
    (tmp_path / "k.py").write_text("import numba\nX = 1\n")
    assert stamp(str(tmp_path)) == s0
    (tmp_path / "other.py").write_text("X = 2\n")
    assert stamp(str(tmp_path)) == s0
    (tmp_path / "k.py").write_text("import numba\nX = 2\n")
    assert stamp(str(tmp_path)) != s0


def test_every_module_takes_numba_from_the_stamped_import():
    """A module importing numba directly would decorate its kernels before the locators are
    in place if it were imported first."""
    direct = []
    for path in sorted(PKG.rglob("*.py")):
        if path.name == "_jit_cache.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import) and any(a.name.split(".")[0] == "numba" for a in node.names):
                direct.append(str(path.relative_to(PKG)))
            elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "numba":
                direct.append(str(path.relative_to(PKG)))
    assert not direct, f"import numba via 'from silo_dolfinx._jit_cache import numba' in {direct}"
