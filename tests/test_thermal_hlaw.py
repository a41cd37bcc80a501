"""h(V) law: fit, continuity, TOML layout and validation."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from brakethermo.errors import ConfigError, DataError
from brakethermo.thermal.hlaw import KMH, HLaw, read_h_law

V_REF = 350.0 * KMH
TRUE = HLaw(v_ref=V_REF, a=110.0, b=0.75, c=(260.0, 400.0, -150.0))


def noisy_samples(seed: int, n: int = 4000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Off-brake samples: noisy at low speed (paper §5.1) plus a few gross outliers."""
    rng = np.random.default_rng(seed)
    v = rng.uniform(3.0, 95.0, n)
    std = np.where(v < 25.0, 35.0, 4.0)
    h = TRUE(v) + std * rng.standard_normal(n)
    h[rng.choice(n, n // 50, replace=False)] += rng.uniform(150.0, 400.0, n // 50)
    return v, h, std


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fit_recovers_known_law(seed: int) -> None:
    v, h, std = noisy_samples(seed)
    law = HLaw.fit(v, h, 1.0 / std**2, v_ref=V_REF)
    grid = np.linspace(5.0, 95.0, 200)
    assert np.max(np.abs(law(grid) / TRUE(grid) - 1.0)) < 0.03
    assert law.b == pytest.approx(TRUE.b, abs=0.05)
    plain = HLaw.fit(v, h, v_ref=V_REF, robust=False)  # outliers pull a plain fit up
    assert np.mean(plain(grid) - TRUE(grid)) > np.mean(law(grid) - TRUE(grid))


def test_fit_without_high_speed_data_continues_smoothly() -> None:
    v, h, std = noisy_samples(5)
    low = v < 0.75 * V_REF
    law = HLaw.fit(v[low], h[low], 1.0 / std[low] ** 2, v_ref=V_REF)
    eps = 1e-6
    left = (law(0.8 * V_REF - eps) - law(0.8 * V_REF - 2 * eps)) / eps
    right = (law(0.8 * V_REF + 2 * eps) - law(0.8 * V_REF + eps)) / eps
    assert right == pytest.approx(left, rel=1e-3)
    with pytest.raises(DataError, match="samples below"):
        HLaw.fit(v[:3], h[:3], v_ref=V_REF)


@settings(max_examples=50, deadline=None)
@given(
    a=st.floats(1.0, 500.0),
    b=st.floats(0.0, 3.0),
    c=st.tuples(*[st.floats(-1e3, 1e3)] * 3),
    knee=st.floats(0.3, 1.2),
)
def test_continuous_at_knee(a: float, b: float, c: tuple, knee: float) -> None:
    law = HLaw(v_ref=V_REF, a=a, b=b, c=c, knee=knee)
    vk = knee * V_REF
    below, above = law(vk * (1 - 1e-12)), law(vk)
    assert below == pytest.approx(above, rel=1e-9, abs=1e-9)
    assert np.all(law(np.linspace(0, 120, 50)) >= 0.0)


def test_constant_law() -> None:
    law = HLaw.constant(85.0)
    np.testing.assert_allclose(law(np.array([0.0, 10.0, 0.8 * V_REF, 100.0, -30.0])), 85.0)


def test_toml_round_trip_and_layout(tmp_path: Path) -> None:
    path = tmp_path / "h_law.toml"
    path.write_text(TRUE.toml_text(weights=(0.8, 1.1, 1.05),
                                   extra={"kz_ratio": 0.35, "fit": {"n": 12}}))
    record = read_h_law(path)
    assert record.law == TRUE
    assert HLaw.from_toml(path) == TRUE
    assert record.weights == (0.8, 1.1, 1.05)
    assert record.extra == {"kz_ratio": 0.35, "fit": {"n": 12}}
    raw = tomllib.loads(path.read_text())
    assert raw["v_ref_kmh"] == pytest.approx(350.0)
    assert raw["knee"] == 0.8
    assert raw["weights"]["w"] == [0.8, 1.1, 1.05]
    speeds = np.array(raw["tabulated"]["speed_kmh"])
    np.testing.assert_array_equal(speeds, np.arange(0.0, 361.0, 10.0))
    np.testing.assert_allclose(raw["tabulated"]["h"], TRUE(speeds * KMH), rtol=1e-15)
    a, b, c = raw["power"]["a"], raw["power"]["b"], raw["cubic"]["c"]
    x = speeds / 350.0
    u = x - 0.8
    formula = np.where(x < 0.8, a * x**b, c[0] + c[1] * u + c[2] * u**2 + c[3] * u**3)
    np.testing.assert_allclose(raw["tabulated"]["h"], np.maximum(formula, 0.0), rtol=1e-12)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("knee = 0.8\n[power]\na = 1.0\nb = 0.5\n[cubic]\nc = [1, 0, 0, 0]\n", "v_ref_kmh"),
        ('v_ref_kmh = 350\nknee = 0.8\n[power]\na = "x"\nb = 0.5\n',
         "key 'power.a': expected a finite number >= 0, found the text 'x'"),
        ("v_ref_kmh = 350\nknee = 0.8\n[power]\na = 1.0\nb = 0.5\n[cubic]\nc = [2, 0, 0, 0]\n",
         "continuity"),
        ("v_ref_kmh = 350\nknee = 0.8\n[power]\na = 1.0\nb = 0.5\n[cubic]\nc = [1, 0, 0]\n",
         r"key .cubic\.c.: expected a list of 4 finite numbers, found \[1, 0, 0\]"),
        ("v_ref_kmh = 350\nknee = 0.8\n[power]\na = 1.0\nb = 0.0\n[cubic]\nc = [1, 0, 0, 0]\n"
         "[weights]\nw = [1, -1, 1]\n", r"key 'weights\.w\[1\]'"),
        ("v_ref_kmh = -1\nknee = 0.8\n[power]\na = 1.0\nb = 0.0\n[cubic]\nc = [1, 0, 0, 0]\n",
         "key 'v_ref_kmh': expected a finite number > 0, found -1"),
        ("v_ref_kmh = 350\nknee = [\n", "invalid TOML"),
        # an edit of v_ref_kmh that v_ref_mps beside it silently overruled
        ("v_ref_kmh = 250\nv_ref_mps = 97.2222222\nknee = 0.8\n[power]\na = 1.0\nb = 0.0\n"
         "[cubic]\nc = [1, 0, 0, 0]\n", "key 'v_ref_kmh': expected 350 km/h, as v_ref_mps"),
        ('kind = "power-cubc"\nv_ref_kmh = 350\nknee = 0.8\n[power]\na = 1.0\nb = 0.0\n'
         "[cubic]\nc = [1, 0, 0, 0]\n", "key 'kind': expected \"power-cubic\""),
    ],
)  # fmt: skip
def test_invalid_files_raise_config_error(tmp_path: Path, text: str, match: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=match) as info:
        read_h_law(path)
    assert str(path) in str(info.value)


