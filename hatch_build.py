"""Build hook: an editable install compiles the numba kernels once, at install.

numba caches a compiled kernel beside its source file and loads it only for that file,
with the numba version that wrote it. An editable install runs the package from this
tree, so kernels compiled here at install are the ones every later run loads: the first
run after ``pip install -e .`` costs what later runs do (``brakethermo/cli/warmup.py``
says how). The warm-up runs with the packages of the environment being installed into
when that environment can already import the package (a re-install: its own numba
writes the cache); in a fresh environment pip installs the dependencies after building,
so the warm-up then runs in the build environment, which gets the runtime dependencies
for it (``dependencies``; pip resolves both to the same versions). A wheel install puts
copies elsewhere, which this cache does not serve (see the README). Never fails the
build: a kernel not compiled here compiles on first use. ``BRAKETHERMO_NO_WARMUP=1``
skips it.
"""

from __future__ import annotations

import os
import subprocess
import sys
from typing import Any

from hatchling.builders.hooks.plugin.interface import BuildHookInterface

# pip's build isolation: variables that hide the target environment's packages
ISOLATION = ("PYTHONPATH", "PYTHONNOUSERSITE")


def _env(root: str, isolated: bool) -> dict[str, str]:
    """Environment for a child running the package from ``root``: pip's build environment
    (``isolated``) or the environment being installed into."""
    env = dict(os.environ) if isolated else {k: v for k, v in os.environ.items()
                                             if k not in ISOLATION}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, (root, env.get("PYTHONPATH"))))
    return env


def _target_can_run(root: str) -> bool:
    """Whether the environment being installed into already imports the package's CLI."""
    try:
        probe = subprocess.run([sys.executable, "-c", "import brakethermo.cli"], cwd=root,
                               env=_env(root, isolated=False), capture_output=True,
                               timeout=300, check=False)
    except (OSError, subprocess.SubprocessError):
        return False
    return probe.returncode == 0


class WarmKernels(BuildHookInterface):
    """Runs ``python -m brakethermo.cli.warmup`` from the source tree after an editable build."""

    PLUGIN_NAME = "custom"

    def dependencies(self) -> list[str]:
        # Asked before the build; hatchling does not say then whether it is an editable one.
        if os.environ.get("BRAKETHERMO_NO_WARMUP") or _target_can_run(self.root):
            return []
        return list(self.metadata.core.dependencies)

    def finalize(self, version: str, build_data: dict[str, Any], artifact_path: str) -> None:
        if version != "editable" or os.environ.get("BRAKETHERMO_NO_WARMUP"):
            return
        env = _env(self.root, isolated=not _target_can_run(self.root))
        self.app.display_info("brakethermo: compiling the kernels once (about a minute)")
        try:
            subprocess.run([sys.executable, "-m", "brakethermo.cli.warmup"], cwd=self.root,
                           env=env, timeout=1200, check=False)
        except (OSError, subprocess.SubprocessError) as exc:
            self.app.display_warning(f"brakethermo: kernels not compiled at install ({exc});"
                                     " each command compiles its own on first use")
