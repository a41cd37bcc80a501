"""The disc model extended by registered effects, run open loop for many parameter sets.

:class:`ExtendedDisc` lays out one parameter vector — the reference model's
``log a, b, log scale, log w_1, log w_2`` (power-law h(V), the constant friction level
and the mean pad-crown weights, ``w_3`` = 1) followed by
the parameters of each effect switched on and their latent per-segment values — and
predicts the four spot readings for a batch of such vectors in one pass of the
banded FE kernel (each vector a batch member). Output-error fits (diagnose,
identify-h ``--with-effect``) take their residual and forward-difference Jacobian
from one such pass, as identify-h's structure fit does.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from brakethermo.models.effects import (
    EFFECTS,
    MU_SPAN_C,
    EffectParam,
    knee_factor,
    lag_alpha,
    pyrometer_reading,
)
from brakethermo.thermal.hlaw import HLaw
from brakethermo.thermal.model import DiscFEModel
from brakethermo.thermal.power import normalise_weights

REFERENCE_PARAMS = (
    EffectParam("log_a", np.log(100.0), np.log(1.0), np.log(2000.0), unit="log W/(m2 K)"),
    EffectParam("b", 0.8, 0.0, 3.0),
    EffectParam("scale", 1.0, 0.3, 3.0, log=True),
    EffectParam("w1", 1.0, 0.05, 20.0, log=True),
    EffectParam("w2", 1.0, 0.05, 20.0, log=True),
)
N_REFERENCE = len(REFERENCE_PARAMS)
KNEE = 0.8
NO_KNEE = 10.0  # x = V/V_ref never reaches it: the power law holds at every speed


@dataclass(frozen=True)
class Segments:
    """Where each grid step belongs, for effects with per-segment values.

    Attributes
    ----------
    zone : ndarray (K,) of int
        Braking-zone id (the same zone on every lap, by lap distance) at braking steps
        and through the cycle that follows until the next zone; -1 before the first.
    n_zones : int
    straight : ndarray (K,) of int
        Id of the off-brake stretch (one per straight of every lap); -1 under braking.
    n_straights : int
    straight_lap : ndarray (n_straights,) of int
        Lap of each straight.
    zone_names : tuple of str
        The track name of each zone as every page gives it (B1…, "B3+" for an occasional
        stop; ``report.braking_zones``).
    """

    zone: np.ndarray
    n_zones: int
    straight: np.ndarray
    n_straights: int
    straight_lap: np.ndarray
    zone_names: tuple[str, ...] = ()


@dataclass(frozen=True)
class Slot:
    """Where one parameter sits in the vector."""

    effect: str  # "reference" or an effect name
    param: EffectParam
    index: int
    segment: int = -1  # latent parameters: the zone or straight id


def departures(factor: np.ndarray, level: np.ndarray | None = None) -> np.ndarray:
    """Slipstream straight factors (B, straights) as departures from the session's own h:
    divided by the geometric mean of the ``level`` straights (all when ``None``), so their
    common level is h's.

    A slipstream is a departure from the norm, straight by straight; a common level would
    trade against h's ``a`` and move h under the brakes instead (an independent
    generator's test session carried factors of 0.4-0.6 with ``a`` doubled, a law that
    lost to the one without slipstream on every race).
    """
    return factor / _level_mean(factor, level)[:, None]


def _level_mean(factor: np.ndarray, level: np.ndarray | None) -> np.ndarray:
    """Geometric mean (B,) of the ``level`` straights' factors (all when ``None``)."""
    ref = factor if level is None or not np.any(level) else factor[:, level]
    return np.exp(np.mean(np.log(ref), axis=1))


