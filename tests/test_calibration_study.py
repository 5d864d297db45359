"""The study's bisection with the batched look-ahead (``StudyOptions.look_ahead``): the same evaluations, decisions,
history, parameters and messages as the sequential bisection, bit for bit; the unused runs counted, a rerun from
the FE cache identical."""

from __future__ import annotations

from dataclasses import replace

import pandas as pd
import pytest

from skidsim.calibration import FECache, FEOutcome, StudyOptions, calibrate_study
from skidsim.calibration.cache import fe_simulator, withdraw
from skidsim.errors import ConfigError
from skidsim.friction import ExponentialDecay
from skidsim.solver import SolverConfig, simulate
from skidsim.solver.surfaces import RandomTexture, to_heightfield

WALL_COLUMNS = ["wall_s_run", "fe_wall_s"]
MODES = ("quarters", "predicted", "stages")


def steps_for(speed_kmh: float) -> int:
    """Explicit steps to slide 114.3 mm at 0.8 us."""
    return int(round(0.1143 / (speed_kmh / 3.6) / 0.8e-6))


class BatchSurrogate:
    """SN = g mu(v) with a ``run_batch`` (so :meth:`FECache.wrap` batches announced runs); records calls and
    batches."""

    def __init__(self, g: float = 1.0, fail_after: int | None = None):
        self.g = g
        self.calls: list[tuple[float, ExponentialDecay]] = []
        self.batches: list[list] = []
        self.fail_after = fail_after

    def __call__(self, speed_kmh, law):
        if self.fail_after is not None and len(self.calls) >= self.fail_after:
            raise RuntimeError("simulated crash")
        self.calls.append((speed_kmh, law))
        n = steps_for(speed_kmh)
        return FEOutcome(sn=self.g * float(law.mu_kmh(speed_kmh)), n_steps=n, wall_s=n * 1e-6)

    def run_batch(self, requests):
        self.batches.append(list(requests))
        return [self(v, law) for v, law in requests]


class SpeedSurrogate(BatchSurrogate):
    """SN = (0.7 + 0.01 v) mu(v), v in km/h: a geometric factor that depends on the speed."""

    def __call__(self, speed_kmh, law):
        out = super().__call__(speed_kmh, law)
        return FEOutcome(sn=(0.7 + 0.01 * speed_kmh) * out.sn, n_steps=out.n_steps, wall_s=out.wall_s)


def same(a, b) -> None:
    """History (without wall times), parameters, convergence and message equal, bit for bit."""
    ha, hb = a.history.drop(columns=WALL_COLUMNS), b.history.drop(columns=WALL_COLUMNS)
    pd.testing.assert_frame_equal(ha, hb, check_exact=True)
    assert (a.params, a.converged, a.message) == (b.params, b.converged, b.message)


HAND = ({20: 0.55, 40: 0.30, 60: 0.30}, StudyOptions(start=(0.4, 0.35, 0.1)))  # 3 + 3 + 2 evaluations
EXHAUST = ({20: 0.60, 40: 0.50, 60: 0.42}, StudyOptions(max_iter=7))  # mu_s at 20 km/h exhausts max_iter


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("case", [HAND, EXHAUST], ids=["hand", "exhaust"])
def test_look_ahead_is_the_sequential_bisection(tmp_path, case, mode):
    meas, opt = case
    seq = calibrate_study(BatchSurrogate(), meas, opt)  # no prefetch: one call per evaluation
    assert seq.settings["speculative_fe_runs"] == 0
    sim = BatchSurrogate()
    la = calibrate_study(FECache(tmp_path / "c.parquet", "A").wrap(sim), meas, replace(opt, look_ahead=mode))
    same(seq, la)
    assert sim.batches, "the look-ahead ran batches"
    # every run is an evaluation or counted as speculative, with its steps
    st = la.settings
    assert len(sim.calls) == la.n_fe_runs + st["speculative_fe_runs"]
    assert sum(steps_for(v) for v, _ in sim.calls) == la.n_steps + st["speculative_fe_steps"]
    assert st["speculative_fe_steps_run"] == st["speculative_fe_steps"] and st["look_ahead"] == mode
    assert not la.history["cached"].any() and (la.history["n_steps_run"] == la.history["n_steps"]).all()


