"""The reduced-order filter: modes that hold the model's own field, and an estimate
within a degree of the full-order filter's on the same session."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from brakethermo.errors import ConfigError
from brakethermo.models.reduced import pod_modes, with_directions
from brakethermo.pipelines.estimate import EstimateOptions, estimate_session
from brakethermo.sim.session import SimConfig, simulate, write_simulation

SEED = 61301  # not a tuning seed


@settings(max_examples=20, deadline=None)
@given(rank=st.integers(1, 6), n=st.integers(8, 40), seed=st.integers(0, 1000))
def test_modes_are_orthonormal_and_hold_low_rank_snapshots(rank: int, n: int, seed: int
                                                           ) -> None:
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(200, rank)) @ rng.normal(size=(rank, n)) * 50.0
    Phi, err = pod_modes(X, tolerance_c=1e-6)
    assert np.allclose(Phi.T @ Phi, np.eye(Phi.shape[1]), atol=1e-10)
    assert Phi.shape[1] <= max(rank, 4) and err <= 1e-6
    np.testing.assert_allclose(X @ Phi @ Phi.T, X, atol=1e-6)
    D = rng.normal(size=(n, 2))
    Psi = with_directions(Phi, D)
    assert np.allclose(Psi.T @ Psi, np.eye(Psi.shape[1]), atol=1e-10)
    np.testing.assert_allclose(Psi @ (Psi.T @ D), D, atol=1e-8)  # D is in the span
    assert with_directions(Psi, D).shape == Psi.shape  # nothing new to add


def test_reduced_noise_is_the_projected_full_noise() -> None:
    """Q(k) from parts projected once equals the full Q(k) projected, braking or not,
    with random-walk parameters and a lagging sensor."""
    from brakethermo.models.disc import DiscEffects, DiscStateSpace, RandomWalkParam
    from brakethermo.models.reduced import ReducedStateSpace
    from brakethermo.thermal.disc import load_disc
    from brakethermo.thermal.model import DiscFEModel

    disc = load_disc()
    model = DiscFEModel(disc, 20, 2)
    q = np.array([0.0, 4.0e4, 0.0])
    ssm = DiscStateSpace(model, q, np.full(3, 25.0), np.full(3, 90.0),
                         [RandomWalkParam("power_scale", 1.0, 0.1, 0.01),
                          RandomWalkParam("h_factor", 1.0, 0.1, 0.02, off_brake_only=True)],
                         sigma_temp=0.5, sigma_crown=0.2,
                         effects=DiscEffects(sensor_tau_s=0.5), spot_radius=disc.spot_radii[2])
    Phi, _ = pod_modes(np.random.default_rng(0).normal(size=(50, model.n_state)), 1e-9, 8)
    red = ReducedStateSpace(ssm, Phi)
    for k in range(3):
        np.testing.assert_allclose(red.Q(k), red.L.T @ ssm.Q(k) @ red.L, atol=1e-12)


def test_session_modes_are_computed_once_per_model_and_session(monkeypatch) -> None:
    """The decision's filter variants of one model share its modes, also when they ask at
    once; another law's h or another mesh computes its own."""
    from concurrent.futures import ThreadPoolExecutor

    from brakethermo.pipelines import race_filter
    from brakethermo.pipelines.inputs import DiscInputs
    from brakethermo.thermal.disc import load_disc
    from brakethermo.thermal.model import DiscFEModel

    K = 300
    t = np.arange(K) * 0.1
    q = np.where((t % 10.0) < 2.0, 6.0e4, 0.0)
    inputs = DiscInputs(t, np.zeros(K, int), np.full(K, 60.0), q, np.full(K, 25.0),
                        np.full((K, 4), np.nan), (3,))
    h = np.full(K, 80.0)
    calls = []
    original = race_filter.open_loop_modes

    def counted(*args):
        calls.append(args[0].n_state)
        return original(*args)

    monkeypatch.setattr(race_filter, "open_loop_modes", counted)
    monkeypatch.setattr(race_filter, "_MODES", type(race_filter._MODES)())
    disc = load_disc()
    model = DiscFEModel(disc, 10, 4)
    with ThreadPoolExecutor(4) as pool:
        answers = list(pool.map(
            lambda _: race_filter.session_modes(model, inputs, h, 1.0, 40), range(4)))
    assert len(calls) == 1
    assert all(a[0] is answers[0][0] for a in answers)
    assert not answers[0][0].flags.writeable  # shared: nobody may change it
    race_filter.session_modes(DiscFEModel(disc, 10, 4), inputs, h, 1.0, 40)
    assert len(calls) == 1  # an equal model of another variant: the same modes
    # whatever changes the open loop computes its own
    for other in (DiscFEModel(disc, 15, 6), DiscFEModel(disc, 10, 4, kz_ratio=0.5),
                  DiscFEModel(disc, 10, 4, weights=(1.2, 1.0, 0.8)),
                  DiscFEModel(disc, 10, 4, layer_growth=1.5),
                  DiscFEModel(disc, 10, 4, k_z=2.0)):
        race_filter.session_modes(other, inputs, h, 1.0, 40)
    race_filter.session_modes(model, inputs, 1.1 * h, 1.0, 40)
    race_filter.session_modes(model, inputs, h, 1.2, 40)
    assert calls == [40, 90, 40, 40, 40, 40, 40, 40]