class ExtendedDisc:
    """Open-loop spot predictions of the disc model with effects, batched over parameters.

    Parameters
    ----------
    model : DiscFEModel
        The reference structure (datasheet k_z, layers); its crown weights are the
        reference's (uniform pad pressure).
    speed, q_brk, t_amb : ndarray (K,) — m/s, W, degC
        Inputs on the grid; step k -> k+1 uses the inputs at k (eq. 15).
    T0 : ndarray (n_state,) — degC
        Initial node temperatures.
    spot_radii : sequence of float — m
    v_ref : float — m/s
    effects : sequence of str
        Registered effect names switched on.
    segments : Segments
    level : ndarray (n_straights,) of bool, optional
        The straights whose slipstream factors set h's own level (:func:`departures`):
        those fitted together with h, the training laps' in the diagnosis (held-out
        straights, fitted later from spot 3, then depart from it without moving it).
        All when ``None``.
    """

    def __init__(
        self,
        model: DiscFEModel,
        speed: np.ndarray,
        q_brk: np.ndarray,
        t_amb: np.ndarray,
        T0: np.ndarray,
        spot_radii: Sequence[float],
        v_ref: float,
        effects: Sequence[str],
        segments: Segments,
        level: np.ndarray | None = None,
    ) -> None:
        self.model = model
        self.level = None if level is None else np.asarray(level, bool)
        self.speed, self.q, self.t_amb = (np.asarray(a, float)[:-1] for a in (speed, q_brk, t_amb))
        self.T0 = np.asarray(T0, float)
        self.H = model.spot_matrix(spot_radii)
        self.v_ref = float(v_ref)
        self.effects = tuple(effects)
        self.segments = segments
        edges = model.disc.crown_edges
        contact = (model.radii >= edges[0] - 1e-9) & (model.radii <= edges[-1] + 1e-9)
        self._contact_face = model.face_index[contact]
        self._basis = model.crown_basis()
        self.slots: list[Slot] = []
        for p in REFERENCE_PARAMS:
            self._add("reference", p)
        for name in self.effects:
            eff = EFFECTS[name]
            for p in eff.params:
                self._add(name, p)
            if eff.latent is not None:
                count = segments.n_zones if eff.latent == "zone" else segments.n_straights
                for param in eff.latent_params:
                    for s in range(count):
                        self._add(name, param, s)
        self.index = {(s.effect, s.param.name): s.index for s in self.slots if s.segment < 0}

    def _add(self, effect: str, param: EffectParam, segment: int = -1) -> None:
        self.slots.append(Slot(effect, param, len(self.slots), segment))

    # -------------------------------------------------------------- the vector
    @property
    def size(self) -> int:
        return len(self.slots)

    def neutral(self) -> np.ndarray:
        """The vector with every effect absent and the reference at its defaults (fitted)."""
        return np.array([float(s.param.to_fit(s.param.neutral)) for s in self.slots])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = zip(*(s.param.bounds_fit for s in self.slots), strict=True)
        return np.array(lo), np.array(hi)

    def at_bounds(self, p: np.ndarray, every: bool = False) -> dict[tuple[str, str], float]:
        """``(effect, param): value`` of the effects' parameters that ``p`` leaves at a
        bound of their range (within 1 % of the range, in the fitted space: a bounded
        least-squares fit stops near its bound, not on it — 0.6002 on a bound of 0.6).

        By default the effect's form is stretched: a strength parameter pushed past what
        the form allows, not at the effect's absent value — what a verdict sets aside and
        identify-h's selection drops. ``every`` adds what is reported but decides nothing:
        per-segment values one by one, named ``param[i]`` (``i`` the zone or straight; a
        slipstream straight judged as the multiplier of h it is written as,
        :meth:`values`: found at 1.6 and 0.400 with nothing said), and a bound that is the
        effect's absent value (a named pyrometer lag at its 0.01 s floor: the fit found
        none). One straight of 46 at its bound set a true slipstream aside when it
        decided. Shape parameters (:attr:`EffectParam.shape`) are not judged.
        """
        return self._at_bounds(p, [sl for sl in self.slots if sl.effect != "reference"
                                   and not sl.param.shape and (every or sl.segment < 0)],
                               every)

    def reference_at_bounds(self, p: np.ndarray) -> dict[tuple[str, str], float]:
        """:meth:`at_bounds` of the reference's own parameters (h's ``a`` and ``b``, the
        power scale, the mean crown weights ``w1``, ``w2`` relative to ``w3``)."""
        return self._at_bounds(p, [sl for sl in self.slots if sl.effect == "reference"])

    def _at_bounds(self, p: np.ndarray, slots: list[Slot], every: bool = True
                   ) -> dict[tuple[str, str], float]:
        """:meth:`at_bounds` over ``slots`` (``every``: also at the absent value)."""
        lo, hi = self.bounds()
        tol = 1e-2 * np.where(np.isfinite(hi - lo), hi - lo, 1.0)
        neutral = self.neutral()
        x = np.asarray(p, float).copy()
        shown = self.latent_slots("slipstream")
        if shown:  # judged as written: the multipliers of h, not the raw factors
            raw = np.exp(x[[sl.index for sl in shown]])
            x[[sl.index for sl in shown]] = np.log(self._as_multipliers(raw))
        out: dict[tuple[str, str], float] = {}
        for sl in slots:
            i = sl.index
            if not every and abs(x[i] - neutral[i]) <= tol[i]:
                continue
            if x[i] <= lo[i] + tol[i] or x[i] >= hi[i] - tol[i]:
                name = sl.param.name if sl.segment < 0 else f"{sl.param.name}[{sl.segment}]"
                out[(sl.effect, name)] = float(sl.param.from_fit(x[i]))
        return out

    def at_bounds_words(self, p: np.ndarray, every: bool = False) -> str:
        """:meth:`at_bounds` in words, ``""`` when none (``"ratio = 0.6, at the edge of its
        range 0.6 to 1.5"``; per-segment values together, ``"straight_factor[0] = 1.6,
        straight_factor[4] = 0.4, at the edges of its range 0.4 to 1.6"``)."""
        return self.bound_words(self.at_bounds(p, every))

    def reference_at_bounds_words(self, p: np.ndarray) -> str:
        """:meth:`reference_at_bounds` in words, ``""`` when none."""
        return self.bound_words(self.reference_at_bounds(p))

    def bound_words(self, found: dict[tuple[str, str], float]) -> str:
        """Bound findings in words, grouped by parameter (segments together)."""
        params = {(s.effect, s.param.name): s.param for s in self.slots}
        groups: dict[tuple[str, str], dict[str, float]] = {}
        for (effect, name), v in found.items():
            groups.setdefault((effect, name.split("[", 1)[0]), {})[name] = v
        parts = []
        for key, values in groups.items():
            par = params[key]
            # a bound that is the effect's absent value (the lag's 0.01 s): it found none
            absent = all(np.isclose(v, par.neutral, rtol=0.05) for v in values.values())
            parts.append(", ".join(f"{n} = {v:.3g}" for n, v in values.items())
                         + f", at the edge{'s' if len(values) > 1 else ''} of its range"
                         f" {par.lower:g} to {par.upper:g}"
                         + (" (the effect's absent value: the fit found none)" if absent
                            else ""))
        return "; ".join(parts)

    def prior(self) -> tuple[np.ndarray, np.ndarray]:
        """Prior mean and standard deviation (inf = none) in the fitted space."""
        mu = np.array([float(s.param.to_fit(s.param.neutral)) for s in self.slots])
        sd = np.array([s.param.prior_sigma or np.inf for s in self.slots])
        return mu, sd

    def values(self, p: np.ndarray, effect: str) -> dict[str, float | list[float]]:
        """Parameter values (in their units) of ``effect`` in vector ``p``; a slipstream's
        straight factors as the multipliers of h they act as (:func:`departures`), within
        their bounds (a common factor changes nothing in the model)."""
        out: dict[str, float | list[float]] = {}
        for s in self.slots:
            if s.effect != effect:
                continue
            v = float(s.param.from_fit(p[s.index]))
            if s.segment < 0:
                out[s.param.name] = v
            else:
                latent = out.setdefault(s.param.name, [])
                assert isinstance(latent, list)
                latent.append(v)
        if effect == "slipstream" and "straight_factor" in out:
            out["straight_factor"] = self._as_multipliers(np.asarray(out["straight_factor"]))
        return out

    def _as_multipliers(self, raw: np.ndarray) -> list[float]:
        """Raw straight factors scaled by the common factor that makes them the
        multipliers of h they act as, as far as their bounds allow."""
        lo, hi = next((sl.param.lower, sl.param.upper) for sl in self.latent_slots("slipstream"))
        c = 1.0 / float(_level_mean(raw[None], self.level)[0])
        c = min(max(c, lo / raw.min()), hi / raw.max())
        return np.clip(raw * c, lo, hi).tolist()

    def law(self, p: np.ndarray) -> HLaw:
        """The reference power-law h(V) of vector ``p`` (knee beyond any speed: no knee)."""
        return HLaw(v_ref=self.v_ref, a=float(np.exp(p[0])), b=float(p[1]), knee=NO_KNEE)

    def weights(self, p: np.ndarray) -> tuple[float, float, float]:
        """Mean pad-crown weights of vector ``p``, normalised as eq. 8."""
        w = normalise_weights(np.exp([p[3], p[4], 0.0]), self.model.disc.crown_edges)
        return float(w[0]), float(w[1]), float(w[2])

    def latent_slots(self, effect: str) -> list[Slot]:
        return [s for s in self.slots if s.effect == effect and s.segment >= 0]

    # -------------------------------------------------------------- prediction
    def _col(self, P: np.ndarray, effect: str, name: str) -> np.ndarray | None:
        i = self.index.get((effect, name))
        if i is None:
            return None
        return np.asarray(self.slots[i].param.from_fit(P[:, i]))

    def _latent(self, P: np.ndarray, effect: str, name: str) -> np.ndarray | None:
        """Latent values ``name`` of ``effect`` per member and segment (B, segments)."""
        slots = [s for s in self.latent_slots(effect) if s.param.name == name]
        if not slots:
            return None
        return np.column_stack([s.param.from_fit(P[:, s.index]) for s in slots])

    def _h(self, P: np.ndarray) -> np.ndarray:
        """h per member and step (B, K) — W/(m² K)."""
        a, b = np.exp(P[:, 0]), P[:, 1]
        x = np.abs(self.speed) / self.v_ref
        h = a[:, None] * np.power(x[None, :], b[:, None])
        gain = self._col(P, "h_speed_knee", "gain")
        if gain is not None:
            h = h * knee_factor(self.speed, self.v_ref, KNEE, gain)
        factor = self._latent(P, "slipstream", "straight_factor")
        if factor is not None:
            factor = departures(factor, self.level)
            seg = self.segments.straight[:-1]
            on = seg >= 0
            h[:, on] *= factor[:, seg[on]]
        return h

    def _loads(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Face loads per zone (Z + 1, B, N), the last row outside any zone; zone per step."""
        B = P.shape[0]
        edges = self.model.disc.crown_edges
        base = np.column_stack([np.exp(P[:, 3]), np.exp(P[:, 4]), np.ones(B)])
        balance = self._latent(P, "power_distribution", "zone_balance")
        middle = self._latent(P, "power_distribution", "zone_middle")
        n_z = 0 if balance is None or middle is None else balance.shape[1]
        loads = np.empty((n_z + 1, B, self.model.n_nodes))
        for z in range(n_z + 1):
            w = base.copy()
            if z < n_z:
                w[:, 0] *= np.exp(balance[:, z])
                w[:, 1] *= np.exp(middle[:, z])
                w[:, 2] *= np.exp(-balance[:, z])
            norm = np.stack([normalise_weights(row, edges) for row in w])
            loads[z] = norm @ self._basis
        zone = self.segments.zone[:-1] if n_z else np.full(self.q.size, -1)
        return loads, np.where(zone >= 0, zone, n_z)

    def predict(self, P: np.ndarray) -> np.ndarray:
        """Spot readings (B, K, 4) of B parameter vectors, degC (row 0 from ``T0``)."""
        P = np.atleast_2d(np.asarray(P, float))
        B = P.shape[0]
        h = self._h(P)
        loads, zone_of_step = self._loads(P)
        scale0 = np.exp(P[:, 2])
        kz = self._col(P, "thickness_gradient", "kz_factor")
        kz = np.ones(B) if kz is None else kz
        beta = self._col(P, "friction_temperature", "beta")
        t_mid = self._col(P, "friction_temperature", "t_mid")
        mu = None
        if beta is not None and t_mid is not None:  # mu_ratio of the contact-band face
            mu = (beta, t_mid, MU_SPAN_C, self._contact_face)
        face = self.model.run_readout(np.tile(self.T0, (B, 1)), self.q[:, None] * scale0,
                                      h.T, self.t_amb, kz, loads, zone_of_step, self.H, mu)
        return self._measure(P, face).transpose(1, 0, 2)

    def _measure(self, P: np.ndarray, face: np.ndarray) -> np.ndarray:
        """Pyrometer readings (K + 1, B, 4) of the face temperatures at the spots."""
        tau = self._col(P, "sensor_lag", "tau_s")
        y = face
        if tau is not None:
            alpha = lag_alpha(tau, self.model.dt)[:, None]
            y = np.empty_like(face)
            y[0] = face[0]
            for k in range(1, face.shape[0]):
                y[k] = y[k - 1] + alpha * (face[k] - y[k - 1])
        ratio = self._col(P, "emissivity_error", "ratio")
        if ratio is not None:
            y = pyrometer_reading(y, ratio[None, :, None])
        return y
