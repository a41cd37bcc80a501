"""What a rig run carries from a diagnosis: the rig commands' ``--with-effect``.

``diagnose`` on a rig session with the output's sensor fits the departures of the trained
relation (or datasheet law) that its estimator trusts (:mod:`brakethermo.models.
rig_effects`); the rig's estimator then runs on the changed relation, on that session or
on others of the same rig that lack the sensor. Four sources:

- ``none`` — the relation as trained (or the datasheet's);
- ``NAME=VALUE[,NAME=VALUE]`` — one-parameter effects, values as the diagnosis prints them;
- a ``diagnosis.json`` of ``diagnose`` on a session of the same rig;
- ``auto`` — diagnose the session itself first (it needs the sensor).

From a diagnosis its verdict is carried: alone, or the first of a set the data cannot
tell apart (the simplest, else the best; the summary names the set); a verdict of
``none`` carries nothing.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from brakethermo.errors import ConfigError, DataError
from brakethermo.io.session import Session
from brakethermo.models.rig_effects import ROLLER_EFFECTS, RigContext, RigEffect
from brakethermo.models.roller_rig import CreepEffects

Carried = dict[str, dict[str, float]]  # effect name -> its parameters


def carried(text: str, registry: Mapping[str, RigEffect], rig: str,
            diagnose: Callable[[], dict[str, Any]]) -> tuple[Carried, dict[str, Any] | None]:
    """The effects a run carries and the summary's ``with_effect`` fact (None for none).

    Parameters
    ----------
    text : str — the ``--with-effect`` value (module docstring).
    registry : the rig's candidate effects.
    rig : str — the rig's name in ``diagnosis.json`` (``roller-rig``, ``ebooster``...).
    diagnose : callable — runs ``diagnose`` on the session and returns its summary
        (for ``auto``).
    """
    value = text.strip()
    if value.lower() in ("", "none"):
        return {}, None
    if value.lower() == "auto":
        try:
            found = diagnose()
        except DataError as exc:
            raise ConfigError(
                f"--with-effect auto diagnoses the session first, and cannot: {exc}. Pass the"
                " diagnosis.json of a session of this rig that logs it, or NAME=VALUE"
            ) from None
        return _from_diagnosis(found, registry, "auto (diagnose on this session)")
    if value.lower().endswith(".json"):
        return _from_diagnosis(_read_diagnosis(Path(value), rig), registry, value)
    return _from_pairs(value, registry)


def _read_diagnosis(path: Path, rig: str) -> dict[str, Any]:
    try:
        summary = json.loads(path.read_text())
    except FileNotFoundError:
        raise ConfigError(f"--with-effect {path}: no such file (a diagnosis.json of"
                          f" brakethermo diagnose on a session of the {rig} rig)") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ConfigError(f"--with-effect {path}: not a readable diagnosis.json ({exc})"
                          ) from None
    if not isinstance(summary, dict):
        raise ConfigError(f"--with-effect {path}: not a diagnosis.json (a JSON object with"
                          " 'rig', 'verdict' and 'effects', as brakethermo diagnose writes)")
    if summary.get("rig") != rig:
        raise ConfigError(f"--with-effect {path}: the diagnosis of a"
                          f" {summary.get('rig') or 'disc'} session, not of this rig ({rig});"
                          " run brakethermo diagnose on a session of this rig with the sensor"
                          " its diagnosis needs")
    return summary


def _from_diagnosis(summary: dict[str, Any], registry: Mapping[str, RigEffect], source: str
                    ) -> tuple[Carried, dict[str, Any]]:
    verdict = summary.get("verdict", "none")
    chosen = list(summary.get("verdict_set") or [])
    fact: dict[str, Any] = {"source": source, "verdict": verdict, "verdict_set": chosen,
                            "session": summary.get("session"), "effects": {}}
    if verdict == "none" or not chosen:
        fact["note"] = "the diagnosis found no effect worth modelling: nothing carried"
        return {}, fact
    if len(chosen) > 1:
        # the verdict engine leads a set with its simplest member (fewest parameters),
        # else its best: the explanation to carry until a session separates them
        fact["note"] = (f"the diagnosis cannot tell {', '.join(chosen)} apart; its verdict,"
                        f" {verdict}, is carried (its next steps say what would separate"
                        " them)")
    entry = next((e for e in summary.get("effects") or [] if isinstance(e, dict)
                  and e.get("name") == verdict), None)
    if entry is None or verdict not in registry:
        raise ConfigError(f"--with-effect {source}: its verdict {verdict!r} is not an effect"
                          " of this rig with fitted parameters")
    params = _numbers(entry.get("params"), registry[verdict], source)
    fact["effects"] = {verdict: params}
    return {verdict: params}, fact


def _numbers(params: Any, effect: RigEffect, source: str) -> dict[str, float]:
    """The effect's parameters from a diagnosis.json, each a finite number."""
    names = set(effect.params)
    if not isinstance(params, dict) or set(params) != names:
        raise ConfigError(f"--with-effect {source}: {effect.name} needs the parameters"
                          f" {', '.join(effect.params)}, the file gives {params!r}")
    out = {}
    for k, v in params.items():
        try:
            out[k] = float(v)
        except (TypeError, ValueError):
            out[k] = math.nan
        if not math.isfinite(out[k]):
            raise ConfigError(f"--with-effect {source}: {effect.name} {k} = {v!r} is not a"
                              " number")
    return out


