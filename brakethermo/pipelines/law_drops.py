"""What the race did with the h law's parts, said where the engineer reads it.

The race judges the parts of the h law a race may not share (its pad-crown weights, its
pyrometer lag, its μ(T); :mod:`~brakethermo.pipelines.online_choice`) on the measured
spot alone. Dropping one moves the spots the race does not measure, and a drop judged
on one spot can throw away what the test session's four spots established (a law's
crown of 0.64, 1.07, 1.22 dropped on spot 3's evidence left an independent generator's
race 26-43 °C off at spots 1, 2 and 4 while its contact band stayed within 3 °C). So
every part dropped, or kept where the measured spot leaned the other way, is said on
the console and the session page with its evidence, how far the unmeasured spots move
with it, and the ``--law-as-written`` way to keep the law.
"""

from __future__ import annotations

from typing import Any

import numpy as np

# what each part is, in words
_WHAT = {"crown_weights": "pad-crown weights", "sensor_lag": "pyrometer lag",
         "friction_temperature": "μ(T) (friction_temperature)"}
_KEEP = "If the race ran the test session's {}, `estimate --law-as-written` keeps the law whole"
_KEPT_AS = {"crown_weights": "pads (same pads, bedded alike)",
            "sensor_lag": "pyrometer (the same sensor, as clean)",
            "friction_temperature": "pads (same compound, bedded alike)"}


def said(row: dict[str, Any], dropped: bool, measured_spot: int) -> str | None:
    """One sentence on a ``law_effects_tested`` row the engineer must hear of: the part
    dropped, or kept though the measured spot leaned to dropping it.

    Parameters
    ----------
    row : dict
        The row (:func:`~brakethermo.pipelines.online_choice.choose_online`): ``name``
        ``"without <part>"``, ``shrink_pct`` and ``shrink_ci95_pct``, ``must_earn`` on
        the μ(T) row (its shrink is the law with the part against without it), ``law``
        on the crown's, ``peaks_apart_c`` (spot -> °C) where the decision had both runs.
    dropped : bool
        The race dropped the part.
    measured_spot : int
        The spot the race measures (1-4).

    Returns
    -------
    str or None
        None for a part kept where the evidence agreed with the law.
    """
    name = str(row["name"]).removeprefix("without ")
    earn = bool(row.get("must_earn"))
    shrink = _number(row.get("shrink_pct"))
    lo, hi = (_number(v) for v in row.get("shrink_ci95_pct") or [None, None])
    # the drop's favour in %: positive where the measured spot predicts better without it
    favour, f_lo, f_hi = (-shrink, -hi, -lo) if earn else (shrink, lo, hi)
    if not dropped and not (np.isfinite(favour) and favour > 0.0):
        return None
    what = _WHAT.get(name, name)
    if "law" in row:
        what += " w = " + ", ".join(f"{w:.2f}" for w in row["law"])
    head = (f"the race {'dropped' if dropped else 'kept'} the h law's {what}"
            + (" (a part the race must earn)" if earn and dropped else ""))
    if not np.isfinite(favour):
        evidence = "untested: fewer than two flying laps"
    else:
        evidence = (f"without it spot {measured_spot}'s error was {-favour:+.0f} %"
                    + (f" (95 % {-f_hi:+.0f} to {-f_lo:+.0f} %)" if np.isfinite(f_lo)
                       else "") + f", {row.get('test', '')}")
    return (f"{head}: {evidence}. {_unmeasured(row, name, dropped, measured_spot)}."
            f" {_KEEP.format(_KEPT_AS.get(name, 'parts'))}")


def _number(value: Any) -> float:
    """A figure of a row, NaN for a missing one (null once through JSON)."""
    return float("nan") if value is None else float(value)


def _unmeasured(row: dict[str, Any], name: str, dropped: bool, measured_spot: int) -> str:
    """What the choice means for the spots the race does not measure, in words."""
    apart = {s: v for s, v in (row.get("peaks_apart_c") or {}).items()
             if s != f"spot{measured_spot}" and np.isfinite(v)}
    others = ", ".join(str(s) for s in range(1, 5) if s != measured_spot)
    one_spot = (f"Spot {measured_spot} alone hardly sees an inner/outer split: spots"
                f" {others} now rest on uniform weights, not on the test session's four"
                " spots" if name == "crown_weights" else
                f"Spots {others} follow spot {measured_spot}'s evidence, not the test"
                " session's")
    if not dropped:
        one_spot = f"Spots {others} keep the law's, against spot {measured_spot}'s lean"
    if not apart:
        return one_spot
    moves = ", ".join(f"{s.replace('spot', 'spot ')} {v:+.0f} °C" for s, v in apart.items())
    return (f"{one_spot} — with the law's part their lap peaks on the decision laps read"
            f" {moves} against without it (mean over laps): an error of that size there"
            " does not show in the contact band's")


def law_part_warnings(choice_facts: dict[str, Any] | None) -> list[str]:
    """The sentences of :func:`said` the decision wrote into its rows (``said``)."""
    rows = (choice_facts or {}).get("law_effects_tested", [])
    return [str(r["said"]) for r in rows if r.get("said")]
