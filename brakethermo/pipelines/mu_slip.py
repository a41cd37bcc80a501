"""``mu-slip``: the tyre μ–slip peak of a braking-to-lock rig session (Rudd 2011, and beyond).

Slip from the speeds (or the rig's ``slip_ratio``), μ = drag / normal force; the ramp
from free rolling up to wheel lock is found in the log; the EKF and Levenberg–Marquardt
fits of the two-parameter curve run on its points, then the curve families that can
fit a real tyre, the best chosen by held-out error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.ndimage import median_filter

from brakethermo.errors import ConfigError, DataError
from brakethermo.estimation.consistency import nis_consistency, variance_scale
from brakethermo.io.load import load_session
from brakethermo.io.plausibility import ratio_cause
from brakethermo.io.session import Session
from brakethermo.models.mu_slip import (
    FamilyFit,
    RelaxationChoice,
    best_fit,
    choose_relaxation,
    fit_families,
    rudd_ekf,
    rudd_lm,
)
from brakethermo.numeric import noise_std, rmse, true_runs
from brakethermo.pipelines.rig_checks import frozen_stretches
from brakethermo.results.mu_slip import MuSlipResult

CHANNELS = ("vehicle_speed", "wheel_speed", "drag_force", "normal_force", "slip_ratio",
            "friction_coefficient")
RADIUS_FACTS = ("wheel_radius_m", "rolling_radius_m")
LOCK_SLIP = 0.95  # slip at which the wheel counts as locked
RADIUS_RANGE_M = (0.05, 2.0)  # m: a wheel radius (--radius's range)


@dataclass(frozen=True)
class MuSlipOptions:
    """Options of the EKF start and the ramp search.

    Attributes
    ----------
    mu_range : (float, float) — expected range of the peak μ, – (paper: 0.1–1.0 for cars).
    slip_range : (float, float) — expected range of the peak slip, – (paper: 0.1–0.2).
    inflation : float — constant factor on the noise std (paper: 3).
    radius_m : float or None — wheel radius, m, when the session does not give it.
    points : bool — the file is a set of (slip, μ) points (the paper's case: no time ramp),
        every sample with 0 < slip ≤ 1 is used, in file order.
    """

    mu_range: tuple[float, float] = (0.1, 1.5)
    slip_range: tuple[float, float] = (0.05, 0.3)
    inflation: float = 3.0
    radius_m: float | None = None
    points: bool = False

    def __post_init__(self) -> None:
        for name, option, (lo, hi), top in (("peak μ", "--mu-max", self.mu_range, 3.0),
                                            ("peak slip", "--slip-max", self.slip_range, 1.0)):
            if not 0.0 < lo < hi <= top:
                raise ConfigError(f"{option} {hi:g}: give the high end of the expected {name}"
                                  f" above its low end {lo:g} and at most {top:g}")
        if not 1.0 <= self.inflation < float("inf"):
            raise ConfigError(f"inflation must be at least 1, got {self.inflation}")
        if self.radius_m is not None and not (RADIUS_RANGE_M[0] <= self.radius_m
                                              <= RADIUS_RANGE_M[1]):
            raise ConfigError(f"--radius {self.radius_m} m is not a wheel radius; give metres,"
                              " 0.05 to 2 (a tyre rig's wheel is some 0.2-0.4 m)")


def slip_and_mu(
    session: Session, radius_m: float | None
) -> tuple[np.ndarray, np.ndarray, float | None]:
    """Slip (–) and μ (–) on the session grid; the radius used (None with ``slip_ratio``).

    μ is the drag over the normal force, or the rig's own ``friction_coefficient`` when the
    file carries that and not both forces (a (slip, μ) point set as the paper gives one).
    """
    if _mu_logged(session):
        mu = session.values("friction_coefficient").astype(float)
    else:
        session.require("drag_force", "normal_force")
        Fz = session.values("normal_force")
        if np.nanmax(np.abs(Fz)) <= 0.0:
            raise DataError(
                "normal force is zero throughout", path=session.path, channel="normal_force"
            )
        with np.errstate(divide="ignore", invalid="ignore"):
            mu = session.values("drag_force") / Fz
        mu[np.abs(Fz) < 0.05 * np.nanmax(np.abs(Fz))] = np.nan
    if session.has("slip_ratio"):
        return session.values("slip_ratio"), mu, None
    session.require("vehicle_speed", "wheel_speed")
    if radius_m is None:
        for key in RADIUS_FACTS:
            if key in session.metadata:
                try:
                    radius_m = float(session.metadata[key])
                except ValueError:
                    raise DataError(
                        f"session fact {key}={session.metadata[key]!r} is not a number; fix it"
                        " or pass --radius",
                        path=session.path,
                    ) from None
                break
    if radius_m is None:
        radius_m = free_rolling_radius(session, mu)
    if radius_m is None:
        raise DataError(
            "no wheel radius: the session has no slip_ratio channel, no fact"
            f" {' or '.join(RADIUS_FACTS)} and too little free rolling (μ about 0) to take"
            " it from the speeds; pass --radius METRES",
            path=session.path,
        )
    V = session.values("vehicle_speed")
    with np.errstate(divide="ignore", invalid="ignore"):
        slip = (V - session.values("wheel_speed") * radius_m) / V
    slip[V < 1.0] = np.nan  # slip is undefined near standstill
    return slip, mu, radius_m


def free_rolling_radius(session: Session, mu: np.ndarray) -> float | None:
    """The wheel's rolling radius (m) from its free rolling: the median of V / ω where
    μ is about nil (no brake torque: slip nil) and the carriage moves (V > 1 m/s), at
    least :data:`MIN_FREE_SAMPLES` of them; None when there are fewer, or the ratio is no
    wheel radius (:data:`RADIUS_RANGE_M`). A session without a radius fact was refused
    while its own speeds gave 0.300 m (new-user test)."""
    r, n = _speed_ratio(session, np.abs(mu) < FREE_MU)
    if n < MIN_FREE_SAMPLES:
        return None
    return r if RADIUS_RANGE_M[0] <= r <= RADIUS_RANGE_M[1] else None


def _speed_ratio(session: Session, where: np.ndarray) -> tuple[float, int]:
    """The median of V / ω (m) over ``where`` with the carriage moving (V >= 1 m/s) and
    the wheel turning, and how many samples it took (NaN over none)."""
    V, w = session.values("vehicle_speed"), session.values("wheel_speed")
    ok = where & np.isfinite(V) & np.isfinite(w) & (V >= 1.0) & (np.abs(w) > 1e-6)
    return (float(np.median(V[ok] / w[ok])) if ok.any() else math.nan), int(ok.sum())


def _smoothed(session: Session, slip: np.ndarray) -> np.ndarray:
    """Slip through a 10 ms median filter (odd, at least 3 samples), NaN as 0: the ramp's
    shape without single-sample spikes."""
    w = max(3, round(0.01 / session.dt) | 1)
    return median_filter(np.nan_to_num(slip, nan=0.0), size=w, mode="nearest")


def find_ramp(session: Session, slip: np.ndarray) -> tuple[int, int]:
    """Index range [start, end) of the first braking ramp from free rolling: up to wheel
    lock, or, without a lock, up to the deepest slip of that braking.

    Raises
    ------
    DataError
        No braking in the session.
    """
    smooth = _smoothed(session, slip)
    locked = np.flatnonzero(smooth >= LOCK_SLIP)
    if locked.size:
        lock = int(locked[0])
    else:
        braking = np.flatnonzero(smooth > 0.02)
        if braking.size == 0:
            raise DataError("no braking found (slip never exceeds 0.02); give a session of"
                            " a brake ramp, or a (slip, μ) point set with --points",
                            path=session.path)
        # the first braking event: up to where its slip is deepest
        gap = np.flatnonzero(np.diff(braking) > 1)
        last = braking[gap[0]] if gap.size else braking[-1]
        lock = int(braking[0] + np.argmax(smooth[braking[0]: last + 1]))
    before = smooth[:lock]
    free = float(np.percentile(before, 5)) if before.size else 0.0
    rolling = np.flatnonzero(before <= free + 0.01)
    start = int(rolling[-1]) + 1 if rolling.size else 0
    if lock - start < 20:
        raise DataError(
            f"the braking ramp to lock holds only {lock - start} samples; log faster or brake"
            " more slowly",
            path=session.path,
        )
    return start, lock


def later_ramp_s(session: Session, slip: np.ndarray, lock: int) -> float | None:
    """Time of a second braking ramp after the first one's lock (slip back to free rolling
    and held there :data:`SETTLED_S`, then past :data:`SECOND_RAMP_SLIP` again), s; None
    when the log holds one. A wheel let go from lock spins up with a swing of its own (an
    independent rig's: slip -0.73, then +0.45 within 60 ms), no braking."""
    smooth = _smoothed(session, slip)
    after = np.abs(smooth[lock:]) <= FREE_ROLLING_SLIP
    hold = max(1, round(SETTLED_S / session.dt))
    runs = [a for a, b in true_runs(after) if b - a >= hold]
    if not runs:
        return None
    settled = lock + runs[0]
    again = np.flatnonzero(smooth[settled:] > SECOND_RAMP_SLIP)
    return None if again.size == 0 else float(session.time[settled + again[0]])


SECOND_RAMP_SLIP = 0.1  # –, slip a later braking must pass to count as another ramp
FREE_ROLLING_SLIP = 0.02  # –, |slip| of a wheel rolling free
SETTLED_S = 0.3  # s, free rolling held this long ends the first ramp's release
MU_PLAUSIBLE = (0.05, 3.0)  # peak friction of any tyre on any surface, –


def _mu_logged(session: Session) -> bool:
    """Whether μ comes from the file's own ``friction_coefficient`` (no pair of forces)."""
    return session.has("friction_coefficient") and not (
        session.has("drag_force") and session.has("normal_force"))


def _check_plausible_mu(mu: np.ndarray, session: Session) -> None:
    """μ through the ramp must look like a tyre's: positive while the wheel is braked,
    peaking between ice and a racing slick, and moving with the slip; anything else is a
    sign, unit or sensor fault, named here rather than fitted."""
    lo, hi = MU_PLAUSIBLE
    peak, spread = float(np.percentile(np.abs(mu), 95)), float(np.ptp(np.percentile(mu, [5, 95])))
    logged = _mu_logged(session)
    what, channel = (("μ (friction_coefficient)", "friction_coefficient") if logged
                     else ("μ = drag_force / normal_force", "drag_force"))
    if np.median(mu) < 0.0:
        raise DataError(
            f"{what} is negative through the braking ramp (median"
            f" {float(np.median(mu)):.3f}): " + ("it is logged with the wrong sign" if logged
            else "one of the two has the wrong sign; braking drag and the normal load are"
                 " both positive"), path=session.path, channel=channel)
    if peak > hi:
        raise DataError(
            f"{what} reaches {peak:.3g} in the braking ramp, beyond any tyre (at most about"
            f" {hi:g}): " + ("in per cent? label the column '[%]'" if logged else
                             "check the two channels' units (kN logged as N?)"),
            path=session.path, channel=channel)
    if peak < lo or spread < 0.5 * lo:
        raise DataError(
            f"{what} stays at {float(np.median(mu)):.3g}"
            f" ({spread:.3g} between its 5th and 95th percentile) while the wheel slips to"
            " lock: " + ("the channel is zero, stuck or in the wrong unit" if logged else
                         "the drag or load cell is zero, stuck or in the wrong unit"),
            path=session.path, channel=channel)


def _check_past_peak(best: FamilyFit, s: np.ndarray, session: Session) -> None:
    """A peak needs points on both sides: refuse a curve still rising at the largest slip."""
    s_peak = float(best.slip_peak)
    beyond = int(np.sum(s > 1.2 * s_peak))
    if not np.isfinite(s_peak) or beyond < 3:
        where = (f"peaks at slip {s_peak:.3f} and only {beyond} point(s) lie beyond it"
                 if np.isfinite(s_peak) and s_peak <= 1.0 else "is still rising at the"
                 " largest slip")
        raise DataError(
            f"the slip never passes the μ peak: the best curve ({best.name}) {where} (largest"
            f" slip {float(np.max(s)):.3f}); brake further, toward wheel lock",
            path=session.path)


@dataclass(frozen=True)
class RampPoints:
    """The (slip, μ) points of the braking ramp (or of a point set) and where they came from."""

    session: Session
    time: np.ndarray  # s
    slip: np.ndarray  # -
    mu: np.ndarray  # -
    radius_m: float | None
    ramp_s: tuple[float, float]
    warnings: tuple[str, ...] = ()
    # the whole ramp in time order (slip bridged over its gaps) and where the points sit in
    # it: a lag runs over the ramp, not over the points kept (a dropped force leaves holes)
    ramp_time: np.ndarray | None = None
    ramp_slip: np.ndarray | None = None
    kept: np.ndarray | None = None


FREE_SLIP = (0.02, 0.06)  # |slip| in free rolling: said above the first, refused above the second
FREE_MU = 0.05  # |μ| below this: no brake torque, the wheel rolls free
MIN_FREE_SAMPLES = 20  # free-rolling samples before the ramp needed to judge the slip there


def free_rolling_check(session: Session, slip: np.ndarray, mu: np.ndarray, start: int,
                       radius_m: float | None, given: bool) -> list[str]:
    """Slip where the wheel rolls free — before the ramp and with μ about nil (no brake
    torque; a session that starts braking has no such samples and is not judged) — must
    be near nil: a radius a few per cent off shows there first and moves every slip of the
    ramp. Returns the warnings; DataError beyond :data:`FREE_SLIP`'s upper bound, naming
    the radius the free-rolling speeds give."""
    rolling = np.zeros(slip.size, bool)
    rolling[:start] = True
    rolling &= np.isfinite(slip) & np.isfinite(mu) & (np.abs(mu) < FREE_MU)
    if rolling.sum() < MIN_FREE_SAMPLES:
        return []
    s0 = float(np.median(slip[rolling]))
    if abs(s0) <= FREE_SLIP[0]:
        return []
    if radius_m is None:
        channel, said = "slip_ratio", " in the slip_ratio channel"
        fix = "check the slip channel's zero and unit"
    else:
        channel, said, fix = _radius_cause(session, rolling, radius_m, given)
    text = (f"in free rolling before the ramp (μ about 0) the slip is {s0:+.3f}, not about"
            f" 0{said}: every slip of the ramp moves with it")
    if abs(s0) > FREE_SLIP[1]:
        raise DataError(f"{text}; {fix}", path=session.path, channel=channel)
    return [text]


def _radius_cause(session: Session, rolling: np.ndarray, radius_m: float, given: bool
                  ) -> tuple[str, str, str]:
    """The channel to name, what was used and the likely fix, when the slip computed with
    ``radius_m`` (m; ``given``: by --radius, else the session's fact) is not nil in free
    rolling: the radius the free-rolling speeds give (m) against it. A radius the user
    typed is the first suspect, before a unit the speeds' ratio may resemble."""
    r_free, n = _speed_ratio(session, rolling)
    speeds = f"; the free-rolling speeds give {r_free:.3f} m" if n else ""
    said = (f" with the wheel radius {radius_m:g} m"
            f" ({'--radius' if given else 'the session fact'}){speeds}")
    cause = ratio_cause(radius_m / r_free, "vehicle_speed", "wheel_speed", "the radius")
    if given:
        unit = ("check the units of vehicle_speed and wheel_speed"
                if cause.startswith("check the units") else cause)
        fact = next((k for k in RADIUS_FACTS if k in session.metadata), None)
        instead = [f"run without it (the session's {fact})"] if fact else []
        instead += [f"give --radius {r_free:.3f}"] if n else []
        return ("wheel_speed", said, f"the given --radius {radius_m:g} m may be wrong: "
                + " or ".join(instead or ["check it"]) + f"; else {unit}")
    fix = "fix the radius" if cause.startswith("check the units") else cause
    return ("vehicle_speed" if cause.startswith("vehicle_speed") else "wheel_speed", said, fix)


MAX_FROZEN_SHARE = 0.2  # of a ramp's samples lost to a frozen force: the curve is not there


def _point_table(path: str | Path, aliases: Path | None) -> bool:
    """Whether the file reads as a (slip, μ) point table (every column a channel)."""
    try:
        table = load_session(path, rate_hz=None, channels=CHANNELS, aliases=aliases,
                             indexed=True)
        slip_and_mu(table, None)
    except (DataError, ConfigError):
        return False
    return True


def ramp_points(path: str | Path, options: MuSlipOptions, *, aliases: Path | None = None
                ) -> RampPoints:
    """Read a session and keep the points ``mu-slip`` fits: the first braking ramp to lock
    (or every point of a point set), 0 < slip <= 1, μ plausible (DataError otherwise)."""
    try:
        session = load_session(path, rate_hz=None, channels=CHANNELS, aliases=aliases,
                               indexed=options.points)
        slip, mu, radius = slip_and_mu(session, options.radius_m)
    except DataError:
        if not options.points and _point_table(path, aliases):
            raise DataError("holds slip and μ columns and no time series: a (slip, μ) point"
                            " table, as the paper's 40 points; pass --points",
                            path=Path(path)) from None
        raise
    warnings = _radius_warning(session, options.radius_m, radius)
    frozen, where = np.zeros(mu.size, bool), []
    for channel in ("drag_force", "normal_force"):
        if session.has(channel) and not _mu_logged(session):
            mask, said = frozen_stretches(session, channel, "N")
            if said:
                frozen |= mask
                where.append(said.split(" where ")[0])
                warnings.append(f"{said}; the (slip, μ) points there are left out")
    mu[frozen] = np.nan  # a dropped-out force is not a point of the curve
    if options.points:
        start, lock = 0, slip.size
    else:
        start, lock = find_ramp(session, slip)
        warnings += free_rolling_check(session, slip, mu, start, radius,
                                       options.radius_m is not None)
        if (t2 := later_ramp_s(session, slip, lock)) is not None:
            warnings.append(f"the log holds another braking ramp from t = {t2:.1f} s; only the"
                            " first (to its lock) is analysed here: split the log to analyse"
                            " the other")
    sl = slice(start, lock)
    if frozen[sl].mean() > MAX_FROZEN_SHARE:
        raise DataError(
            f"{100 * frozen[sl].mean():.0f} % of the braking ramp's samples come from a force"
            f" sensor that froze or dropped out ({'; '.join(where)}): the curve is not"
            " measured there; fix the sensor's logging or record the ramp again",
            path=session.path)
    ok = np.isfinite(slip[sl]) & np.isfinite(mu[sl]) & (slip[sl] > 0.0) & (slip[sl] <= 1.0)
    t, s, m = session.time[sl][ok], slip[sl][ok], mu[sl][ok]
    if options.points:
        # a point table has no time order: the EKF's one pass and the noise estimate from
        # neighbouring points both want the points along the slip axis, as a ramp gives them
        order = np.argsort(s, kind="stable")
        t, s, m = t[order], s[order], m[order]
    if s.size < 10:
        beyond = np.isfinite(slip[sl]) & (slip[sl] > 1.0) & (slip[sl] <= 100.0)
        hint = ("; most slips lie between 1 and 100: in per cent? label the column '[%]'"
                if beyond.sum() > 0.5 * np.isfinite(slip[sl]).sum() else "")
        raise DataError(f"only {s.size} (slip, μ) points with 0 < slip <= 1; a curve needs"
                        f" at least 10{hint}", path=session.path)
    _check_plausible_mu(m, session)
    span = (float(session.time[start]), float(session.time[min(lock, slip.size - 1)]))
    if options.points:
        return RampPoints(session, t, s, m, radius, span, tuple(warnings))
    t_ramp, s_ramp = session.time[sl], slip[sl]
    fin = np.isfinite(s_ramp)
    return RampPoints(session, t, s, m, radius, span, tuple(warnings), t_ramp,
                      np.interp(t_ramp, t_ramp[fin], s_ramp[fin]), np.flatnonzero(ok))


TYRE_RIG_RADIUS_M = (0.15, 0.6)  # m: the wheels tyre rigs run, scooter to truck
KMH = 3.6  # km/h per m/s


def _implausible_radius(radius_m: float) -> list[str]:
    """A warning when the radius the free-rolling speeds give is no tyre rig's wheel.

    A log whose carriage speed is in km/h labelled m/s gives 3.6x the radius: 1.081 m
    was taken, no word, for a 0.300 m wheel.

    Parameters
    ----------
    radius_m : float
        The radius taken, m.

    Returns
    -------
    list of str
        One sentence naming the likely unit slip and the radius it would give, or nothing.
    """
    lo, hi = TYRE_RIG_RADIUS_M
    if lo <= radius_m <= hi:
        return []
    kmh = (f"; a vehicle_speed in km/h labelled m/s gives 3.6x the radius (that would be"
           f" {radius_m / KMH:.3f} m): check the speed channel's unit" if
           lo <= radius_m / KMH <= hi else
           f"; a vehicle_speed in m/s labelled km/h gives 1/3.6 of it (that would be"
           f" {radius_m * KMH:.3f} m): check the speed channel's unit" if
           lo <= radius_m * KMH <= hi else
           "; check the units of vehicle_speed (m/s) and wheel_speed (rad/s)")
    return [f"the wheel radius the free-rolling speeds give, {radius_m:.3f} m, is outside a"
            f" tyre rig's {lo:g}-{hi:g} m{kmh}, or pass --radius"]


def _radius_warning(session: Session, radius_m: float | None, used: float | None
                    ) -> list[str]:
    """--radius beside a session fact that says otherwise: the option wins, and says so;
    a radius taken from the free-rolling speeds (``used``, neither given nor a fact) is
    said too."""
    if radius_m is not None and session.has("slip_ratio"):
        return [f"--radius {radius_m:g} m is not used: the session logs slip_ratio, which"
                " needs no radius"]
    fact = next((k for k in RADIUS_FACTS if k in session.metadata), None)
    if radius_m is None and fact is None and used is not None:
        return [f"no wheel radius in the session: taken from its free-rolling speeds,"
                f" {used:.3f} m (the median of V / ω where μ is about 0); pass --radius to"
                " set it", *_implausible_radius(used)]
    if radius_m is None or fact is None:
        return []
    try:
        logged = float(session.metadata[fact])
    except ValueError:
        return []
    if abs(radius_m - logged) <= 0.02 * logged:
        return []
    return [f"--radius {radius_m:g} m replaces the session's {fact} = {logged:g} m"
            f" ({100 * (radius_m / logged - 1):+.0f} %): slip is computed with --radius"]


def result_warnings(options: MuSlipOptions, ekf_peak: np.ndarray, best: FamilyFit,
                    scale: float) -> list[str]:
    """The result against what a tyre can do and what the options expected."""
    out = []
    mu_e, s_e = float(ekf_peak[0]), float(ekf_peak[1])
    if not (0.0 < mu_e <= MU_PLAUSIBLE[1] and 0.0 < s_e < 1.0):
        out.append(f"the EKF's one pass ended at peak μ {mu_e:.3g}, slip {s_e:.3g}, which no"
                   " tyre has (its start, --mu-max / --slip-max, is far from this tyre); the"
                   f" reported peak is the {best.name} fit's")
    (m_lo, m_hi), (s_lo, s_hi) = options.mu_range, options.slip_range
    if not (m_lo <= best.mu_peak <= m_hi and s_lo <= best.slip_peak <= s_hi):
        out.append(f"the peak (μ {best.mu_peak:.3f}, slip {best.slip_peak:.3f}) lies outside the"
                   f" expected range the EKF starts from (μ {m_lo:g}–{m_hi:g}, slip"
                   f" {s_lo:g}–{s_hi:g}): widen --mu-max / --slip-max to start it nearer")
    if scale > 4.0:
        out.append(f"the EKF's innovations are {scale:.1f}x its noise (mean NIS): the"
                   " two-parameter curve does not follow these points; its band is widened"
                   " by that, the reported peak is the best family's")
    return out


def mu_slip(
    path: str | Path, options: MuSlipOptions | None = None, *, aliases: Path | None = None
) -> MuSlipResult:
    """Run the whole ``mu-slip`` pipeline on one session file."""
    options = options or MuSlipOptions()
    ramp = ramp_points(path, options, aliases=aliases)
    session, t, s, m = ramp.session, ramp.time, ramp.slip, ramp.mu
    relax = None
    if ramp.kept is not None and session.has("vehicle_speed"):
        # the force lags the slip on a ramp: every estimator sees the slip aligned with it
        speed = np.interp(ramp.ramp_time, session.time, session.values("vehicle_speed"))
        if np.isfinite(speed).all():
            relax, s = choose_relaxation(ramp.ramp_time, ramp.ramp_slip, m, speed, ramp.kept)
    sigma = noise_std(m)
    (m_lo, m_hi), (s_lo, s_hi) = options.mu_range, options.slip_range
    x0 = np.array([m_hi, s_hi])  # paper: start at the high end, covariance covering the range
    P0 = np.diag([(m_hi - m_lo) ** 2, (s_hi - s_lo) ** 2])
    ekf = rudd_ekf(s, m, sigma, x0, P0, inflation=options.inflation)
    # over-confident innovations (the two-parameter curve's shape error): the reported
    # spread widened by their mean NIS, as every rig observer's
    consistency = nis_consistency(ekf.nis, ekf.n_obs, ekf.innovation)
    scale = variance_scale(consistency)
    if scale > 1.0:
        ekf = replace(ekf, var_filt=ekf.var_filt * scale, P_filt=ekf.P_filt * scale)
    fams = fit_families(s, m, spline=True)
    best = best_fit(fams)
    _check_past_peak(best, s, session)
    return MuSlipResult(
        session=session,
        time=t,
        slip=s,
        mu=m,
        sigma=sigma,
        ekf=ekf,
        lm_one_pass=rudd_lm(s, m, x0, 1),
        lm_converged=rudd_lm(s, m, x0, None),
        families=fams,
        best=best,
        radius_m=ramp.radius_m,
        ramp_s=ramp.ramp_s,
        inflation=options.inflation,
        ekf_noise_scale=scale,
        ekf_consistency=consistency,
        points=options.points,
        relaxation=relax,
        warnings=(*session.warnings, *ramp.warnings,
                  *result_warnings(options, ekf.x_filt[-1], best, scale)),
    )


# held-out RMSE within this fraction of the best family's: no shape error worth the name
SAME_SHAPE = 0.05


def shape_mismatch(result: MuSlipResult) -> dict[str, object]:
    """How far the two-parameter curve is from the best family, in words and figures."""
    rudd = next(f for f in result.families if f.name == "rudd")
    best = result.best
    d_mu = 100.0 * (rudd.mu_peak / best.mu_peak - 1.0) if best.mu_peak else float("nan")
    d_s = rudd.slip_peak - best.slip_peak
    if best.name == "rudd":
        words = (
            "the two-parameter curve fits as well as any family on held-out points;"
            " its peak is the answer"
        )
    elif rudd.heldout_rmse <= best.heldout_rmse * (1.0 + SAME_SHAPE):
        words = (
            f"the two-parameter curve fits as well as the best family, {best.name}, on"
            f" held-out points (RMSE {rudd.heldout_rmse:.4f} against {best.heldout_rmse:.4f});"
            f" their peaks differ by {d_mu:+.1f} % in μ and {d_s:+.3f} in slip"
        )
    else:
        words = (
            f"the two-parameter curve has the wrong shape for this tyre: its held-out RMSE is"
            f" {rudd.heldout_rmse:.4f} against {best.heldout_rmse:.4f} for {best.name}, and its"
            f" peak μ is {abs(d_mu):.1f} % {'above' if d_mu > 0 else 'below'} and its peak slip"
            f" {abs(d_s):.3f} {'above' if d_s > 0 else 'below'} the {best.name} peak"
        )
    return {
        "best_family": best.name,
        "rudd_mu_peak_minus_best_pct": d_mu,
        "rudd_slip_peak_minus_best": d_s,
        "rudd_heldout_rmse": rudd.heldout_rmse,
        "best_heldout_rmse": best.heldout_rmse,
        "words": words,
    }


# families within this factor of the best held-out RMSE: the shapes the data still allow
PLAUSIBLE_SHAPE = 2.0


def _allowed(families: list[FamilyFit]) -> list[FamilyFit]:
    """The families the held-out points still allow: held-out RMSE within
    :data:`PLAUSIBLE_SHAPE` of the best's, with a peak a tyre can have (a curve still
    rising at slip 1e13 is no shape the data allow, whatever its RMSE)."""
    best = min(families, key=lambda f: f.heldout_rmse)
    return [f for f in families
            if f.heldout_rmse <= PLAUSIBLE_SHAPE * best.heldout_rmse
            and 0.0 < f.slip_peak <= 1.0 and 0.0 < f.mu_peak <= MU_PLAUSIBLE[1]]


def peak_band(result: MuSlipResult) -> dict[str, float]:
    """1σ of the reported peak that admits the curve's form: the RMS distance of the peaks
    of the families the held-out points still allow (:func:`_allowed`) — on the aligned
    slip and on the slip as logged, when the two differ — from the best's, and never below
    the EKF's own (fit) standard deviation. One family's fit noise is far smaller than
    what another plausible shape moves the peak by (on a brush tyre the EKF's 0.005
    against 0.15 off)."""
    best = result.best
    relax = result.relaxation
    aligned = _allowed(result.families)
    logged = (_allowed(relax.as_logged) if relax is not None and relax.length_m > 0.0
              else [])
    allowed = aligned + logged or [best]
    sd_fit = np.sqrt(np.maximum(result.ekf.var_filt[-1], 0.0))
    mu_sd = rmse([f.mu_peak for f in allowed], best.mu_peak)
    slip_sd = rmse([f.slip_peak for f in allowed], best.slip_peak)
    return {"mu_std": max(mu_sd, float(sd_fit[0])), "slip_std": max(slip_sd, float(sd_fit[1])),
            "families": [f.name for f in aligned] or [best.name],
            "families_as_logged": [f.name for f in logged]}


def result_frame(res: MuSlipResult) -> pd.DataFrame:
    """The ``mu_slip.parquet`` table: the points used and the EKF track."""
    x, v = res.ekf.x_filt, res.ekf.var_filt
    return pd.DataFrame(
        {
            "time": res.time,
            "slip": res.slip,
            "mu": res.mu,
            "ekf_mu_peak": x[:, 0],
            "ekf_mu_peak_std": np.sqrt(v[:, 0]),
            "ekf_slip_peak": x[:, 1],
            "ekf_slip_peak_std": np.sqrt(v[:, 1]),
        }
    )


UNITS = {
    "time": "s",
    "slip": "-",
    "mu": "-",
    "ekf_mu_peak": "-",
    "ekf_mu_peak_std": "-",
    "ekf_slip_peak": "-",
    "ekf_slip_peak_std": "-",
}


def _peak(x: np.ndarray, sd: np.ndarray | None = None) -> dict[str, float]:
    out = {"mu_peak": float(x[0]), "slip_peak": float(x[1])}
    if sd is not None:
        out |= {"mu_peak_std": float(sd[0]), "slip_peak_std": float(sd[1])}
    return out


def summary(res: MuSlipResult) -> dict[str, Any]:
    """The ``summary.json`` of OUTPUTS.md "mu-slip"."""
    return {
        "session": str(res.session.path),
        "rate_hz": round(res.session.rate_hz, 6),
        "ramp_s": [round(float(t), 6) for t in res.ramp_s],
        "points": int(res.slip.size),
        "noise_std_mu": res.sigma,
        "wheel_radius_m": res.radius_m,
        "ekf": _peak(res.ekf.x_filt[-1], np.sqrt(res.ekf.var_filt[-1])),
        # the EKF's noise is the measured std times the inflation: its NIS says whether
        # that covers the curve's shape error (over-confident: the two-parameter form)
        "ekf_consistency": res.ekf_consistency,
        "ekf_noise_scale": res.ekf_noise_scale,
        "lm_one_pass": _peak(*res.lm_one_pass),
        "lm_converged": _peak(*res.lm_converged),
        "families": [
            {
                "model": f.name,
                "params": f.params,
                "rmse": f.rmse,
                "heldout_rmse": f.heldout_rmse,
                "mu_peak": f.mu_peak,
                "slip_peak": f.slip_peak,
            }
            for f in res.families
        ],
        "peak": {"mu": res.best.mu_peak, "slip": res.best.slip_peak, "model": res.best.name,
                 **peak_band(res)},
        "shape_mismatch": shape_mismatch(res),
        "relaxation": _relaxation(res.relaxation),
        "warnings": list(res.warnings),
    }


def _relaxation(choice: RelaxationChoice | None) -> dict[str, Any] | None:
    """``summary.json`` ``relaxation``: the slip's alignment with the force (None for a
    point set or a session without the carriage speed)."""
    if choice is None:
        return None
    L = choice.length_m
    at = choice.heldout_rmse[choice.candidates_m.index(L)]
    return {
        "length_m": L,
        "candidates_m": list(choice.candidates_m),
        "heldout_rmse": list(choice.heldout_rmse),
        "words": ("the slip as logged: no lag of the force behind it improves the held-out fit"
                  if L == 0.0 else
                  f"the slip aligned with the force over {L:g} m of travel (the tyre's"
                  " relaxation length and the force sensors' lag: held-out μ RMSE"
                  f" {choice.heldout_rmse[0]:.4f} with the slip as logged, {at:.4f} aligned);"
                  " every estimator here sees the aligned slip"),
    }