def _from_pairs(text: str, registry: Mapping[str, RigEffect]
                ) -> tuple[Carried, dict[str, Any]]:
    chosen: Carried = {}
    single = [n for n, e in registry.items() if len(e.params) == 1]
    for item in (s.strip() for s in text.split(",") if s.strip()):
        name, sep, raw = item.partition("=")
        name = name.strip()
        if not sep or name not in single:
            raise ConfigError(
                f"--with-effect {item!r}: give NAME=VALUE with NAME one of"
                f" {', '.join(single)} (values as diagnose prints them), a diagnosis.json,"
                " 'auto' or 'none'")
        try:
            v = float(raw)
        except ValueError:
            v = math.nan
        if not math.isfinite(v):
            raise ConfigError(f"--with-effect {item!r}: {raw!r} is not a number")
        chosen[name] = {registry[name].params[0]: v}
    return chosen, {"source": "option", "effects": chosen}


def carried_prediction(registry: Mapping[str, RigEffect], chosen: Carried, ctx: RigContext
                       ) -> np.ndarray:
    """The trained relation under the one carried effect, on the session's context (the
    effect's own prediction, as ``diagnose`` fitted it); ConfigError outside its bounds."""
    (name, params), = chosen.items()
    effect = registry[name]
    theta = np.array([params[p] for p in effect.params])
    for p, v, lo, hi in zip(effect.params, theta, effect.lower, effect.upper, strict=True):
        if not lo <= v <= hi:
            raise ConfigError(f"--with-effect: {name} {p} = {v:g} is outside the range"
                              f" diagnose fits ({lo:g} to {hi:g})")
    return effect.predict(theta, ctx)


def creep_effects(text: str, session: Session, *, rig: str, creep_law: str,
                  aliases: str | Path | None) -> tuple[CreepEffects, dict[str, Any] | None]:
    """The roller rig's creep-curve effects (:class:`CreepEffects`) and their fact."""

    def diagnose() -> dict[str, Any]:
        from brakethermo.pipelines.diagnose.rig_roller import diagnose_roller_rig

        return diagnose_roller_rig(session, rig=rig, creep_law=creep_law,
                                   aliases=aliases).summary

    chosen, fact = carried(text, ROLLER_EFFECTS, "roller-rig", diagnose)
    fields = {p: v for params in chosen.values() for p, v in params.items()}
    try:
        return CreepEffects(**fields), fact
    except ConfigError as exc:
        raise ConfigError(f"--with-effect {fact and fact['source']}: {exc}") from None
