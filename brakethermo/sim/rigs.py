"""Rig simulators reachable from ``brakethermo simulate --rig NAME --set KEY=VALUE``.

Each rig registers a config dataclass (its fields are the ``--set`` keys) and a
function that simulates and writes a session plus its truth file. The simulators
(numba kernels, scipy, pyarrow) are imported on first use: the CLI lists the rig names
in ``simulate --help`` and must start without them.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import typing
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from brakethermo.errors import ConfigError

if TYPE_CHECKING:
    from brakethermo.sim.ebooster import EboosterRigConfig
    from brakethermo.sim.emb import EmbSimConfig
    from brakethermo.sim.roller_rig import RollerRigSimConfig
    from brakethermo.sim.tyre_rig import TyreRigSimConfig


@dataclass(frozen=True)
class RigSimulator:
    """A rig's simulator: its config class and ``run(config, out, fmt) -> (session, truth)``.

    The config class is named (``module``, ``config_name``) and imported when first asked
    for. ``truth_facts(config)``, when given, adds the truth a user compares the pipeline
    with (e.g. a tyre's true peak) to the command's summary.
    """

    module: str
    config_name: str
    run: Callable[[Any, Path, str | None], tuple[Path, Path]]
    truth_facts: Callable[[Any], dict[str, Any]] | None = None

    @property
    def config(self) -> type:
        """The rig's config dataclass (imports its simulator module)."""
        return getattr(importlib.import_module(self.module), self.config_name)


def _roller_rig(cfg: RollerRigSimConfig, out: Path, fmt: str | None) -> tuple[Path, Path]:
    from brakethermo.sim.roller_rig import simulate_roller_rig, write_roller_rig_simulation

    return write_roller_rig_simulation(simulate_roller_rig(cfg), out, fmt)


def _ebooster(cfg: EboosterRigConfig, out: Path, fmt: str | None) -> tuple[Path, Path]:
    from brakethermo.sim.ebooster import write_ebooster_simulation

    return write_ebooster_simulation(cfg, out, fmt)


def _emb(cfg: EmbSimConfig, out: Path, fmt: str | None) -> tuple[Path, Path]:
    from brakethermo.sim.emb import simulate_emb_config, write_emb_simulation

    return write_emb_simulation(simulate_emb_config(cfg), out, fmt)


def _tyre(cfg: TyreRigSimConfig, out: Path, fmt: str | None) -> tuple[Path, Path]:
    from brakethermo.sim.tyre_rig import simulate_tyre_config, write_tyre_simulation

    return write_tyre_simulation(simulate_tyre_config(cfg), out, fmt)


def _tyre_peak(cfg: TyreRigSimConfig) -> dict[str, Any]:
    from brakethermo.sim.tyre_rig import tyre_curve

    mu_p, s_p = tyre_curve(cfg.tyre)[1]
    return {"peak_mu": float(mu_p), "peak_slip": float(s_p)}


RIG_SIMULATORS: dict[str, RigSimulator] = {
    "ebooster": RigSimulator("brakethermo.sim.ebooster", "EboosterRigConfig", _ebooster),
    "emb": RigSimulator("brakethermo.sim.emb", "EmbSimConfig", _emb),
    "roller-rig": RigSimulator("brakethermo.sim.roller_rig", "RollerRigSimConfig", _roller_rig),
    "tyre": RigSimulator("brakethermo.sim.tyre_rig", "TyreRigSimConfig", _tyre, _tyre_peak),
}


def _convert(text: str, kind: Any, key: str) -> Any:
    base = [a for a in typing.get_args(kind) if a is not type(None)] or [kind]
    target = base[0]
    if text.lower() in ("none", "null") and type(None) in typing.get_args(kind):
        return None
    try:
        if target is bool:
            if text.lower() in ("1", "true", "yes", "on"):
                return True
            if text.lower() in ("0", "false", "no", "off"):
                return False
            raise ValueError(text)
        value = target(text)
        if isinstance(value, float) and not math.isfinite(value):
            raise ValueError(text)
        return value
    except (TypeError, ValueError):
        expected = ("true or false (or 1/0, yes/no, on/off)" if target is bool else
                    f"a finite {getattr(target, '__name__', target)}")
        raise ConfigError(f"--set {key}={text}: expected {expected}") from None


def rig_name(rig: str) -> str:
    """The rig's name as ``--rig`` takes it (ConfigError listing the simulated rigs).

    Parameters
    ----------
    rig : str
        The name given.

    Returns
    -------
    str
        ``rig`` itself, one of :data:`RIG_SIMULATORS`.
    """
    if rig in RIG_SIMULATORS:
        return rig
    # the likely slips (roller_rig, Tyre) are named, not taken: the name is the
    # session's fact and the output's title, spelled one way
    near = rig.strip().lower().replace("_", "-").replace(" ", "-")
    hint = f" (did you mean '{near}'?)" if near in RIG_SIMULATORS else ""
    raise ConfigError(f"--rig {rig}: unknown rig{hint}; simulated rigs:"
                      f" {', '.join(RIG_SIMULATORS)}")


def rig_settings(rig: str, settings: Sequence[str], seed: int) -> dict[str, Any]:
    """The keyword arguments of the rig's config from ``KEY=VALUE`` settings (and the
    command's seed), each of its field's type (ConfigError: a key the config does not
    have, a value not of its type); the config's own checks of the values come after."""
    cls = RIG_SIMULATORS[rig_name(rig)].config
    hints = typing.get_type_hints(cls)
    fields = {f.name for f in dataclasses.fields(cls)}
    values: dict[str, Any] = {"seed": seed} if "seed" in fields else {}
    for item in settings:
        key, sep, text = item.partition("=")
        key = key.strip()
        if key == "seed":
            raise ConfigError(f"--set {item!r}: give the seed with --seed (the session's"
                              " facts and the title report that one)")
        if not sep or key not in fields - {"seed"}:
            raise ConfigError(
                f"--set {item!r}: expected KEY=VALUE with KEY one of"
                f" {', '.join(sorted(fields - {'seed'}))}"
            )
        values[key] = _convert(text.strip(), hints[key], key)
    return values
