"""Convection coefficient as a function of forward speed, h(V) (paper 000 §5.1).

With ``x = V / V_ref`` and the knee ``x_k`` (0.8 in the paper)::

    h = a x^b                                          x <  x_k   (power law)
    h = c0 + c1 u + c2 u^2 + c3 u^3,  u = x - x_k      x >= x_k   (cubic)
    c0 = a x_k^b                                       (continuous at the knee)

Only the value is continuous at the knee, as in the paper: the slope is left free
because the knee is a physical change of regime (above ~0.8 V_ref tyre deformation
exposes the disc to the free stream), which a slope constraint would smooth away.
``h`` is clipped at 0 so an extrapolated cubic can never make the disc gain heat from
cooling air, and held at the cubic's first maximum beyond it: forced convection does not
weaken as the air speeds up, and a cubic that turns down past its data (a knee gain fitted
at its negative bound put h at 157 W/(m² K) at 360 km/h against 308 at 300 on an
independent generator's session) would cool the fastest straights less than the slower
ones.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from brakethermo.config import config_file
from brakethermo.errors import ConfigError, DataError

KMH = 1.0 / 3.6  # m/s per km/h
KIND = "power-cubic"  # the law's form, written in h_law.toml
TABLE_SPEEDS_KMH = np.arange(0.0, 361.0, 10.0)
MIN_SAMPLES_POWER = 5  # below the knee, to fit a and b
MIN_SAMPLES_CUBIC = 100  # above the knee (10 s at 10 Hz) to fit c1..c3; else the tangent


@dataclass(frozen=True)
class HLaw:
    """Power law below the knee, cubic above (module docstring).

    Attributes
    ----------
    v_ref : float — m/s
        Reference speed of the normalisation.
    a : float — W/(m^2 K)
        Power-law factor (h at V_ref on the power branch).
    b : float — dimensionless
        Power-law exponent.
    c : tuple of 3 float — W/(m^2 K)
        Cubic coefficients c1, c2, c3 in ``u = V/V_ref - knee``; c0 follows from continuity.
    knee : float — dimensionless
        Knee ``x_k`` as a fraction of V_ref.
    x_data : float — dimensionless
        The fastest speed, as a fraction of V_ref, of the samples the law was identified
        on (inf: not recorded). Beyond it the law grows as its power branch does, ``h(x) =
        h(x_data) (x / x_data)^b``: a cubic fitted on the few fastest straights of a
        session is no evidence of what h does faster still (an independent generator's
        session to 303 km/h gave a law of 909 W/(m² K) at 350 km/h against a true 327).
    """

    v_ref: float
    a: float
    b: float
    c: tuple[float, float, float] = (0.0, 0.0, 0.0)
    knee: float = 0.8
    x_data: float = math.inf

    def __post_init__(self) -> None:
        if len(self.c) != 3:
            raise ValueError("HLaw needs three cubic coefficients c1, c2, c3")
        for name in ("v_ref", "a", "b", "knee", "x_data"):  # plain floats, also from numpy
            object.__setattr__(self, name, float(getattr(self, name)))
        object.__setattr__(self, "c", tuple(float(v) for v in self.c))
        if not all(math.isfinite(v) for v in (self.v_ref, self.a, self.b, self.knee, *self.c)):
            raise ValueError("HLaw coefficients must be finite")
        if self.v_ref <= 0 or self.a < 0 or self.b < 0 or not 0 < self.knee:
            raise ValueError("HLaw needs v_ref > 0, a >= 0, b >= 0 and knee > 0")
        if not self.x_data > 0:
            raise ValueError("HLaw needs x_data > 0 (inf: not recorded)")

    @classmethod
    def constant(cls, h: float, v_ref: float = 350.0 * KMH) -> HLaw:
        """A speed-independent law ``h(V) = h`` (W/(m^2 K))."""
        return cls(v_ref=v_ref, a=float(h), b=0.0)

    @property
    def c0(self) -> float:
        """Cubic constant term, ``a knee^b`` (continuity at the knee), W/(m^2 K)."""
        return self.a * self.knee**self.b

    @property
    def u_peak(self) -> float:
        """The cubic's first maximum at or beyond the knee, in ``u = x - knee`` (inf when
        it never turns down): the law is held there (module docstring)."""
        c1, c2, c3 = self.c
        if c1 < 0.0 or (c1 == 0.0 and (c2 < 0.0 or (c2 == 0.0 and c3 < 0.0))):
            return 0.0  # falling from the knee on
        # dh/du = c1 + 2 c2 u + 3 c3 u^2: its first sign change from + to - at u > 0
        A, B, C = 3.0 * c3, 2.0 * c2, c1
        if abs(A) <= 1e-12 * max(abs(B), abs(C), 1.0):  # (nearly) a quadratic law
            roots = [-C / B] if B else []
        else:
            disc = B * B - 4.0 * A * C
            if disc < 0.0:
                roots = []
            else:  # the stable pair of roots
                q = -0.5 * (B + math.copysign(math.sqrt(disc), B))
                roots = [q / A] + ([C / q] if q else [])
        turns = sorted(u for u in roots if u > 0.0 and B + 2.0 * A * u < 0.0)  # h'' < 0
        return turns[0] if turns else math.inf

    def __call__(self, v_mps: float | np.ndarray) -> np.ndarray:
        """h in W/(m^2 K) at forward speed ``v_mps`` (m/s; the sign is ignored)."""
        h = self._value(v_mps, self.u_peak)
        if not math.isfinite(self.x_data):
            return h
        x = np.abs(np.asarray(v_mps, dtype=float)) / self.v_ref
        h_data = float(self._value(self.x_data * self.v_ref, self.u_peak))
        return np.where(x > self.x_data, h_data * (np.maximum(x, self.x_data) / self.x_data)
                        ** self.b, h)

    def _value(self, v_mps: float | np.ndarray, u_max: float) -> np.ndarray:
        """h with the cubic held beyond ``u_max`` (inf: the plain cubic, as fitted)."""
        x = np.abs(np.asarray(v_mps, dtype=float)) / self.v_ref
        u = np.minimum(x - self.knee, u_max)
        c1, c2, c3 = self.c
        cubic = self.c0 + u * (c1 + u * (c2 + u * c3))
        power = self.a * np.power(np.minimum(x, self.knee), self.b)
        return np.maximum(np.where(x < self.knee, power, cubic), 0.0)

    # --------------------------------------------------------------------- fit
    @classmethod
    def fit(
        cls,
        v_mps: np.ndarray,
        h: np.ndarray,
        weights: np.ndarray | None = None,
        *,
        v_ref: float,
        knee: float = 0.8,
        robust: bool = True,
    ) -> HLaw:
        """Fit the law to samples of h (e.g. UKF posterior means off the brakes).

        Parameters
        ----------
        v_mps : ndarray — m/s
            Forward speed of each sample.
        h : ndarray — W/(m^2 K)
            Identified convection coefficient.
        weights : ndarray, optional — 1/(W/(m^2 K))^2
            Per-sample weights, e.g. ``1 / h_std**2`` from the filter; NaN or non-positive
            weights drop the sample.
        v_ref : float — m/s
            Reference speed.
        knee : float
            Knee as a fraction of ``v_ref``.
        robust : bool
            Huber loss (scale from the median absolute residual of a plain fit), so the
            noisy low-speed samples (paper §5.1) do not drag the law.

        Notes
        -----
        The power branch is started from a weighted log-log line through the samples
        between 0.05 and 1 times the knee, then all five coefficients (a, b, c1..c3) are
        fitted jointly, so the knee value is shared by both branches. With fewer than
        six samples above the knee the cubic degenerates to the power law's tangent
        (slope-continuous extrapolation) instead of an unsupported cubic.

        Raises
        ------
        DataError
            Too few usable samples below the knee.
        """
        x, y, sw, low = _fit_samples(v_mps, h, weights, v_ref, knee)
        a0, b0 = _power_start(x, y, sw, low)
        with_cubic = np.count_nonzero(x >= knee) >= MIN_SAMPLES_CUBIC

        def unpack(p: np.ndarray) -> HLaw:
            if with_cubic:
                return cls(v_ref=v_ref, a=p[0], b=p[1], c=(p[2], p[3], p[4]), knee=knee)
            # too little data above the knee: continue the power law with its slope
            slope = p[0] * p[1] * knee ** (p[1] - 1.0)
            return cls(v_ref=v_ref, a=p[0], b=p[1], c=(slope, 0.0, 0.0), knee=knee)

        def residual(p: np.ndarray) -> np.ndarray:
            # the plain cubic: held at a maximum, its coefficients would lose their slope
            return sw * (unpack(p)._value(x * v_ref, math.inf) - y)

        p0 = np.array([a0, b0, a0 * b0 * knee ** (b0 - 1.0), 0.0, 0.0][: 5 if with_cubic else 2])
        return unpack(_least_squares(residual, p0, robust))

    # -------------------------------------------------------------------- TOML
    def tabulate(self) -> tuple[np.ndarray, np.ndarray]:
        """Speeds 0..360 km/h in steps of 10 and h there (OUTPUTS.md ``[tabulated]``)."""
        return TABLE_SPEEDS_KMH.copy(), self(TABLE_SPEEDS_KMH * KMH)

    def toml_text(
        self,
        weights: Sequence[float] = (1.0, 1.0, 1.0),
        extra: Mapping[str, Any] | None = None,
        effects: Mapping[str, Mapping[str, Any]] | None = None,
        notes: Mapping[str, str] | None = None,
    ) -> str:
        """The ``h_law.toml`` text (OUTPUTS.md layout); io writes it.

        Parameters
        ----------
        weights : sequence of 3 float
            Pad-crown power weights w_1..w_3 (eq. 6–8), stored in ``[weights]``.
        extra : mapping, optional
            Further identified values (str, bool, int, float, lists of them, or one level
            of nested mappings), stored under ``[extra]``.
        effects : mapping of str to mapping, optional
            Fitted effect parameters, one table ``[effects.<name>]`` per effect
            (OUTPUTS.md); ``estimate --h-law`` uses them.
        notes : mapping of str to str, optional
            Comment lines, each above the ``[extra]`` key or the ``effects.<name>`` table
            it names (what a value's scale is, for a reader of the file).
        """
        said = notes or {}

        def noted(key: str) -> list[str]:
            return [f"# {line}" for line in said[key].splitlines()] if key in said else []

        w = [float(v) for v in weights]
        if len(w) != 3 or not all(math.isfinite(v) and v >= 0 for v in w):
            raise ValueError(f"weights must be three finite values >= 0, got {weights}")
        speeds, hs = self.tabulate()
        lines = [
            "# brakethermo h(V) convection law, paper 000 §5.1. x = V / v_ref, h in W/(m^2 K):",
            "#   h = a * x^b                                   for x < knee",
            "#   h = c[0] + c[1] u + c[2] u^2 + c[3] u^3, u = x - knee, for x >= knee",
            "#   c[0] = a * knee^b (continuous at the knee); h is clipped at 0 and held at",
            *(["#   the cubic's first maximum (it never falls with speed); beyond v_data_kmh,",
               "#   the fastest speed it was identified on, h = h(v_data) (V / v_data)^b."]
              if math.isfinite(self.x_data) else
              ["#   the cubic's first maximum (it never falls with speed)."]),
            f'kind = "{KIND}"',
            f"v_ref_kmh = {_fmt(round(self.v_ref / KMH, 9))}",
            f"v_ref_mps = {_fmt(self.v_ref)}  # exact; v_ref_kmh is for people",
            f"knee = {_fmt(self.knee)}",
            *([f"v_data_kmh = {_fmt(self.x_data * self.v_ref / KMH)}"]
              if math.isfinite(self.x_data) else []),
            "",
            "[power]",
            f"a = {_fmt(self.a)}",
            f"b = {_fmt(self.b)}",
            "",
            "[cubic]",
            f"c = {_fmt([self.c0, *self.c])}",
            "",
            "[weights]  # pad-crown power weights w_1..w_3 (eq. 6-8)",
            f"w = {_fmt(w)}",
            "",
            "[tabulated]",
            f"speed_kmh = {_fmt(list(speeds))}",
            f"h = {_fmt(list(hs))}",
        ]
        if extra:
            lines += ["", "[extra]"]
            tables = {k: v for k, v in extra.items() if isinstance(v, Mapping)}
            for k, v in extra.items():
                if k not in tables:
                    lines += [*noted(k), f"{k} = {_fmt(v)}"]
            for name, table in tables.items():
                lines += ["", f"[extra.{name}]"] + [f"{k} = {_fmt(v)}" for k, v in table.items()]
        for name, table in (effects or {}).items():
            lines += ["", *noted(f"effects.{name}"), f"[effects.{name}]"] + [
                f"{k} = {_fmt(v)}" for k, v in table.items()]
        return "\n".join(lines) + "\n"

    @classmethod
    def from_toml(cls, path: str | Path) -> HLaw:
        """Read the law from an ``h_law.toml`` (:func:`read_h_law` also gives weights)."""
        return read_h_law(path).law


@dataclass(frozen=True)
class HLawRecord:
    """Everything an ``h_law.toml`` holds: the law, crown weights and extra values."""

    law: HLaw
    weights: tuple[float, float, float]
    extra: dict[str, Any] = field(default_factory=dict)
    effects: dict[str, dict[str, Any]] = field(default_factory=dict)


def read_h_law(path: str | Path) -> HLawRecord:
    """Read and validate an ``h_law.toml`` (schema layer of :mod:`brakethermo.config`).

    Raises
    ------
    ConfigError
        Missing keys, wrong types, non-finite values or a cubic that is not continuous
        with the power law at the knee.
    """
    path = Path(path)
    raw = config_file(path)
    law_keys = ("v_ref_kmh", "v_ref_mps", "knee", "power", "cubic")
    if not any(raw.has(k) for k in law_keys):
        raise ConfigError(
            f"not an h law: none of {', '.join(law_keys)} is set (it sets:"
            f" {', '.join(sorted(raw.raw)) or 'none'}); give the h_law.toml that"
            " `brakethermo identify-h` wrote", path=path)
    if raw.has("kind"):
        kind = raw.raw["kind"]
        raw.check(kind == KIND, "kind", f'"{KIND}" (the only law identify-h writes)', kind)
    if raw.has("v_ref_mps"):
        v_ref = raw.number("v_ref_mps", positive=True)
        if raw.has("v_ref_kmh"):  # both written: an edit of one alone must not go unseen
            kmh = raw.number("v_ref_kmh", positive=True)
            raw.check(math.isclose(kmh * KMH, v_ref, rel_tol=1e-3), "v_ref_kmh",
                      f"{v_ref / KMH:.6g} km/h, as v_ref_mps = {v_ref:.6g} m/s says (edit"
                      " both, or delete one)", kmh)
    else:
        v_ref = raw.number("v_ref_kmh", positive=True) * KMH
    knee = raw.number("knee", positive=True, hi=10.0)
    power = raw.table("power")
    a, b = power.number("a", lo=0.0), power.number("b", lo=0.0, hi=10.0)
    cubic = raw.table("cubic")
    c = cubic.numbers("c", length=4)
    weights = raw.table("weights", {})
    w = weights.numbers("w", [1.0, 1.0, 1.0], length=3, lo=0.0)
    weights.check(sum(w) > 0, "w", "three weights >= 0, not all 0", w)
    v_data = (raw.number("v_data_kmh", positive=True, hi=1000.0) if "v_data_kmh" in raw.raw
              else math.inf)
    law = HLaw(v_ref=v_ref, a=a, b=b, c=(c[1], c[2], c[3]), knee=knee,
               x_data=v_data * KMH / v_ref)
    cubic.check(
        math.isclose(c[0], law.c0, rel_tol=1e-6, abs_tol=1e-9), "c",
        f"c[0] = a * knee^b = {law.c0} (continuity at the knee)", c[0],
    )
    extra = raw.table("extra", {}).raw
    effects = raw.table("effects", {}).raw
    for name, table in effects.items():
        if not isinstance(table, dict):
            raise raw.error(f"effects.{name}", "a table [effects.<name>] of parameters", table)
    return HLawRecord(law=law, weights=(w[0], w[1], w[2]), extra=extra, effects=effects)


def _fit_samples(
    v_mps: np.ndarray, h: np.ndarray, weights: np.ndarray | None, v_ref: float, knee: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The usable samples of :meth:`HLaw.fit`, checked.

    Parameters
    ----------
    v_mps : ndarray — m/s, forward speed.
    h : ndarray — W/(m^2 K), identified convection coefficient.
    weights : ndarray, optional — 1/(W/(m^2 K))^2, NaN or non-positive drops the sample.
    v_ref : float — m/s, reference speed.
    knee : float — knee as a fraction of ``v_ref``.

    Returns
    -------
    x : ndarray — V / V_ref of the kept samples.
    y : ndarray — W/(m^2 K), their h.
    sw : ndarray — square roots of the weights normalised to mean 1.
    low : ndarray of bool — the samples that start the power branch.

    Raises
    ------
    DataError
        Too few usable samples below the knee.
    """
    v = np.abs(np.asarray(v_mps, dtype=float)).ravel()
    y = np.asarray(h, dtype=float).ravel()
    w = np.ones_like(y) if weights is None else np.asarray(weights, dtype=float).ravel()
    if not v.shape == y.shape == w.shape:
        raise ValueError("v_mps, h and weights must have the same length")
    keep = np.isfinite(v) & np.isfinite(y) & np.isfinite(w) & (w > 0)
    x, y, sw = v[keep] / v_ref, y[keep], np.sqrt(w[keep] / np.mean(w[keep]))
    low = (x < knee) & (x > 0.05 * knee) & (y > 0)
    if np.count_nonzero(low) < MIN_SAMPLES_POWER:
        raise DataError(
            f"only {np.count_nonzero(low)} usable h samples below {knee:.2f} V_ref; the law"
            f" needs at least {MIN_SAMPLES_POWER} — use a session with more off-brake running"
        )
    return x, y, sw, low


def _power_start(
    x: np.ndarray, y: np.ndarray, sw: np.ndarray, low: np.ndarray
) -> tuple[float, float]:
    """Start of the power branch, a (W/(m^2 K)) and b: a weighted log-log line through the
    ``low`` samples of :func:`_fit_samples`."""
    A = np.stack([np.ones(np.count_nonzero(low)), np.log(x[low])], axis=1)
    coef = np.linalg.lstsq(A * sw[low, None], np.log(y[low]) * sw[low], rcond=None)[0]
    return math.exp(coef[0]), float(np.clip(coef[1], 0.0, 5.0))


def _least_squares(
    residual: Callable[[np.ndarray], np.ndarray], p0: np.ndarray, robust: bool
) -> np.ndarray:
    """Coefficients (a, b[, c1..c3]) minimising ``residual`` from ``p0``, a >= 0 and
    0 <= b <= 5; ``robust`` refits with a Huber loss scaled by the first fit's residuals."""
    lo = [0.0, 0.0] + [-np.inf] * (len(p0) - 2)
    hi = [np.inf, 5.0] + [np.inf] * (len(p0) - 2)
    p0 = np.clip(p0, np.array(lo) + 1e-9, np.array(hi) - 1e-9)
    # here, not at the top: every command reads a law, only identify-h fits one
    # (scipy.optimize is 0.25 s of import)
    from scipy.optimize import least_squares

    sol = least_squares(residual, p0, bounds=(lo, hi), x_scale="jac")
    if robust:
        r = residual(sol.x)
        scale = 1.4826 * float(np.median(np.abs(r - np.median(r))))
        if scale > 0:
            sol = least_squares(
                residual, sol.x, bounds=(lo, hi), loss="huber", f_scale=1.345 * scale,
                x_scale="jac",
            )  # fmt: skip
    return sol.x


def _fmt(value: Any) -> str:
    """TOML literal of a scalar, string or list (floats round-trip exactly)."""
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        v = float(value)
        if not math.isfinite(v):
            raise ValueError(f"cannot store non-finite value {v} in TOML")
        return repr(v)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, Sequence | np.ndarray):
        return "[" + ", ".join(_fmt(v) for v in value) + "]"
    raise TypeError(f"cannot store {type(value).__name__} in h_law.toml")
