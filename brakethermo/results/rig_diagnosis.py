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

    @property
    def stem(self) -> str:
        return self.session.path.stem
