"""The compiled core's packaging: where its machine code is cached, and the fallback to
compiling in memory where no cache folder can be written (a read-only install)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import grasp_env.sim as sim


def test_cache_is_used_where_it_can_be_written(tmp_path: Path) -> None:
    """The package's own folder is writable here, and any folder numba can write to
    counts."""
    assert sim.cache_writable(Path(sim.__file__))
    module = tmp_path / "module.py"
    module.write_text("")
    assert sim.cache_writable(module)


def test_no_writable_cache_folder_means_compiling_in_memory() -> None:
    """A source file whose folder, user cache folder and ``NUMBA_CACHE_DIR`` cannot be
    written (paths under /proc, which not even root can create folders in): no cache, so
    the kernels are compiled in memory rather than failing at import as numba's
    ``cache=True`` does."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["XDG_CACHE_HOME"] = "/proc/1/no-cache"  # numba's user-wide cache folder
    env["HOME"] = "/proc/1/no-home"
    code = (
        "from pathlib import Path; import grasp_env.sim as sim; "
        "print(sim.cache_writable(Path('/proc/1/no-package/module.py')))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "False"
