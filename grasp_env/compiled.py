"""Where the compiled code is cached: numba's on-disk cache of :mod:`grasp_env.solvers`,
:mod:`grasp_env.sim` and :mod:`grasp_env.kernel`, whose functions call each other across
modules and packages.

The same source runs interpreted under ``NUMBA_DISABLE_JIT=1``, which is how to debug it.
Compiled code is cached on disk (numba's ``cache=True``) where a cache folder can be written
(:data:`CACHE`); elsewhere (a read-only install with no writable home or
``NUMBA_CACHE_DIR``) it is compiled in memory in each process.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from numba.core import caching

#: The packages whose modules hold compiled functions.
PACKAGES = ("solvers", "sim", "kernel")


def drop_stale_cache(sources: list[Path], cache: Path | None) -> bool:
    """Clear numba's on-disk cache ``cache`` when the compiled code's ``sources`` changed.

    numba checks a cached function against the file that defines it only, but these
    functions call each other across modules: after an edit of one module, cached callers
    would keep its old code. So the cache is stamped with a digest of all the sources and
    cleared when that changes. Without a cache (None), or where it cannot be written, nothing
    happens. Returns whether a stale cache was cleared.
    """
    if cache is None:
        return False
    digest = hashlib.sha256(b"".join(p.read_bytes() for p in sources)).hexdigest()
    stamp = cache / "kernel_sources.sha256"
    try:
        if stamp.read_text() == digest:
            return False
    except OSError:
        pass
    try:
        cache.mkdir(parents=True, exist_ok=True)
        stale = [f for pattern in ("*.nbi", "*.nbc") for f in cache.glob(pattern)]
        for f in stale:
            f.unlink(missing_ok=True)
        stamp.write_text(digest)
    except OSError:
        return False
    return bool(stale)


def cache_folder(source: Path) -> Path | None:
    """The folder numba caches the functions of the file ``source`` in: the first of its own
    locators (``NUMBA_CACHE_DIR``, the ``__pycache__`` beside the file, the user's cache
    folder) that can be written; None when none can."""

    def probe() -> None:
        """A function of ``source``, as numba's locators see one."""

    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl  # renamed in numba 0.5x
    for locator in impl._locator_classes:
        found = locator.from_function(probe, str(source))
        if found is not None:
            return Path(found.get_cache_path())
    return None


_ROOT = Path(__file__).parent
#: Where each package's compiled code is cached on disk (None where no folder can be
#: written).
CACHE_FOLDERS = {name: cache_folder(_ROOT / name / "__init__.py") for name in PACKAGES}
#: Whether the compiled code is cached on disk (numba's ``cache=``).
CACHE = all(folder is not None for folder in CACHE_FOLDERS.values())

_SOURCES = sorted(p for name in PACKAGES for p in (_ROOT / name).glob("*.py"))
for _folder in CACHE_FOLDERS.values():
    drop_stale_cache(_SOURCES, _folder)