def test_a_toml_that_is_no_h_law_is_said_so(tmp_path) -> None:
    """A valid TOML of another kind (the tuning file, a booster fit) read as an h law said
    "key 'v_ref_kmh': … missing", as if a law had lost one key."""
    import pytest

    from brakethermo.errors import ConfigError
    from brakethermo.thermal.hlaw import read_h_law

    path = tmp_path / "fit.toml"
    path.write_text("[estimate]\nnodes = 10\n")
    with pytest.raises(ConfigError, match=r"not an h law: .*it sets: estimate.*identify-h"):
        read_h_law(path)


def test_the_law_never_falls_with_speed_beyond_the_cubics_first_maximum() -> None:
    """A knee gain fitted at its negative bound gave a cubic that fell from 308 W/(m² K)
    at 300 km/h to 157 at 360 (an independent generator's session): the law is held at
    the cubic's first maximum; a rising cubic and the power branch are untouched."""
    import numpy as np

    from brakethermo.thermal.hlaw import HLaw

    v = np.linspace(0.0, 400.0, 401) / 3.6
    falling = HLaw(v_ref=350 / 3.6, a=306.0 / 0.8**0.5, b=0.5, c=(162.2, -3267.6, -1313.97))
    h = falling(v)
    assert np.all(np.diff(h) >= -1e-9)
    u = np.linspace(0.0, falling.u_peak, 50)
    c1, c2, c3 = falling.c
    assert h.max() == pytest.approx(np.max(falling.c0 + u * (c1 + u * (c2 + u * c3))))
    for c in ((0.0, -100.0, 0.0), (0.0, 0.0, -50.0), (-5.0, 1.5, 0.0)):  # down from the knee
        flat = HLaw(v_ref=350 / 3.6, a=300.0, b=0.5, c=c)
        assert flat.u_peak == 0.0 and np.all(np.diff(flat(v)) >= -1e-9)
    rising = HLaw(v_ref=350 / 3.6, a=300.0, b=0.5, c=(40.0, 10.0, 0.0))
    assert rising.u_peak == np.inf
    x = v / rising.v_ref
    uu = np.maximum(x - 0.8, 0.0)
    expect = np.where(x < 0.8, 300.0 * x**0.5,
                      rising.c0 + uu * (40.0 + uu * 10.0))
    np.testing.assert_allclose(rising(v), expect)


