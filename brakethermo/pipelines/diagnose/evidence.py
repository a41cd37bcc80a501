"""The evidence behind each effect: residual signatures, their sentences, and each
effect's size in physical units."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from brakethermo.models.disc_effects import KNEE, Segments
from brakethermo.models.effects import knee_factor, mu_ratio
from brakethermo.pipelines.diagnose.fit import _nanmean
from brakethermo.pipelines.diagnose.layout import Layout
from brakethermo.pipelines.diagnose.where import zone_label
from brakethermo.pipelines.inputs import DiscInputs
from brakethermo.thermal.disc import DiscSpec
from brakethermo.thermal.power import normalise_weights


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 3 or np.std(a[ok]) == 0 or np.std(b[ok]) == 0:
        return float("nan")
    return float(np.corrcoef(a[ok], b[ok])[0, 1])


def signatures(res: np.ndarray, y: np.ndarray, inputs: DiscInputs, layout: Layout,
               segments: Segments, v_ref: float, dt: float) -> dict[str, dict[str, float]]:
    """Residual statistics behind each effect's signature (reference model, all laps).

    ``res`` is measurement minus model, degC (K, 4).
    """
    flying = layout.train | layout.held
    br, cool = layout.braking & flying, ~layout.braking & flying
    dTdt = np.gradient(y, dt, axis=0)
    fast = np.abs(inputs.speed) >= 0.8 * v_ref
    lapwise = []
    for s in range(segments.n_straights):
        m = (segments.straight == s) & cool
        if m.sum() > 20:
            lapwise.append(float(_nanmean(res[m])))
    contact = _nanmean(y[:, 1:4], axis=1)
    return {
        "sensor_lag": {"corr_residual_dTdt": _corr(res[flying].ravel(), dTdt[flying].ravel())},
        "emissivity_error": {
            "slope_braking_c_per_100c": 100.0 * _slope(y[br].ravel(), res[br].ravel()),
            "slope_cooling_c_per_100c": 100.0 * _slope(y[cool].ravel(), res[cool].ravel()),
        },
        "h_speed_knee": {
            "cooling_bias_fast_c": float(_nanmean(res[cool & fast])) if (cool & fast).any()
            else float("nan"),
            "cooling_bias_slow_c": float(_nanmean(res[cool & ~fast])),
        },
        "friction_temperature": {
            "corr_braking_residual_temperature": _corr(_nanmean(res[br], axis=1),
                                                       contact[br]),
        },
        "power_distribution": {
            "braking_bias_spot2_c": float(_nanmean(res[br, 1])),
            "braking_bias_spot4_c": float(_nanmean(res[br, 3])),
        },
        "slipstream": {"lap_to_lap_sd_straight_bias_c": float(np.std(lapwise))
                       if len(lapwise) > 2 else float("nan")},
        "thickness_gradient": {
            "braking_bias_c": float(_nanmean(res[br])),
            "release_bias_c": float(_nanmean(res[layout.release & flying])),
        },
    }


def _slope(x: np.ndarray, r: np.ndarray) -> float:
    ok = np.isfinite(x) & np.isfinite(r)
    if ok.sum() < 3 or np.std(x[ok]) == 0:
        return float("nan")
    return float(np.polyfit(x[ok], r[ok], 1)[0])


EVIDENCE: dict[str, Callable[[dict[str, float]], str]] = {
    "sensor_lag": lambda s: (
        f"residual vs dT/dt correlation {s['corr_residual_dTdt']:+.2f} (a lagging sensor"
        " reads low while heating, high while cooling: negative)"),
    "emissivity_error": lambda s: (
        f"bias slope {s['slope_braking_c_per_100c']:+.1f} °C per 100 °C braking,"
        f" {s['slope_cooling_c_per_100c']:+.1f} cooling (same sign in every phase for a"
        " wrong emissivity)"),
    "h_speed_knee": lambda s: (
        f"cooling bias {s['cooling_bias_fast_c']:+.1f} °C above 0.8 V_ref vs"
        f" {s['cooling_bias_slow_c']:+.1f} °C below (measured minus model)"),
    "friction_temperature": lambda s: (
        "braking residual vs contact temperature correlation"
        f" {s['corr_braking_residual_temperature']:+.2f}"),
    "power_distribution": lambda s: (
        f"braking bias spot 2 {s['braking_bias_spot2_c']:+.1f} °C, spot 4"
        f" {s['braking_bias_spot4_c']:+.1f} °C"
        + (" (opposite signs: the heat split over the radius is not the model's)"
           if s["braking_bias_spot2_c"] * s["braking_bias_spot4_c"] < 0 else
           " (same sign: the whole band, not its split, departs)")),
    "slipstream": lambda s: (
        f"lap-to-lap spread of the straights' cooling bias {s['lap_to_lap_sd_straight_bias_c']:.1f}"
        " °C"),
    "thickness_gradient": lambda s: (
        f"braking bias {s['braking_bias_c']:+.1f} °C, just after release"
        f" {s['release_bias_c']:+.1f} °C"),
}


def straight_places(segments: Segments) -> list[tuple[int, str]]:
    """Each straight's lap and the braking zone it follows, as the pages name zones ("the
    start" for a straight before the first stop)."""
    ids, first = np.unique(segments.straight, return_index=True)
    start = dict(zip(ids.tolist(), first.tolist(), strict=True))
    return [(int(segments.straight_lap[j]),
             zone_label(int(segments.zone[start[j]]), segments.zone_names) or "the start")
            for j in range(segments.n_straights)]


