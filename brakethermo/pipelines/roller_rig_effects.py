"""What a roller-rig run carries from a diagnosis: ``roller-rig --with-effect``.

``diagnose`` on a roller-rig session (with the roller torque transducer) fits the creep
curve's departures from the datasheet's law (:data:`~brakethermo.models.rig_effects.
ROLLER_EFFECTS`); the rolling-radius filter then runs on the changed curve
(:class:`~brakethermo.models.roller_rig.CreepEffects`), on that session or on others of the
same wheel and rollers that lack the transducer. Four sources:

- ``none`` — the datasheet's law;
- ``NAME=VALUE[,NAME=VALUE]`` — the effects' parameters as the diagnosis prints them;
- a ``diagnosis.json`` of ``diagnose`` on a roller-rig session;
- ``auto`` — diagnose the session itself first (it needs the transducer).

From a diagnosis only a verdict that stands alone is carried: a verdict of ``none`` or a
set the data cannot tell apart carries nothing, and the summary says why.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from brakethermo.errors import ConfigError
from brakethermo.models.rig_effects import ROLLER_EFFECTS
from brakethermo.models.roller_rig import CreepEffects

RIG = "roller-rig"


def carried_effects(text: str, session: str | Path, *, rig: str, creep_law: str,
                    aliases: str | Path | None) -> tuple[CreepEffects, dict[str, Any] | None]:
    """The creep effects a run carries and the summary's ``with_effect`` (None for none).

    Parameters
    ----------
    text : str — the ``--with-effect`` value (module docstring).
    session : path — the session the run estimates (``auto`` diagnoses it).
    rig, creep_law, aliases — as the run's options, for ``auto``.
    """
    value = text.strip()
    if value.lower() in ("", "none"):
        return CreepEffects(), None
    if value.lower() == "auto":
        from brakethermo.pipelines.diagnose.rig_roller import diagnose_roller_rig

        found = diagnose_roller_rig(session, rig=rig, creep_law=creep_law, aliases=aliases)
        return _from_diagnosis(found.summary, "auto (diagnose on this session)")
    if value.lower().endswith(".json"):
        return _from_diagnosis(_read_diagnosis(Path(value)), value)
    return _from_pairs(value)


def _read_diagnosis(path: Path) -> dict[str, Any]:
    try:
        summary = json.loads(path.read_text())
    except FileNotFoundError:
        raise ConfigError(f"--with-effect {path}: no such file (a diagnosis.json of"
                          " brakethermo diagnose on a roller-rig session)") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ConfigError(f"--with-effect {path}: not a readable diagnosis.json ({exc})"
                          ) from None
    if not isinstance(summary, dict) or summary.get("rig") != RIG:
        found = summary.get("rig", "a disc") if isinstance(summary, dict) else "no"
        raise ConfigError(f"--with-effect {path}: a diagnosis of {found} session, not of a"
                          " roller-rig session; run brakethermo diagnose on a roller-rig"
                          " session with its roller torque transducer")
    return summary


def _from_diagnosis(summary: dict[str, Any], source: str
                    ) -> tuple[CreepEffects, dict[str, Any]]:
    verdict = summary.get("verdict", "none")
    chosen = list(summary.get("verdict_set") or [])
    fact: dict[str, Any] = {"source": source, "verdict": verdict, "verdict_set": chosen,
                            "session": summary.get("session"), "effects": {}}
    if verdict == "none" or not chosen:
        fact["note"] = "the diagnosis found no effect worth modelling: the datasheet's law"
        return CreepEffects(), fact
    if len(chosen) > 1:
        fact["note"] = (f"the diagnosis cannot tell {', '.join(chosen)} apart: nothing"
                        " carried (the datasheet's law); a session with traction up to"
                        " sliding separates them")
        return CreepEffects(), fact
    entry = next((e for e in summary.get("effects", []) if e.get("name") == verdict), None)
    if entry is None or verdict not in ROLLER_EFFECTS:
        raise ConfigError(f"--with-effect {source}: its verdict {verdict!r} is not a roller-rig"
                          " effect with fitted parameters")
    params = {k: float(v) for k, v in entry["params"].items()}
    fact["effects"] = {verdict: params}
    return _effects({verdict: params}, source), fact


def _from_pairs(text: str) -> tuple[CreepEffects, dict[str, Any]]:
    chosen: dict[str, dict[str, float]] = {}
    for item in (s.strip() for s in text.split(",") if s.strip()):
        name, sep, raw = item.partition("=")
        name = name.strip()
        if not sep or name not in ROLLER_EFFECTS:
            raise ConfigError(
                f"--with-effect {item!r}: give NAME=VALUE with NAME one of"
                f" {', '.join(ROLLER_EFFECTS)} (values as diagnose prints them), a"
                " diagnosis.json, 'auto' or 'none'")
        try:
            v = float(raw)
        except ValueError:
            v = math.nan
        if not math.isfinite(v):
            raise ConfigError(f"--with-effect {item!r}: {raw!r} is not a number")
        chosen[name] = {ROLLER_EFFECTS[name].params[0]: v}
    return _effects(chosen, "option"), {"source": "option", "effects": chosen}


def _effects(chosen: dict[str, dict[str, float]], source: str) -> CreepEffects:
    fields = {p: v for params in chosen.values() for p, v in params.items()}
    try:
        return CreepEffects(**fields)
    except ConfigError as exc:
        raise ConfigError(f"--with-effect {source}: {exc}") from None
