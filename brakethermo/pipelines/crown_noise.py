"""The crown-split noise of a race on a thinner skin, chosen by the race's own likelihood.

identify-h chooses the crown-split process noise (``sigma_crown``: how far the braking
power's share between the pad's crowns may wander) on its four-spot test session, for
the test disc. A race that switches k_z on and learns it below the law's runs a thinner
thermal skin (identify-h's thin-skin layering,
:func:`~brakethermo.pipelines.race_run.thin_skin`): its face follows the pads' flux
closely, and the law's noise can let the one measured spot shift power between the
crowns against what the spots it does not measure do. On an independent generator's
low-k_z race (its own 2D disc) with the law of a μ(T) test session, spots 2 and 4 ran 26
and 22 °C RMS, 1.00x the single-spot baseline. A fixed lower noise helped there but cost
races whose test bike had a pad split (0.95 -> 1.45x), so the race chooses:

the filter runs over the decision's laps
(:data:`~brakethermo.pipelines.online_choice.DECISION_LAPS`) at :data:`FACTORS` of the
law's noise, on the mesh and with the states and reading noise the race runs, beside the
race's own filter at the law's noise; the noise whose one-step predictive likelihood over
those laps (predictions from past readings only) is best is kept where its gain over the
law's clears :data:`~brakethermo.pipelines.online_choice.MIN_LOGLIK_GAIN` nats per
reading at the lower end of a 95 % bootstrap interval over braking cycles — a noise is
the filter's model of what it does not know, judged by the proper score as the pyrometer
lag is — and the race's filter runs again on it. A noise too low for the race shows
there: on that race, a quarter of the law's sent the states astray from the out-lap on
(-15 nats per reading).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from brakethermo.errors import BrakethermoError
from brakethermo.io.session import Session
from brakethermo.pipelines.online_choice import (
    DECISION_LAPS,
    MIN_LOGLIK_GAIN,
    OnlineChoice,
    decision_units,
    head,
    likelihood_test,
    thin_skin_learned,
)
from brakethermo.pipelines.speculative import Cancelled
from brakethermo.pipelines.tuning import user_tuning_keys

if TYPE_CHECKING:
    from brakethermo.pipelines.estimate import EstimateOptions

# A race chooses on all of the decision's laps or not at all: on 3-lap development races
# (the same 16 cells, seed base 57400) the lower noises it took moved the contact band
# 0.43/0.77/0.95 -> 0.37/0.71/0.91x and 0.40/0.45/0.36 -> 0.44/0.56/0.41x, the sum up by
# 0.04, where on 8-lap ones it fell by 0.45 (below); the reporting race matrix's 3-lap
# races moved the same way (11 k_z cells, the sum up by 0.22), so short races keep the
# law's noise.

# factors of the law's crown-split noise the race tries. The independent race above:
# 0.63x at half the law's 0.4 (a quarter diverged). Development 8-lap low-k_z races (both
# tracks, every test-session effect, seeds 57400 and 61400): 12 of 32 took a lower noise,
# 7 better, 5 worse, the sum of the 32 ratios 0.45 lower (README, accuracy).
FACTORS = (0.5, 0.25)


@dataclass(frozen=True)
class Innovations:
    """The measured spot's one-step-ahead innovations of a filter pass and their
    variances, degC and degC^2 (what :func:`likelihood_test` scores)."""

    innovation: np.ndarray
    innovation_var: np.ndarray


def free(choice: OnlineChoice | None, options: EstimateOptions, flying: int) -> bool:
    """Does the race choose its crown-split noise: it switched k_z on below the law's, has
    all :data:`~brakethermo.pipelines.online_choice.DECISION_LAPS` decision laps
    (``flying``: its flying laps; :data:`DECISION_LAPS`), and neither an option nor the
    user's tuning file sets the noise."""
    return (choice is not None and flying >= DECISION_LAPS
            and thin_skin_learned(choice) is not None and options.sigma_crown is None
            and "sigma_crown" not in user_tuning_keys(options.tuning, "estimate"))


def decision_part(session: Session) -> Session:
    """The race up to the end of its last decision lap (the online decision's laps)."""
    flying = [lap.lap for lap in session.laps if lap.lap >= 1]
    return head(session, min(DECISION_LAPS, max(flying)))


def trials(steps: int, sigma: float, run: Callable[[int, float], Innovations]
           ) -> dict[float, Innovations | str]:
    """Each of :data:`FACTORS` of the law's noise ``sigma`` run by ``run(steps, noise)``
    over the first ``steps`` grid points, one after the other (on the caller's thread:
    the core the race's own filter leaves). A filter that breaks down at a noise (or is
    stopped with the race) leaves why, in words: that noise lost."""
    out: dict[float, Innovations | str] = {}
    for f in FACTORS:
        try:
            out[f] = run(steps, sigma * f)
        except (BrakethermoError, Cancelled) as exc:
            out[f] = str(exc) or type(exc).__name__
    return out


def judge(part: Session, law: Innovations, tried: dict[float, Innovations | str],
          sigma: float, chosen: list[str]) -> dict[str, Any]:
    """The ``run.online_choice.crown_noise`` fact: each tried noise against the law's
    ``sigma`` (``law``: the race's own filter at it, over ``part``'s steps), and the noise
    the race keeps (``chosen``; ``changed`` when it is not the law's)."""
    lap, cycles, rule = decision_units(part)
    n = lap.size
    ref = Innovations(law.innovation[:n], law.innovation_var[:n])
    tests = []
    for f, other in tried.items():
        if isinstance(other, str):
            tests.append({"factor": f, "sigma_crown": sigma * f, "failed": other,
                          "significant": False})
            continue
        row = likelihood_test(ref, other, lap, cycles, rule)
        tests.append({"factor": f, "sigma_crown": sigma * f, **{k: row[k] for k in (
            "loglik_gain_per_reading", "loglik_gain_ci95", "significant")}})
    won = [r for r in tests if r["significant"]]
    best = max(won, key=lambda r: r["loglik_gain_per_reading"]) if won else None
    laps = ", ".join(str(int(v)) for v in np.unique(lap[lap >= 1]))
    factors = " and ".join(f"{f:g}" for f in FACTORS)
    return {"law": sigma, "chosen": sigma if best is None else best["sigma_crown"],
            "changed": best is not None, "tests": tests,
            "test": (f"the law's crown-split noise against {factors}"
                     f" of it, with {', '.join(chosen)} online on the race's mesh: one-step"
                     f" predictive likelihood, flying laps {laps}; the best whose gain clears"
                     f" {MIN_LOGLIK_GAIN:g} nats per reading at the lower end of its 95 %"
                     " interval (a thinner skin than the law's disc)")}
