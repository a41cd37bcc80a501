"""A rig diagnosis's result: what ``diagnose`` computes on a rig session and its page reads."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from brakethermo.io.session import Session


@dataclass
class RigDiagnosis:
    """What ``diagnose`` found on a rig session; :attr:`summary` is ``diagnosis.json``."""

    session: Session
    summary: dict[str, Any]
    time: np.ndarray
    x: np.ndarray  # the rig's input (s2 mm, motor angle rad)
    measured: np.ndarray
    reference: np.ndarray
    best: np.ndarray | None
    reference_sse: np.ndarray | None = None  # held-out SSE per unit of the reference
    evidence: tuple[Any, ...] = ()  # each candidate's CandidateEvidence (pooling reads it)
    negligible: frozenset[str] = frozenset()  # candidates under the floor here

    @property
    def stem(self) -> str:
        return self.session.path.stem


def carried_text(fact: dict[str, Any]) -> str:
    """One line on the effects a rig run carried (``--with-effect``; the summary's
    ``with_effect`` fact of :mod:`brakethermo.pipelines.rig_carry`)."""
    effects = fact.get("effects") or {}
    values = "; ".join(
        f"{name} ({', '.join(f'{p} = {v:+.3g}' for p, v in params.items())})"
        for name, params in effects.items()
    )
    where = {"option": "given with --with-effect"}.get(fact["source"], f"from {fact['source']}")
    if not values:
        return f"nothing, {where}: {fact.get('note', '')}"
    if fact.get("kept") is False:
        return f"nothing: {values}, {where}, was {fact['note']}"
    drift = fact.get("traction_drift_mm")
    kept = ("" if drift is None else f" (the radius moves {drift['carried']:+.3f} mm from free"
            f" rolling to traction with it, {drift['datasheet']:+.3f} mm without)")
    return f"{values}, {where}{kept}"
