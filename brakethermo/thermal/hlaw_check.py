"""Is a fitted h(V) law plausible as forced convection? (It must rise with speed.)

Every fit of the law bounds its exponent ``b`` below by 0 (``HLaw.fit``, identify-h's
structure fit, the diagnosis's reference): h may not fall with speed. A law that ends
there, or that hardly rises across the speeds its session ran, is no convection law: an
unmodelled effect (a friction that grows with temperature, a lagging pyrometer, a
slipstream) was absorbed by h. Found on a μ(T) test session fitted without effects:
``b`` = 2.4e-06, h = 76.8 W/(m² K) at every speed, while the session's own straights
cooled as the law x1.31; an independent generator's sessions gave ``b`` = 0.066 and 0.000.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from brakethermo.thermal.hlaw import HLaw

B_LOWER = 0.0  # the exponent's lower bound in every fit of the law
B_HAIR = 0.01  # an exponent this close to its bound sits on it (a bounded fit stops near)
# an exponent at a bound below this is at its lower bound, which law_speed_check says; one
# above it (the upper bound, 3) is said as any parameter at a bound
B_LAW_CHECKED = 1.0
# Forced convection off a disc rises as about V^0.5 (laminar) to V^0.8 (turbulent): a law
# rising less than V^0.2 between the session's slow and fast speeds does not follow it.
MIN_RISE_EXPONENT = 0.2
SPEED_QUANTILES = (10.0, 90.0)  # the session's "low" and "high" speeds, percent
KMH = 3.6


def law_speed_check(law: HLaw, speed_mps: np.ndarray) -> dict[str, Any] | None:
    """The law's exponent at its bound, or h(V) not rising over the session's speeds.

    Parameters
    ----------
    law : HLaw
        The fitted law.
    speed_mps : ndarray — m/s
        The speeds the law was fitted on (off-brake samples, or the whole session).

    Returns
    -------
    dict or None
        ``None`` when the law is plausible; else ``b``, ``b_at_bound`` (bool),
        ``v_low_kmh``, ``v_high_kmh`` (the 10th and 90th percentiles of the speeds),
        ``h_low``, ``h_high`` (W/(m² K)), ``rise`` (h_high / h_low), ``rise_needed``
        (the rise of V^0.2 over the same speeds) and ``text`` (what it means).
    """
    v = np.asarray(speed_mps, float)
    v = v[np.isfinite(v) & (v > 1.0)]
    if v.size < 2:
        return None
    v_low, v_high = (float(x) for x in np.percentile(v, SPEED_QUANTILES))
    h_low, h_high = float(law(v_low)), float(law(v_high))
    at_bound = law.b <= B_LOWER + B_HAIR
    need = (v_high / v_low) ** MIN_RISE_EXPONENT if v_low > 0 else 1.0
    rise = h_high / h_low if h_low > 0 else float("nan")
    flat = v_high > v_low * 1.05 and not rise >= need
    if not (at_bound or flat):
        return None
    what = (f"exponent b = {law.b:.3g} at its lower bound {B_LOWER:g}" if at_bound
            else f"exponent b = {law.b:.3g}")
    text = (f"h(V) law implausible for forced convection: {what}; h = {h_low:.1f} W/(m² K)"
            f" at {v_low * KMH:.0f} km/h and {h_high:.1f} at {v_high * KMH:.0f} km/h"
            f" (x{rise:.2f}; convection off a disc rises about as V^0.5-0.8, here at least"
            f" x{need:.2f}). The law has likely absorbed an unmodelled effect (μ(T), a"
            " pyrometer lag, slipstream): `brakethermo diagnose` tests which, and identify-h"
            " with the effect selection carries it (--with-effect auto, or its name)")
    return {"b": float(law.b), "b_at_bound": bool(at_bound), "v_low_kmh": v_low * KMH,
            "v_high_kmh": v_high * KMH, "h_low": h_low, "h_high": h_high, "rise": rise,
            "rise_needed": need, "text": text}
