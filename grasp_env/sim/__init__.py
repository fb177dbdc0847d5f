"""The quasi-static simulator's compiled core (numba, plain arrays, no BLAS).

A whole hand move is one compiled call, :func:`grasp_env.sim.move.move_hand`, on the
scene's arrays (:class:`grasp_env.sim.model.Model`). Its parts live in modules named for
what they compute:

* :mod:`~grasp_env.sim.move`: the increment loop (plan, solve, check, locate, update);
* :mod:`~grasp_env.sim.motion`: the active set and least-motion twist (the LPs);
* :mod:`~grasp_env.sim.step`: pose solves, checks and event location for one active set;
* :mod:`~grasp_env.sim.fall`: constrained falls;
* :mod:`~grasp_env.sim.equilibrium`: whether contacts hold the object, and the forces;
* :mod:`~grasp_env.sim.hand`: the hand's motion (contact velocities, the support limit);
* :mod:`~grasp_env.sim.contact_sets`, :mod:`~grasp_env.sim.events`: contact sets and event
  codes;
* the kernels: :mod:`~grasp_env.sim.dense` (small linear algebra),
  :mod:`~grasp_env.sim.placement` (world geometry and contact gaps),
  :mod:`~grasp_env.sim.detection` (which vertex-edge pairs touch),
  :mod:`~grasp_env.sim.clearance` (vertex-in-body gaps, overlap),
  :mod:`~grasp_env.sim.pose` (Newton on a contact set), :mod:`~grasp_env.sim.consistency`
  (the violations a step checks), :mod:`~grasp_env.sim.least_norm` (least-norm twists) and
  :mod:`~grasp_env.sim.velocity_lp` (the velocity and force LPs).

The same source runs interpreted under ``NUMBA_DISABLE_JIT=1``, which is how to debug it.
Compiled code is cached on disk (numba's ``cache=True``) where a cache folder can be
written (:data:`CACHE`).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from numba.core import caching


def drop_stale_cache(package: Path, cache: Path | None) -> bool:
    """Clear numba's on-disk cache ``cache`` of the code in ``package`` when its sources
    changed.

    numba checks a cached function against the file that defines it only, but these
    functions call each other across modules: after an edit of one module, cached callers
    would keep its old code. So the cache is stamped with a digest of all the package's
    sources and cleared when that changes. Without a cache (None), or where it cannot be
    written, nothing happens. Returns whether a stale cache was cleared.
    """
    if cache is None:
        return False
    sources = b"".join(p.read_bytes() for p in sorted(package.glob("*.py")))
    digest = hashlib.sha256(sources).hexdigest()
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


#: Where the compiled code is cached on disk (the same folder for every module here), or
#: None where no cache folder can be written (a read-only install with no writable home or
#: ``NUMBA_CACHE_DIR``): it is then compiled in memory in each process.
CACHE_FOLDER = cache_folder(Path(__file__))
#: Whether the compiled code is cached on disk (numba's ``cache=``).
CACHE = CACHE_FOLDER is not None

drop_stale_cache(Path(__file__).parent, CACHE_FOLDER)