def test_quarters_on_the_hand_traced_sequence(tmp_path):
    # mu_k: batch {0.35, 0.175, 0.525} (0.35, 0.175 used), batch {0.2625, 0.21875, 0.30625} (0.2625 meets tol):
    # 3 unused; mu_s likewise 3; alpha: batch {0.5, 0.25, 0.75}, 0.25 meets tol: 1 unused
    meas, opt = HAND
    sim = BatchSurrogate()
    cache = FECache(tmp_path / "fe.parquet", "A")
    res = calibrate_study(cache.wrap(sim), meas, replace(opt, look_ahead="quarters"))
    assert [len(b) for b in sim.batches] == [3, 3, 3, 3, 3]
    st = res.settings
    assert st["speculative_fe_runs"] == 7
    assert st["speculative_fe_steps"] == 3 * steps_for(60) + 3 * steps_for(20) + steps_for(40)
    assert not cache._fresh, "unused runs are withdrawn, not left to be answered later"


def test_predicted_path_with_an_exact_model_wastes_nothing(tmp_path):
    # SN = mu(v) exactly (g = 1): the predicted path is the bisection's path, one batch per search
    meas, opt = HAND
    sim = BatchSurrogate()
    cache = FECache(tmp_path / "fe.parquet", "A")
    res = calibrate_study(cache.wrap(sim), meas, replace(opt, look_ahead="predicted"))
    assert [len(b) for b in sim.batches] == [3, 3, 2]
    assert res.settings["speculative_fe_runs"] == 0 and res.n_fe_runs == 8 == len(sim.calls)


def test_stages_with_an_exact_model_is_two_batches(tmp_path):
    # SN = mu(v): mu_k's predicted path (3 runs at 60 km/h), then mu_s's and alpha's predicted paths, alpha's from
    # the value mu_s is predicted to keep: one batch of 3 + 2 runs at 20 and 40 km/h; nothing wasted, same result
    meas, opt = HAND
    seq = calibrate_study(BatchSurrogate(), meas, replace(opt, look_ahead="none"))
    sim = BatchSurrogate()
    res = calibrate_study(FECache(tmp_path / "fe.parquet", "A").wrap(sim), meas, replace(opt, look_ahead="stages"))
    assert [sorted({v for v, _ in b}) for b in sim.batches] == [[60.0], [20.0, 40.0]]
    assert [len(b) for b in sim.batches] == [3, 5] and res.n_fe_runs == 8 == len(sim.calls)
    assert res.settings["speculative_fe_runs"] == 0
    same(seq, res)


def test_stages_after_a_wrong_prediction_is_the_sequential_bisection(tmp_path):
    # SN = g(v) mu(v) with g growing with speed: the paths predicted with the g of the last evaluation miss; the
    # searches look ahead again, the unused runs of every search are withdrawn and counted, the result is the
    # sequential one
    meas, opt = HAND
    seq = calibrate_study(SpeedSurrogate(), meas, replace(opt, look_ahead="none"))
    sim = SpeedSurrogate()
    cache = FECache(tmp_path / "fe.parquet", "A")
    res = calibrate_study(cache.wrap(sim), meas, replace(opt, look_ahead="stages"))
    same(seq, res)
    st = res.settings
    assert len(sim.batches) > 1 and st["speculative_fe_runs"] > 0
    assert len(sim.calls) == res.n_fe_runs + st["speculative_fe_runs"]
    assert sum(steps_for(v) for v, _ in sim.calls) == res.n_steps + st["speculative_fe_steps"]
    assert not cache._fresh, "unused runs are withdrawn, not left to be answered later"