def carry_command(session: Path, name: str) -> str:
    """The command that carries an effect into the law the race estimate uses."""
    return f"brakethermo identify-h {session} --with-effect {name} --out OUT"


def _spread(values: Sequence[float]) -> str:
    v = np.asarray(values, float)
    return f"median {np.median(v):.2f}, range {v.min():.2f}-{v.max():.2f}"


def _knee_size(g: float, disc: DiscSpec, top_kmh: float) -> tuple[dict[str, Any], str]:
    """The knee's gain ``g`` at V_ref, said at the session's top speed (km/h) where its
    straights end below V_ref."""
    v_ref = disc.v_ref * 3.6
    knee = KNEE * v_ref
    size = {"knee_kmh": knee, "gain_at_v_ref": g}
    if top_kmh <= knee:
        return ({**size, "top_kmh": top_kmh},
                f"h {100 * g:+.0f} % at {v_ref:.0f} km/h, growing from the knee at"
                f" {knee:.0f} km/h: the form's extrapolation, the session never passed"
                f" the knee (top speed {top_kmh:.0f} km/h)")
    if not top_kmh < 0.97 * v_ref:
        return size, (f"h {100 * g:+.0f} % at {v_ref:.0f} km/h, growing from the knee"
                      f" at {knee:.0f} km/h")
    # a session whose straights end below V_ref shows the knee up to its top speed
    # only; the gain at V_ref is the form's extrapolation
    g_top = float(knee_factor(np.array(top_kmh / 3.6), disc.v_ref, KNEE, np.array(g))) - 1
    return ({**size, "top_kmh": top_kmh, "gain_at_top": g_top},
            f"h {100 * g_top:+.0f} % at {top_kmh:.0f} km/h (the session's top speed),"
            f" growing from the knee at {knee:.0f} km/h ({100 * g:+.0f} % at"
            f" {v_ref:.0f} km/h if the form held beyond the data)")


def _slipstream_size(f: np.ndarray, straights: Sequence[tuple[int, str]]
                     ) -> tuple[dict[str, Any], str]:
    """The slipstream's h factors per straight ``f`` and where they departed most."""
    off = int(np.sum(np.abs(f - 1.0) > 0.1))
    size = {"h_factor_per_straight": f.tolist(), "straights_off_10pct": off}
    text = (f"h factor per straight {_spread(f)}; {off} of {f.size} straights more than"
            " 10 % off")
    if not straights or len(straights) != f.size:
        return size, text
    most = [int(j) for j in np.argsort(-np.abs(np.log(f)))[:3] if abs(f[j] - 1) > 0.1]
    where = [{"lap": straights[j][0], "after": straights[j][1], "h_factor": float(f[j])}
             for j in most]
    said = ", ".join(f"lap {w['lap']} after {w['after']} {w['h_factor']:.2f}" for w in where)
    return {**size, "most_off": where}, text + (f" (most: {said})" if said else "")


