"""Build hook: an editable install compiles the numba kernels once, at install.

numba caches each compiled kernel beside its source, keyed by the source file's stamp. An
editable install runs the package from this tree, so kernels compiled here, now, are the
ones every later run loads: the first run after ``pip install -e .`` costs what later runs
do (``brakethermo/cli/warmup.py`` says how). A wheel installs copies with new stamps, so
there the first run of each command compiles (``python -m brakethermo.cli.warmup`` after
the install does it ahead). Never fails the build: a kernel not compiled here compiles on
first use. ``BRAKETHERMO_NO_WARMUP=1`` skips it.
"""

from __future__ import annotations

import os
import subprocess
import sys
from typing import Any

from hatchling.builders.hooks.plugin.interface import BuildHookInterface


class WarmKernels(BuildHookInterface):
    """Runs ``python -m brakethermo.cli.warmup`` from the source tree after an editable build."""

    PLUGIN_NAME = "custom"

    def finalize(self, version: str, build_data: dict[str, Any], artifact_path: str) -> None:
        if version != "editable" or os.environ.get("BRAKETHERMO_NO_WARMUP"):
            return
        env = {**os.environ,
               "PYTHONPATH": os.pathsep.join(filter(None, (self.root,
                                                           os.environ.get("PYTHONPATH"))))}
        self.app.display_info("brakethermo: compiling the kernels once (about a minute)")
        try:
            subprocess.run([sys.executable, "-m", "brakethermo.cli.warmup"], cwd=self.root,
                           env=env, timeout=1200, check=False)
        except (OSError, subprocess.SubprocessError) as exc:
            self.app.display_warning(f"brakethermo: kernels not compiled at install ({exc});"
                                     " each command compiles its own on first use")