@pytest.mark.parametrize("mode", MODES)
def test_rerun_and_resume_from_the_cache_are_identical(tmp_path, mode):
    meas, opt = EXHAUST
    opt = replace(opt, look_ahead=mode)
    path = tmp_path / "fe.parquet"
    first = calibrate_study(FECache(path, "A").wrap(BatchSurrogate()), meas, opt)
    sim2 = BatchSurrogate()
    again = calibrate_study(FECache(path, "A").wrap(sim2), meas, opt)
    assert not sim2.calls, "a rerun runs nothing"
    assert again.history["cached"].all() and again.n_steps_run == 0
    for c in ("cached", "n_steps_run"):
        again.history[c] = first.history[c]
    same(first, again)
    s1, s2 = first.settings, again.settings
    assert (s2["speculative_fe_runs"], s2["speculative_fe_steps"]) == (
        s1["speculative_fe_runs"],
        s1["speculative_fe_steps"],
    )
    assert s2["speculative_fe_steps_run"] == 0
    # a run killed after some batches resumes to the same result, never repeating a stored run
    path3 = tmp_path / "fe3.parquet"
    with pytest.raises(RuntimeError, match="simulated crash"):
        calibrate_study(FECache(path3, "A").wrap(BatchSurrogate(fail_after=9)), meas, opt)
    stored = len(FECache(path3, "A"))
    sim4 = BatchSurrogate()
    resumed = calibrate_study(FECache(path3, "A").wrap(sim4), meas, opt)
    assert stored and len(sim4.calls) == len(FECache(path3, "A")) - stored
    for c in ("cached", "n_steps_run"):
        resumed.history[c] = first.history[c]
    same(first, resumed)
    assert resumed.settings["speculative_fe_steps"] == s1["speculative_fe_steps"]


def test_withdraw_without_batching_returns_nothing():
    assert withdraw(BatchSurrogate(), [(20.0, ExponentialDecay(0.4, 0.3, 0.5))]) == []


def test_look_ahead_options():
    assert StudyOptions().look_ahead == "stages"
    with pytest.raises(ConfigError, match=r"calibration\.study\.look_ahead: expected"):
        StudyOptions(look_ahead="both")
    with pytest.raises(ConfigError, match=r"calibration\.study\.look_ahead_depth: expected an integer >= 1"):
        StudyOptions.from_config({"look_ahead_depth": 0})


def test_real_fe_look_ahead_is_bit_identical(tmp_path):
    """Coarse mesh, short slide, small pavement: mu_k meets the tolerance at its first evaluation (the measured
    value is its SN), mu_s at 20 km/h exhausts max_iter (out of reach), alpha in between."""
    pav = to_heightfield(RandomTexture(), 0.25e-3)
    cfg = SolverConfig(element_mm=2.0, slide_length_mm=3.0, window_start_mm=1.0, progress_every_s=1e9)
    sn60 = simulate(pav, 60.0, ExponentialDecay(0.4, 0.35, 0.6), cfg).sn
    meas = {60: sn60, 20: 1.9, 40: 0.9 * sn60}
    opt = StudyOptions(max_iter=3)
    seq = calibrate_study(lambda v, law: _single(pav, cfg, v, law), meas, opt)
    h = seq.history
    assert list(h["stage"]).count("mu_k") == 1 and list(h["stage"]).count("mu_s") == 3 and not seq.converged
    for mode in MODES:
        la = calibrate_study(fe_simulator(pav, cfg), meas, replace(opt, look_ahead=mode))
        same(seq, la)
        if mode == "quarters":  # mu_k's quarter points at least
            assert la.settings["speculative_fe_runs"] >= 2
    # the workflow's path: the per-site FE cache around the batching simulator, then a rerun from the cache alone
    opt = replace(opt, look_ahead="quarters")
    first = calibrate_study(FECache(tmp_path / "fe.parquet", "A").wrap(fe_simulator(pav, cfg)), meas, opt)
    same(seq, first)
    again = calibrate_study(FECache(tmp_path / "fe.parquet", "A").wrap(_never), meas, opt)
    assert again.n_steps_run == 0 and again.settings["speculative_fe_steps_run"] == 0
    assert again.settings["speculative_fe_steps"] == first.settings["speculative_fe_steps"] > 0
    for c in ("cached", "n_steps_run"):
        again.history[c] = seq.history[c]
    same(seq, again)


def _never(v, law):
    raise AssertionError(f"a rerun from the cache ran an FE simulation at {v} km/h for {law}")


def _single(pav, cfg, v, law) -> FEOutcome:
    """Today's path: one ``simulate`` per evaluation."""
    r = simulate(pav, float(v), law, cfg)
    return FEOutcome(sn=float(r.sn), n_steps=int(r.n_steps), wall_s=float(r.wall_s))