def effect_size(name: str, params: dict[str, Any], disc: DiscSpec, layers: int,
                zone_names: tuple[str, ...] = (), top_kmh: float = float("nan"),
                straights: Sequence[tuple[int, str]] = (),
                crown: Sequence[float] = (1.0, 1.0, 1.0),
                reference_crown: Sequence[float] = (1.0, 1.0, 1.0)
                ) -> tuple[dict[str, Any], str]:
    """An effect's fitted size in physical units, and the sentence the page shows
    (``zone_names``: the session's track names of its braking zones; ``top_kmh``: the
    flying laps' top speed, km/h, where a knee's size is stated when below V_ref;
    ``straights``: each straight's lap and the zone it follows, where a slipstream's
    largest departures are said; ``crown``: the candidate's mean crown weights, which a
    pad split's zones act on, and ``reference_crown`` the reference's, w1..w3)."""
    if name == "thickness_gradient":
        f = float(params["kz_factor"])
        k_z = f * disc.k_z if disc.k_z else float("nan")
        return ({"kz_over_nominal": f, "k_z_w_mk": k_z, "k_z_nominal_w_mk": disc.k_z},
                f"through-thickness conductivity k_z = {k_z:.1f} W/(m K), {f:.2f} x the"
                f" datasheet's {disc.k_z:g} W/(m K) ({layers} layers)")
    if name == "sensor_lag":
        tau = float(params["tau_s"])
        return {"tau_s": tau}, f"pyrometer time constant {tau:.2f} s"
    if name == "emissivity_error":
        r = float(params["ratio"])
        eps_set = disc.emissivity / r
        err600 = (600.0 + 273.15) * (r**0.25 - 1.0)
        size = {"eps_disc_over_set": r, "eps_set": eps_set, "eps_disc": disc.emissivity,
                "reading_error_at_600c": err600}
        if eps_set <= 1.0:
            return size, (f"pyrometer set to emissivity {eps_set:.2f} on a {disc.emissivity:g}"
                          f" disc: reads {err600:+.0f} °C at 600 °C")
        # no setting exceeds 1: a radiance ratio this low is a window or lens that
        # passes less than the disc emits (a dirty or misted window), set to 1
        return ({**size, "transmission_at_eps_set_1": r / disc.emissivity},
                f"radiance ratio {r:.2f} on a {disc.emissivity:g} disc, lower than any"
                f" emissivity setting gives: a pyrometer set to 1.00 behind a window passing"
                f" {100 * r / disc.emissivity:.0f} %; reads {err600:+.0f} °C at 600 °C")
    if name == "friction_temperature":
        points = {f"{t:.0f}": float(mu_ratio(np.array(t), params["beta"], params["t_mid"]))
                  for t in (200.0, 400.0, 600.0, 800.0)}
        return ({"mu_over_ref_at_c": points, "beta": params["beta"],
                 "t_mid_c": params["t_mid"]},
                "μ/μ_ref " + ", ".join(f"{v:.2f} at {t} °C" for t, v in points.items()))
    if name == "h_speed_knee":
        return _knee_size(float(params["gain"]), disc, top_kmh)
    if name == "slipstream":
        return _slipstream_size(np.asarray(params.get("straight_factor", [1.0]), float),
                                straights)
    if name == "power_distribution":
        return _crown_size(params, disc, zone_names, crown, reference_crown)
    return dict(params), ""


def _crown_size(params: dict[str, Any], disc: DiscSpec, zone_names: tuple[str, ...],
                crown: Sequence[float], reference: Sequence[float]
                ) -> tuple[dict[str, Any], str]:
    """Each braking zone's pad crown, and the sentence.

    A zone's balance ``b`` and middle ``m`` act on the candidate's own mean crown
    ``(w1 e^b, w2 e^m, w3 e^-b)``, which the fit moves with them (what all zones share is
    that crown's), so the zone's inner/outer power ratio is ``(w1 / w3) e^(2b)``: ``e^(2b)``
    alone said 4.81 on a session whose zones' crowns were 1.4-1.8 (identify-h: 1.55).

    Parameters
    ----------
    params : dict — ``zone_balance``, ``zone_middle`` (one per zone, dimensionless)
    disc : DiscSpec — its crown edges normalise the weights (eq. 8)
    zone_names : tuple of str — the zones' track names
    crown : sequence of 3 float — the candidate's mean crown weights, any scale
    reference : sequence of 3 float — the reference fit's crown weights (one for every stop)

    Returns
    -------
    size : dict — ``per_zone`` (``inner_vs_outer``, ``middle_factor``: the zone's middle
        weight over the reference's, ``weights``: w1..w3 normalised) and
        ``reference_inner_vs_outer``
    text : str
    """
    b = np.asarray(params.get("zone_balance", []), float)
    m = np.asarray(params.get("zone_middle", []), float)
    ref = normalise_weights(np.asarray(reference, float), disc.crown_edges)
    w = [normalise_weights(np.asarray(crown, float) * np.exp([b[z], m[z], -b[z]]),
                           disc.crown_edges) for z in range(b.size)]
    ratio = np.array([wz[0] / wz[2] for wz in w])
    zones = {zone_label(z, zone_names): {"inner_vs_outer": float(ratio[z]),
                                         "middle_factor": float(w[z][1] / ref[1]),
                                         "weights": [float(v) for v in w[z]]}
             for z in range(b.size)}
    size = {"per_zone": zones, "reference_inner_vs_outer": float(ref[0] / ref[2])}
    if not b.size:
        return size, "no zone"
    worst = int(np.argmax(np.abs(np.log(ratio * ref[2] / ref[0]))))
    return size, (f"inner/outer crown power ratio per zone {_spread(ratio)} (one crown for"
                  f" every stop: {ref[0] / ref[2]:.2f}); furthest from it"
                  f" {zone_label(worst, zone_names)}: {ratio[worst]:.2f}")

