"""What the race's online h factor found: slipstream comes and goes, a law that is off
for this race is off on every lap.

The online slipstream state is an h factor that moves off the brakes only
(:data:`~brakethermo.models.disc.H_FACTOR_PARAM`). Following another bike lowers it on
the laps spent behind it; a cooling law that does not fit this race (another day's,
duct's or disc's, or one that absorbed a heat path the model lacks) moves it the same
way on every lap. The race's decision (:mod:`~brakethermo.pipelines.online_choice`) only
says the state helps; this says which of the two the smoothed state shows, from its
mean over each off-brake stretch of each whole flying lap, so that the page does not
call a steady departure of the law "slipstream". An independent generator's six races
without slipstream sat at 0.63-0.86 on every lap (lap means within 3 % of their median)
and were all reported as slipstream; its slipstream race spread 0.57-0.64 by lap.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass
from typing import Any

import numpy as np

from brakethermo.numeric import true_runs
from brakethermo.results.laps import lap_name

MIN_STRAIGHT_S = 3.0  # s off the brakes for a stretch to count
STEADY = 0.10  # |median - 1| from which a factor that holds on every lap is reported
WARN = 0.20  # ... and warned about: a fifth of the law's cooling
LAP_SPREAD = 0.05  # every lap's mean within this (relative) of the median: it holds


@dataclass(frozen=True)
class HFactorFound:
    """The online h factor per lap and what it shows.

    Attributes
    ----------
    per_lap : dict of int to float — mean factor over the lap's off-brake stretches.
    median : float — median of ``per_lap`` (of the laps not lower than the others, for
        ``"by lap"``: the law's departure where no slipstream is).
    kind : str — ``"steady"`` (off the law by the same factor on every lap), ``"by lap"``
        (lower on some laps: slipstream-like), ``"near the law"`` or ``"varies"`` (off the
        law, higher on some laps).
    said : str — the finding in one sentence.
    """

    per_lap: dict[int, float]
    median: float
    kind: str
    said: str

    def facts(self) -> dict[str, Any]:
        """The ``run.effects.slipstream.found`` entry of summary.json."""
        return {"per_lap": {str(k): v for k, v in self.per_lap.items()},
                "median": self.median, "kind": self.kind, "said": self.said}


def _stretch_means(h_factor: np.ndarray, off: np.ndarray, lap: np.ndarray,
                   min_steps: int) -> dict[int, list[float]]:
    out: dict[int, list[float]] = {}
    for a, b in true_runs(off):
        if b - a >= min_steps:
            out.setdefault(int(lap[a]), []).append(float(np.mean(h_factor[a:b])))
    return out


def h_factor_found(h_factor: np.ndarray, braking: np.ndarray, lap: np.ndarray,
                   whole_laps: Collection[int], dt: float) -> HFactorFound | None:
    """What the smoothed online h factor shows (module docstring).

    Parameters
    ----------
    h_factor : ndarray (K,) — the smoothed state, dimensionless (1 = the law's h).
    braking : ndarray (K,) of bool — the brake applied (``DiscInputs.braking``).
    lap : ndarray (K,) of int — lap of each step.
    whole_laps : collection of int — the whole flying laps (out-lap and partial laps
        excluded: an in-lap's slow cooling is no lap's).
    dt : float — s, step.

    Returns
    -------
    HFactorFound, or None with fewer than two whole laps of off-brake stretches.
    """
    off = ~np.asarray(braking, bool)
    means = _stretch_means(np.asarray(h_factor, float), off, np.asarray(lap),
                           max(1, round(MIN_STRAIGHT_S / dt)))
    per_lap = {n: float(np.mean(v)) for n, v in sorted(means.items()) if n in whole_laps}
    if len(per_lap) < 2:
        return None
    f = np.array(list(per_lap.values()))
    m = float(np.median(f))
    laps_text = ", ".join(f"{v:.2f}" for v in f)
    same = bool(np.all(np.abs(f / m - 1.0) <= LAP_SPREAD))
    if same and abs(m - 1.0) >= STEADY:
        word = "below" if m < 1.0 else "above"
        said = (f"the online h factor sat at {m:.2f} on every lap ({laps_text}): this race"
                f" cools as if h were {100 * abs(m - 1.0):.0f} % {word} the law's everywhere off"
                " the brakes, which no slipstream does (it comes and goes): the law may be"
                " another day's, duct's or disc's (then identify-h on a test session of this"
                " bike and disc), or the disc gains or loses heat in a way the model lacks"
                " (to its carrier, say), which a law of this very bike and disc leaves")
        return HFactorFound(per_lap, m, "steady", said)
    low = [n for n, v in per_lap.items() if v < m * (1.0 - LAP_SPREAD)]
    if low:
        rest = float(np.median([v for n, v in per_lap.items() if n not in low]))
        said = (f"the online h factor per lap {laps_text}: lower on "
                + ", ".join(lap_name(n) for n in low)
                + f" (median {np.median([per_lap[n] for n in low]):.2f}) than on the others"
                f" (median {rest:.2f}), as when following another bike (slipstream)")
        if abs(rest - 1.0) >= STEADY:  # and a law off for the race on the other laps
            said += (f"; on the others it sits at {rest:.2f}, {100 * abs(rest - 1.0):.0f} %"
                     f" {'below' if rest < 1.0 else 'above'} the law's h, which no"
                     " slipstream does: the law may be another day's, duct's or disc's")
        return HFactorFound(per_lap, rest, "by lap", said)
    off = float(np.max(np.abs(f - 1.0)))
    if same or off <= STEADY:
        said = (f"the online h factor per lap {laps_text}: within"
                f" {math.ceil(100 * off - 1e-9)} % of the law's h on every lap")
        return HFactorFound(per_lap, m, "near the law", said)
    said = (f"the online h factor per lap {laps_text} (median {m:.2f}): not the same on"
            f" every lap, and off the law's h by up to {100 * off:.0f} %")
    return HFactorFound(per_lap, m, "varies", said)


def h_factor_warning(found: HFactorFound | None) -> list[str]:
    """A run warning when the factor holds far off the law on every lap (those lower
    than the others aside)."""
    if found is None or found.kind not in ("steady", "by lap") or abs(
            found.median - 1.0) < WARN:
        return []
    return [found.said]
