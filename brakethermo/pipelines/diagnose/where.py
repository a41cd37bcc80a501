"""Where the reference model parts from the disc: residuals by spot, phase, braking
zone, speed band and temperature band."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np

from brakethermo.models.disc_effects import Segments
from brakethermo.numeric import rmse as _rmse
from brakethermo.pipelines.diagnose._common import SPEED_BANDS_KMH, TEMP_BANDS_C
from brakethermo.pipelines.diagnose.fit import _nanmean
from brakethermo.pipelines.diagnose.layout import Layout
from brakethermo.pipelines.inputs import DiscInputs


def where_table(res: np.ndarray, layout: Layout, inputs: DiscInputs, segments: Segments,
                y: np.ndarray, top: int = 12) -> list[dict[str, Any]]:
    """Cells spot × phase × zone × speed band × temperature band, by share of squared error,
    over all flying laps (the training laps and the held-out ones: where the model parts
    from the disc, not how well it generalises — the held-out scores say that)."""
    scored = layout.held | layout.train
    phase = np.where(layout.braking, "braking", np.where(layout.release, "release", "straight"))
    v_kmh = np.abs(inputs.speed) * 3.6
    speed_edges = _speed_edges(v_kmh[scored])
    speed_band = np.digitize(v_kmh, speed_edges[1:-1])
    temp_edges = _edges(TEMP_BANDS_C, y[scored])
    rows = []
    total = float(np.nansum(res[scored] ** 2))
    for i in range(4):
        temp_band = np.digitize(np.nan_to_num(y[:, i], nan=-1.0), temp_edges[1:-1])
        ok = scored & np.isfinite(res[:, i])
        keys = np.stack([np.unique(phase, return_inverse=True)[1], segments.zone + 1,
                         speed_band, temp_band], axis=1)[ok]
        r = res[ok, i]
        uniq, inv = np.unique(keys, axis=0, return_inverse=True)
        phases = np.unique(phase)
        sse = np.bincount(inv, weights=r**2)
        bias = np.bincount(inv, weights=r) / np.bincount(inv)
        count = np.bincount(inv)
        for j, key in enumerate(uniq):
            if count[j] < 10:
                continue
            rows.append({
                "spot": f"spot{i + 1}",
                "phase": str(phases[key[0]]),
                "zone": zone_label(int(key[1]) - 1, segments.zone_names),
                "speed_band_kmh": _band(speed_edges, key[2]),
                "temp_band_c": _band(temp_edges, key[3]),
                "rmse_c": float(np.sqrt(sse[j] / count[j])),
                "bias_c": float(bias[j]),
                "share_pct": 100.0 * float(sse[j]) / total if total else 0.0,
                "samples": int(count[j]),
            })
    rows.sort(key=lambda r: -r["share_pct"])
    return rows[:top]


def _band(edges: Sequence[float], i: int) -> str:
    return f"{edges[i]:.0f}-{edges[i + 1]:.0f}"


def zone_label(z: int, names: tuple[str, ...] = ()) -> str | None:
    """Braking zone ``z`` (0-based, by lap distance) as every page names it (``names``:
    the session's ``Segments.zone_names``; B1, B2, … without them)."""
    if z < 0:
        return None
    return names[z] if z < len(names) else f"B{z + 1}"


def _edges(bands: Sequence[float], values: np.ndarray) -> tuple[float, ...]:
    """Band edges within the session: the last band ends at its largest value."""
    top = float(np.ceil(np.nanmax(values))) if np.isfinite(values).any() else bands[1]
    inner = tuple(e for e in bands[1:] if e < top)
    return (bands[0], *inner, top)


def _speed_edges(v_kmh: np.ndarray) -> tuple[float, ...]:
    """Speed-band edges, km/h, within the session: the last band ends at its top speed."""
    return _edges(SPEED_BANDS_KMH, v_kmh)


def _marginals(res: np.ndarray, layout: Layout, inputs: DiscInputs, segments: Segments,
               y: np.ndarray) -> dict[str, Any]:
    scored = layout.held | layout.train
    out: dict[str, Any] = {}
    phases = {"braking": layout.braking, "release": layout.release & ~layout.braking,
              "straight": ~layout.braking & ~layout.release}
    out["by_spot_phase"] = {
        f"spot{i + 1}": {p: {"rmse_c": _rmse(res[scored & m, i]),
                             "bias_c": float(_nanmean(res[scored & m, i]))
                             if (scored & m).any() else float("nan")}
                         for p, m in phases.items()}
        for i in range(4)
    }
    out["by_zone"] = [
        {"zone": zone_label(z, segments.zone_names),
         "rmse_c": _rmse(res[scored & (segments.zone == z)]),
         "bias_c": float(_nanmean(res[scored & (segments.zone == z)]))}
        for z in range(segments.n_zones) if (scored & (segments.zone == z)).any()
    ]
    v = np.abs(inputs.speed) * 3.6
    out["by_speed_band"] = [
        {"band_kmh": f"{lo:.0f}-{hi:.0f}", "rmse_c": _rmse(res[scored & (v >= lo) & (v <= hi)])}
        for lo, hi in itertools.pairwise(_speed_edges(v[scored]))
        if (scored & (v >= lo) & (v <= hi)).any()
    ]
    t = _nanmean(y, axis=1)
    out["by_temperature_band"] = [
        {"band_c": f"{lo:.0f}-{hi:.0f}", "rmse_c": _rmse(res[scored & (t >= lo) & (t <= hi)])}
        for lo, hi in itertools.pairwise(_edges(TEMP_BANDS_C, t[scored]))
        if (scored & (t >= lo) & (t <= hi)).any()
    ]
    return out

