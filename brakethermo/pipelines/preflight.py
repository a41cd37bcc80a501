"""The user's errors before any session is read, checked in one place: estimate,
identify-h, timing-check and batch validate their configuration files, output place and
overrides here, so a broken file is one line and exit 1 rather than a failure per
session (batch) or after minutes of work (estimate, identify-h)."""

from __future__ import annotations

from pathlib import Path


def preflight(
    *, tuning: Path | None = None, h_law: Path | None = None, aliases: Path | None = None,
    disc: str | None = None, out: Path | None = None, nodes: int | None = None,
) -> None:
    """Validate what a run was given: configuration files, the output place, overrides.

    Raises
    ------
    ConfigError
        A broken ``--tuning``, ``--h-law``, ``--aliases`` or ``--disc``, an output place
        that cannot be written, a ``--nodes`` out of range.
    """
    from brakethermo.io.aliases import load_aliases
    from brakethermo.pipelines.models import read_calibration
    from brakethermo.pipelines.output_dir import check_output_dir
    from brakethermo.pipelines.tuning import check_overrides, load_tuning
    from brakethermo.thermal.disc import load_disc

    if out is not None:
        check_output_dir(out)
    if nodes is not None:
        check_overrides({"nodes": nodes}, "--nodes:")
    load_tuning(tuning)
    load_aliases(aliases)
    if h_law is not None:
        read_calibration(h_law)
    if disc is not None:
        load_disc(disc)