def test_beyond_its_data_the_law_grows_as_its_power_branch(tmp_path: Path) -> None:
    """An independent generator's session to 303 km/h: the cubic above the knee, fitted on
    its few fastest straights, gave 551 W/(m² K) at 330 km/h and 909 at 350 against a true
    290 and 327. Beyond the fastest speed it was identified on the law now grows as its
    power branch does, and the file says where that is."""
    cubic = HLaw(v_ref=V_REF, a=227.2, b=0.729, c=(163.2, 14673.4, 12013.1), knee=0.8)
    law = HLaw(v_ref=V_REF, a=227.2, b=0.729, c=(163.2, 14673.4, 12013.1), knee=0.8,
               x_data=302.5 * KMH / V_REF)
    v = np.array([250.0, 300.0, 302.5, 330.0, 350.0]) * KMH
    np.testing.assert_allclose(law(v[:3]), cubic(v[:3]))  # the data's range: as fitted
    h_data = float(cubic(302.5 * KMH))
    np.testing.assert_allclose(law(v[3:]), h_data * (v[3:] / (302.5 * KMH)) ** 0.729)
    assert float(cubic(330.0 * KMH)) > 500.0 and 270.0 < float(law(330.0 * KMH)) < 300.0
    (tmp_path / "h.toml").write_text(law.toml_text())
    raw = tomllib.loads((tmp_path / "h.toml").read_text())
    assert raw["v_data_kmh"] == pytest.approx(302.5)
    back = read_h_law(tmp_path / "h.toml").law
    assert back.x_data == pytest.approx(law.x_data)
    np.testing.assert_allclose(back(v), law(v))
    np.testing.assert_allclose(raw["tabulated"]["h"], law(np.asarray(
        raw["tabulated"]["speed_kmh"]) * KMH))
    # a law written before (no v_data_kmh) reads as it always did
    (tmp_path / "old.toml").write_text(cubic.toml_text())
    assert "v_data_kmh" not in (tmp_path / "old.toml").read_text()
    assert read_h_law(tmp_path / "old.toml").law.x_data == np.inf


def test_a_race_faster_than_the_laws_data_is_warned(tmp_path: Path) -> None:
    """An independent generator's race to 324 km/h on a law identified to 303: no word."""
    from brakethermo.pipelines.estimate import EstimateOptions, calibrated_tuning
    from brakethermo.pipelines.models import calibration_for
    from brakethermo.pipelines.run_facts import law_warnings
    from brakethermo.thermal.disc import load_disc

    law = HLaw(v_ref=V_REF, a=160.0, b=0.5, c=(130.0, 0.0, 0.0), x_data=300.0 * KMH / V_REF)
    (tmp_path / "h.toml").write_text(law.toml_text(extra={"disc": "cc-340-8"}))
    disc = load_disc()
    cal = calibration_for(disc, tmp_path / "h.toml")
    tuning = calibrated_tuning(cal, EstimateOptions())
    fast = np.r_[np.linspace(10.0, 322.0, 500), 322.0] * KMH
    (said,) = [w for w in law_warnings(cal, disc, tuning, fast) if "runs to" in w]
    assert "runs to 322 km/h" in said and "(300 km/h)" in said
    assert not [w for w in law_warnings(cal, disc, tuning, fast * 300.0 / 322.0)
                if "runs to" in w]


def test_a_law_flat_with_speed_is_implausible() -> None:
    """identify-h --with-effect none wrote b = 2.4e-06 (its bound 0), h = 76.8 at every
    speed, with nothing said; an independent generator's sessions gave b = 0.066. Forced
    convection rises with speed: both are flagged, a V^0.6 law is not."""
    from brakethermo.thermal.hlaw_check import law_speed_check

    v = np.linspace(80.0, 300.0, 200) / 3.6
    flat = law_speed_check(HLaw(v_ref=350 / 3.6, a=76.8, b=2.4e-06), v)
    assert flat is not None and flat["b_at_bound"] and flat["rise"] == pytest.approx(1.0, abs=1e-4)
    assert "lower bound 0" in flat["text"] and "--with-effect" in flat["text"]
    weak = law_speed_check(HLaw(v_ref=350 / 3.6, a=100.0, b=0.066), v)
    assert weak is not None and not weak["b_at_bound"] and weak["rise"] < weak["rise_needed"]
    assert law_speed_check(HLaw(v_ref=350 / 3.6, a=180.0, b=0.6), v) is None
