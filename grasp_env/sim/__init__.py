"""The quasi-static simulator's compiled kernels.

Kernels (numba, plain arrays, no BLAS) live in modules named for what they compute:
:mod:`~grasp_env.sim.dense` (small linear algebra), :mod:`~grasp_env.sim.placement` (world
geometry and contact gaps), :mod:`~grasp_env.sim.detection` (which vertex-edge pairs touch),
:mod:`~grasp_env.sim.clearance` (vertex-in-body gaps, overlap), :mod:`~grasp_env.sim.pose`
(the object pose on a contact set), :mod:`~grasp_env.sim.consistency` (what a step checks),
:mod:`~grasp_env.sim.least_norm` (least-motion twists) and
:mod:`~grasp_env.sim.velocity_lp` (the velocity and force LPs).
"""

from __future__ import annotations

import hashlib
from pathlib import Path


def drop_stale_cache(package: Path) -> bool:
    """Clear numba's on-disk cache of the kernels in ``package`` when their sources changed.

    numba checks a cached kernel against the file that defines it only, but these kernels
    call each other across modules: after an edit of one module, cached callers would keep
    its old code. So the cache is stamped with a digest of all the package's sources and
    cleared when that changes. Where the cache cannot be written nothing happens (numba then
    compiles in memory). Returns whether a stale cache was cleared.
    """
    sources = b"".join(p.read_bytes() for p in sorted(package.glob("*.py")))
    digest = hashlib.sha256(sources).hexdigest()
    cache = package / "__pycache__"
    stamp = cache / "kernel_sources.sha256"
    try:
        if stamp.read_text() == digest:
            return False
    except OSError:
        pass
    try:
        cache.mkdir(exist_ok=True)
        stale = [f for pattern in ("*.nbi", "*.nbc") for f in cache.glob(pattern)]
        for f in stale:
            f.unlink(missing_ok=True)
        stamp.write_text(digest)
    except OSError:
        return False
    return bool(stale)


drop_stale_cache(Path(__file__).parent)
