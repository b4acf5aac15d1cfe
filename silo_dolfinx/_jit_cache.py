"""Numba's on-disk cache, made safe for a package whose kernels call each other across files.

Every module of this package imports numba from here (``from silo_dolfinx._jit_cache import
numba``; tests/test_jit_cache.py checks it), so the locators below are in place before any
kernel is decorated.

Numba judges a cached kernel fresh by its own source file only: a kernel that calls (or
inlines) a function from another file, or reads a constant from one, keeps its old machine
code when only that other file changes (numba's documented limitation: "cache invalidation
fails to recognize changes in symbols defined in a different file"). Here that is the rule,
not the exception - the remap's kernels inline ``geometry.moments`` and read ``kernels.FAST``
and ``geometry.TWO_PI``; the materials share ``materials.base`` - so after a ``git pull`` or
an edit in an editable install (what ``./bootstrap`` makes) a run would silently use the old
code. The locators installed here give every kernel of this package one freshness stamp:
the content of all its numba-using sources, so any change to one recompiles them all
(~40 s, once). Where the cache lives is numba's choice as before (``NUMBA_CACHE_DIR`` if
set, else ``__pycache__`` beside the source, else the user's cache directory).
"""

from __future__ import annotations

import functools
import hashlib
import os
from pathlib import Path

__all__ = ["install", "numba", "source_stamp"]

PACKAGE = Path(__file__).resolve().parent


@functools.lru_cache(maxsize=None)
def source_stamp(root: str) -> str:
    """SHA-256 over the numba-using ``.py`` files under ``root`` (relative paths and contents,
    in sorted order): changes when any of them changes, not when one is merely touched."""
    h = hashlib.sha256()
    base = Path(root)
    for path in sorted(base.rglob("*.py")):
        data = path.read_bytes()
        if b"numba" in data:
            h.update(str(path.relative_to(base)).encode())
            h.update(b"\0")
            h.update(data)
    return h.hexdigest()


def _stamped(locator, root: str):
    """A subclass of numba's ``locator`` that serves only files under ``root``, with the
    package-wide stamp as the source stamp."""

    class Stamped(locator):
        def get_source_stamp(self):
            return ("silo_dolfinx package sources", source_stamp(root))

        @classmethod
        def from_function(cls, py_func, py_file):
            if not os.path.abspath(py_file).startswith(root + os.sep):
                return None
            return super().from_function(py_func, py_file)

    Stamped.__name__ = Stamped.__qualname__ = f"PackageStamped{locator.__name__.lstrip('_')}"
    return Stamped


def install(root: str | os.PathLike = PACKAGE) -> None:
    """Put the package-stamped locators first in numba's search (idempotent). Kernels
    decorated after this call (``cache=True``) use them; call it before importing any."""
    from numba.core import caching

    root = os.path.abspath(root)
    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl  # numba < 0.61: _CacheImpl
    if any(getattr(c, "_silo_root", None) == root for c in impl._locator_classes):
        return
    names = ("UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator")
    # (older numba spells them with a leading underscore)
    bases = [getattr(caching, n, None) or getattr(caching, "_" + n) for n in names]
    ours = [_stamped(b, root) for b in bases]
    for c in ours:
        c._silo_root = root
    impl._locator_classes = ours + list(impl._locator_classes)


import numba  # noqa: E402  (re-exported: the package's modules import it from here)

install()
