"""The evidence for a written h(V): each straight's own h through the layered model."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from brakethermo.pipelines.estimate import EstimateOptions, calibrated_tuning
from brakethermo.pipelines.h_evidence import law_level, straight_factors
from brakethermo.pipelines.identify_h import fit_inputs, off_brake_mask
from brakethermo.pipelines.inputs import load_timed
from brakethermo.pipelines.models import calibration_for

SAMPLE = Path(__file__).parents[1] / "sample_sessions" / "mugello_test_multi.mcap"


@pytest.fixture(scope="module")
def setup():
    session, _ = load_timed(SAMPLE, None)
    disc, inputs, y = fit_inputs(session)
    cal = calibration_for(disc, None)  # the shipped law, identified on this very session
    return inputs, y, disc, cal


@pytest.mark.parametrize("scale", [1.0, 0.7])
def test_the_straights_put_a_law_where_the_cooling_is(setup, scale):
    inputs, y, disc, cal = setup
    law = replace(cal.law, a=cal.law.a * scale, c=tuple(c * scale for c in cal.law.c))
    cal = replace(cal, law=law)
    tuning = calibrated_tuning(cal, EstimateOptions())
    df = straight_factors(inputs, y, disc, cal, tuning, off_brake_mask(inputs.braking))
    level = law_level(df)
    assert level["straights"] >= 20
    # the shipped law holds on its own session within a few per cent; a law 30 % low is
    # called low by about as much
    assert level["factor"] == pytest.approx(1.0 / scale, rel=0.1)
    assert level["ci95"][0] < level["factor"] < level["ci95"][1]
    assert np.all(df["factor_sd"] > 0) and np.all(df["duration_s"] >= 3.0)


def test_too_few_straights_give_no_verdict():
    import pandas as pd

    level = law_level(pd.DataFrame({"factor": [1.0], "factor_sd": [0.1]}))
    assert level["straights"] == 1 and np.isnan(level["factor"])