def test_a_failed_modes_computation_reaches_the_waiters_and_is_retried(monkeypatch) -> None:
    import threading

    from brakethermo.pipelines import race_filter
    from brakethermo.pipelines.inputs import DiscInputs
    from brakethermo.thermal.disc import load_disc
    from brakethermo.thermal.model import DiscFEModel

    K = 50
    inputs = DiscInputs(np.arange(K) * 0.1, np.zeros(K, int), np.full(K, 60.0),
                        np.full(K, 3.0e4), np.full(K, 25.0), np.full((K, 4), np.nan), (3,))
    h = np.full(K, 80.0)
    model = DiscFEModel(load_disc(), 10, 4)
    started, release = threading.Event(), threading.Event()
    original = race_filter.open_loop_modes

    def failing(*args):
        started.set()
        release.wait(5.0)
        raise RuntimeError("interrupted")

    monkeypatch.setattr(race_filter, "_MODES", type(race_filter._MODES)())
    monkeypatch.setattr(race_filter, "open_loop_modes", failing)
    errors = []

    def ask() -> None:
        try:
            race_filter.session_modes(model, inputs, h, 1.0, 40)
        except RuntimeError as err:
            errors.append(str(err))

    first = threading.Thread(target=ask)
    first.start()
    started.wait(5.0)
    waiter = threading.Thread(target=ask)
    waiter.start()
    waiter.join(0.2)  # it now waits for the first one's answer
    release.set()
    first.join(5.0)
    waiter.join(5.0)
    assert errors == ["interrupted", "interrupted"]
    monkeypatch.setattr(race_filter, "open_loop_modes", original)
    Phi, _ = race_filter.session_modes(model, inputs, h, 1.0, 40)
    assert Phi.shape[0] == model.n_state


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("reduced")
    return write_simulation(simulate(SimConfig(laps=1, sensor="multi", seed=SEED)),
                            out / "s.parquet")[0]


def test_reduced_filter_matches_the_full_one(session: Path) -> None:
    """On a 40 x 2 mesh (80 states: reduced by default) the reduced filter's contact band
    is within 1 degC RMS of the full filter's, its band within 10 %, and the node field
    comes back on the full mesh."""
    opts = {"nodes": 40, "layers": 2, "online_auto": False, "score": False}
    full = estimate_session(session, EstimateOptions(modes=0, **opts))
    red = estimate_session(session, EstimateOptions(**opts))
    order = red.summary["run"]["filter_order"]
    assert order["kind"] == "reduced" and order["states"] < 0.5 * order["full_states"]
    assert full.summary["run"]["filter_order"]["kind"] == "full"
    a, b = full.frame, red.frame
    assert list(a.columns) == list(b.columns)
    fly = a["lap"].to_numpy() >= 1
    diff = (a["contact_avg"] - b["contact_avg"]).to_numpy()[fly]
    assert np.sqrt(np.mean(diff**2)) < 1.0
    assert abs(b["contact_avg_std"].mean() / a["contact_avg_std"].mean() - 1.0) < 0.1
    node_diff = (a["node_20"] - b["node_20"]).to_numpy()[fly]
    assert np.sqrt(np.mean(node_diff**2)) < 1.5


def test_default_mesh_runs_reduced_at_the_full_filters_figures(session: Path) -> None:
    """The default 10 x 4 mesh runs reduced (the 0.001 degC basis) and stays within a tenth
    of a degree of the full filter on the contact band, its band within 2 %; the paper's
    10 x 1 model stays full."""
    opts = {"online_auto": False, "score": False}
    full = estimate_session(session, EstimateOptions(modes=0, **opts))
    red = estimate_session(session, EstimateOptions(**opts))
    order = red.summary["run"]["filter_order"]
    assert order["kind"] == "reduced" and order["modes"] < 40
    fly = full.frame["lap"].to_numpy() >= 1
    diff = (full.frame["contact_avg"] - red.frame["contact_avg"]).to_numpy()[fly]
    assert np.sqrt(np.mean(diff**2)) < 0.1
    ratio = red.frame["contact_avg_std"].mean() / full.frame["contact_avg_std"].mean()
    assert abs(ratio - 1.0) < 0.02
    paper = estimate_session(session, EstimateOptions(layers=1, **opts))
    assert paper.summary["run"]["filter_order"]["kind"] == "full"


def test_modes_option_is_checked() -> None:
    with pytest.raises(ConfigError, match="modes"):
        EstimateOptions(modes=-1)
    with pytest.raises(ConfigError, match="modes"):
        EstimateOptions(modes=500)
