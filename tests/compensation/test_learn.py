"""Learning from power-ons (compensation/_learn.py) against independent truth: the slopes
from sufficient statistics equal an explicit least-squares fit with one dummy offset per
warm-up; the leave-one-power-on-out RMS equals explicit refits; the gates refuse one
warm-up, one ambient and motion; the learnt calibration matches the simulator's true
bias on power-ons it never saw. Seeds fixed before any result was seen."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from gyrotherm.compensation import RunFeatures, features, fit
from gyrotherm.compensation._learn import (
    GATES,
    LEARN_SCALING,
    PAPER,
    WarmupStats,
    basis_slopes,
    decide,
    heldout_bias_rms,
    heldout_rms,
    learnt_calibration,
    slopes,
    unseen,
    warmup_rows,
)
from gyrotherm.compensation._rest import rest_of_run
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import chamber_runs
from gyrotherm.sim._life import LIFE_GYRO, life, power_on

EST = EstimatorConfig(tau_s=LIFE_GYRO.tau_s)
AXES = ("x", "y", "z")


@pytest.fixture(scope="module")
def feats() -> list[RunFeatures]:
    return [features(r, EST) for r in life(14, seed=5)]


def _design(f: RunFeatures, extra: bool = False) -> tuple[np.ndarray, np.ndarray]:
    use = warmup_rows(f)
    x, g = LEARN_SCALING.centre(f.temperature_c[use], f.delta_t_c[use])
    cols = [x * x, x, g, x * g] + ([x ** 3, g * g] if extra else [])
    return np.column_stack(cols), f.rates_dps["x"][use]


@pytest.mark.parametrize("extra", [False, True], ids=["paper", "paper+cubic+gradient2"])
def test_slopes_equal_least_squares_with_one_offset_per_warmup(
    feats: list[RunFeatures], extra: bool,
) -> None:
    from gyrotherm.compensation._learn import columns

    parts = [_design(f, extra) for f in feats[:6]]
    n = sum(len(y) for _, y in parts)
    dummies = np.zeros((n, len(parts)))
    start = 0
    for k, (_, y) in enumerate(parts):
        dummies[start:start + len(y), k] = 1.0
        start += len(y)
    a = np.hstack([np.vstack([z for z, _ in parts]), dummies])
    coef, *_ = np.linalg.lstsq(a, np.concatenate([y for _, y in parts]), rcond=None)
    cols = columns(("cubic", "gradient_quadratic") if extra else ())
    beta, _ = slopes([WarmupStats.from_features(f) for f in feats[:6]], "x", cols)
    k = len(cols)
    np.testing.assert_allclose(beta[:k], coef[:k], rtol=1e-6, atol=1e-9)
    assert not beta[k:].any()  # columns outside the model stay 0


def test_leave_one_out_from_statistics_equals_explicit_refits(
    feats: list[RunFeatures],
) -> None:
    stats = [WarmupStats.from_features(f) for f in feats[:5]]
    sse = 0.0
    for k in range(5):
        beta, _ = slopes([s for j, s in enumerate(stats) if j != k], "x")
        z, y = _design(feats[k])
        r = y - z @ beta[:4]
        sse += float(np.sum((r - r.mean()) ** 2))
    assert heldout_rms(stats, "x") == pytest.approx(
        math.sqrt(sse / sum(s.n for s in stats)), rel=1e-9)


def test_memory_does_not_grow_with_the_warmup(feats: list[RunFeatures]) -> None:
    short = WarmupStats.from_features(feats[0], warmup_rows(feats[0]) & (feats[0].time_s < 100))
    long = WarmupStats.from_features(feats[0])
    assert long.n > 5 * short.n
    assert len(repr(long.to_dict())) < 1.2 * len(repr(short.to_dict()))


def test_learnt_calibration_matches_the_true_bias_on_unseen_power_ons(
    feats: list[RunFeatures],
) -> None:
    stats = [WarmupStats.from_features(f) for f in feats[:10]]
    d = decide(stats, None, AXES)
    assert d.adopt, d.reasons
    cal = learnt_calibration(stats, AXES, estimator=EST, decision=d)
    assert cal.provenance["validation"]["adopt"] is True
    assert len(cal.provenance["power_ons"]) == 10
    for f in feats[10:]:
        use = warmup_rows(f)
        for a in AXES:
            b, _ = cal.bias_series(a, f.temperature_c, f.delta_t_c)
            err = (b - f.true_bias_dps[a])[use]
            spread = np.std(f.true_bias_dps[a][use])  # what no compensation leaves
            assert np.std(err) < 0.1 * spread


def test_gates_refuse_one_warmup_one_ambient_and_say_why(feats: list[RunFeatures]) -> None:
    one = decide([WarmupStats.from_features(feats[0])], None, AXES)
    assert not one.adopt and "warm-ups: 1 at rest" in one.reasons[0]
    same = [WarmupStats.from_features(features(power_on(20.0, seed=70 + k), EST))
            for k in range(4)]
    d = decide(same, None, AXES)
    assert not d.adopt
    assert any(f"at least {GATES['min_start_span_c']:g} °C" in r for r in d.reasons)


def test_motion_rows_are_never_learnt() -> None:
    run = power_on(5.0, warmup_s=300.0, motion_s=300.0, seed=80)
    f = replace(features(run, EST), rest=rest_of_run(run).rest)  # fit's own detection
    use = warmup_rows(f)
    assert not use[f.time_s > 300.0].any()  # nothing after the vehicle moved off
    assert use.sum() > 2500  # most of the 300 s at rest (10 s of settling left out)


def test_a_better_current_calibration_is_kept(feats: list[RunFeatures]) -> None:
    """The current calibration learnt from 10 other power-ons is not replaced by what 3
    new warm-ups give (scored on those 3, which the current one never saw)."""
    others = [WarmupStats.from_features(f) for f in feats[4:14]]
    current = learnt_calibration(others, AXES, estimator=EST)
    new = [WarmupStats.from_features(f) for f in feats[:3]]
    d = decide(new, current, AXES)
    assert not d.adopt and "not better" in d.reasons[-1]
    assert all(d.current_rms_dps[a] < d.candidate_rms_dps[a] for a in AXES)


def test_learnt_beats_no_compensation_but_not_a_chamber_it_never_saw() -> None:
    """Sanity of the comparison the study makes: a chamber calibration of the same gyro
    is scored on the same held-out warm-ups with the same statistics."""
    cham = fit([features(r, EST) for r in chamber_runs([10, 40], seed=2, rate_hz=1.0,
                                                         hold_s=900.0, gyro=LIFE_GYRO)],
               "paper", estimator=EST)
    held = [WarmupStats.from_features(features(r, EST)) for r in life(4, seed=6)]
    assert heldout_rms(held, "x", basis_slopes(cham, "x")) < 0.5 * heldout_rms(
        held, "x", basis_slopes(None, "x"))


def test_white_noise_estimate_is_the_simulators(feats: list[RunFeatures]) -> None:
    from gyrotherm.compensation._learn import noise_var

    stats = [WarmupStats.from_features(f) for f in feats[:5]]
    sigma = LIFE_GYRO.arw_deg_per_rth / 60.0 * math.sqrt(10.0)  # N/60·√rate at 10 Hz, °/s
    for a in AXES:
        assert math.sqrt(noise_var(stats, a)) == pytest.approx(sigma, rel=0.03)


def test_an_axis_without_thermal_bias_is_not_adopted_the_others_are() -> None:
    from gyrotherm.sim import DEFAULT_TRUE_BIAS, BiasTruth

    flat_z = {**DEFAULT_TRUE_BIAS, "z": {k: 0.0 for k in DEFAULT_TRUE_BIAS["z"]}}
    gyro = replace(LIFE_GYRO, bias=BiasTruth(coefficients=flat_z))
    stats = [WarmupStats.from_features(features(r, EST)) for r in life(8, seed=12, gyro=gyro)]
    d = decide(stats, None, AXES)
    assert d.axes_adopted == ("x", "y")
    assert "not better than no compensation by 10 % on z" in d.reasons[-1]
    cal = learnt_calibration(stats, AXES, estimator=EST, decision=d)
    assert cal.coefficients["z"] == (0.0,) * 5


def test_a_learnt_calibration_is_judged_on_warmups_it_never_saw(
        feats: list[RunFeatures]) -> None:
    """Re-adoption: a calibration learnt from 3 power-ons is scored only on the 7 it
    was not learnt from (on its own training warm-ups it would look better than it is,
    and nothing newer would replace it), the candidate on the same 7; with no new
    warm-up the current one is kept, saying why. A current calibration with the right
    provenance but no thermal shape is replaced by the 10-power-on one, which is closer
    to the simulator's true bias on 4 power-ons neither saw."""
    stats = [WarmupStats.from_features(f) for f in feats[:10]]
    current = learnt_calibration(stats[:3], AXES, estimator=EST)
    assert unseen(stats, current) == list(range(3, 10))
    assert unseen(stats, None) == list(range(10))
    d = decide(stats, current, AXES)
    for a in AXES:
        assert d.current_rms_dps[a] == pytest.approx(heldout_bias_rms(
            stats, a, basis_slopes(current, a), list(range(3, 10))), rel=1e-12)
        assert d.candidate_rms_dps[a] == pytest.approx(heldout_bias_rms(
            stats, a, scored=list(range(3, 10))), rel=1e-12)
    kept = decide(stats[:3], current, AXES)
    assert not kept.adopt and "none that the current calibration was not learnt from" \
        in kept.reasons[0]
    flat = replace(current, coefficients={a: (0.0, 0.0, 0.0, 0.0, c[-1])
                                          for a, c in current.coefficients.items()})
    d = decide(stats, flat, AXES)
    assert d.adopt and d.axes_adopted == AXES
    new = learnt_calibration(stats, AXES, estimator=EST, decision=d)
    held = [WarmupStats.from_features(features(r, EST)) for r in life(4, seed=6)]
    for a in AXES:
        assert heldout_bias_rms(held, a, basis_slopes(new, a)) < \
            0.5 * heldout_bias_rms(held, a, basis_slopes(flat, a))


def _true_spread(fs: list[RunFeatures], axis: str) -> float:
    """RMS of the simulator's true bias about each warm-up's own mean: the bias error no
    compensation leaves once the boot-time zero took the offset."""
    sq, n = 0.0, 0
    for f in fs:
        b = f.true_bias_dps[axis][warmup_rows(f)]
        sq += float(np.sum((b - b.mean()) ** 2))
        n += len(b)
    return math.sqrt(sq / n)


@pytest.mark.parametrize("dt_scale", [1.0, 0.0778])
def test_the_reducible_bias_error_of_no_compensation_is_the_true_thermal_spread(
        dt_scale: float) -> None:
    """With the white noise alone taken out, the gyro's slow noise (bias instability, rate
    random walk) counts as bias error; what the model class leaves in sample takes it out
    too. Against the simulator's truth, on a gyro whose thermal bias is large and on one
    whose bias is of the size of its slow noise (ΔT terms × 0.0778, findings §8)."""
    from gyrotherm.compensation._learn import floor_ms, noise_var
    from gyrotherm.sim._profiles import scaled_dt

    gyro = scaled_dt(LIFE_GYRO, dt_scale)
    fs = [features(r, EST) for r in life(10, seed=21, gyro=gyro)]
    stats = [WarmupStats.from_features(f) for f in fs]
    for a in AXES:
        truth = _true_spread(fs, a)
        est = heldout_bias_rms(stats, a, np.zeros(6))
        # 0.0012 °/s: a fifth of the simulator's bias instability (20 °/h)
        assert est == pytest.approx(truth, rel=0.15, abs=0.0012), a
        if dt_scale < 1:  # white noise alone taken out: the slow noise is counted as bias
            old = math.sqrt(max(heldout_rms(stats, a, np.zeros(6)) ** 2
                                - noise_var(stats, a), 0.0))
            assert floor_ms(stats, a) > noise_var(stats, a)
            assert abs(old - truth) > 1.5 * abs(est - truth), a


def test_extrapolation_is_validated_as_far_as_the_leave_one_out_reached(
        feats: list[RunFeatures]) -> None:
    """The learnt range is widened on each side by the overhang of the warm-up reaching
    furthest past the others (hand-computed from their ranges), because decide scored it
    with the others' slopes, unclamped, and it beat no compensation there; a held-out
    power-on inside that widening is closer to the simulator's truth than the same
    calibration clamped to the data's coverage."""
    from gyrotherm.compensation._calibration import ValidRange
    from gyrotherm.compensation._learn import validated_extension

    stats = [WarmupStats.from_features(f) for f in feats[:10]]
    lows = sorted(w.t_range_c[0] for w in stats)
    highs = sorted(w.t_range_c[1] for w in stats)
    below, above = validated_extension(stats, AXES)
    assert below == pytest.approx(lows[1] - lows[0], rel=1e-12)
    assert above == pytest.approx(highs[-1] - highs[-2], rel=1e-12)
    assert above > 1.0  # the case below needs room
    d = decide(stats, None, AXES)
    cal = learnt_calibration(stats, AXES, estimator=EST, decision=d)
    assert (cal.valid_range.t_min_c, cal.valid_range.t_max_c) == pytest.approx(
        (lows[0] - below, highs[-1] + above))
    assert cal.provenance["coverage_c"] == [lows[0], highs[-1]]
    assert cal.provenance["validated_extrapolation_c"] == [below, above]
    clamped = replace(cal, valid_range=ValidRange(lows[0], highs[-1], cal.valid_range.dt_min_c,
                                                  cal.valid_range.dt_max_c))
    # die ≈ ambient + 8 °C at the end: ambient so that the die ends inside the widening
    f = features(power_on(highs[-1] + 0.6 * above - 8.0, seed=99), EST)
    use = warmup_rows(f)
    assert f.temperature_c[use].max() > highs[-1]
    for a in AXES:
        errs = []
        for c in (cal, clamped):
            e = (c.bias_series(a, f.temperature_c, f.delta_t_c)[0] - f.true_bias_dps[a])[use]
            errs.append(float(np.std(e)))
        assert errs[0] < errs[1], a


def test_extrapolation_that_failed_its_validation_is_not_used(
        feats: list[RunFeatures]) -> None:
    """The hottest warm-up's thermal shape reversed (its rates carry −2× its true bias
    variation): the others' slopes fail on it, so the hot side is clamped at the data's
    coverage; the cold side is unaffected."""
    from gyrotherm.compensation._learn import validated_extension

    fs = list(feats[:10])
    hot = max(range(10), key=lambda k: float(np.nanmax(fs[k].temperature_c)))
    f = fs[hot]
    fs[hot] = replace(f, rates_dps={a: r - 3.0 * (f.true_bias_dps[a] - f.true_bias_dps[a].mean())
                                    for a, r in f.rates_dps.items()})
    good = validated_extension([WarmupStats.from_features(g) for g in feats[:10]], AXES)
    below, above = validated_extension([WarmupStats.from_features(g) for g in fs], AXES)
    assert good[1] > 0 and above == 0.0
    assert below == pytest.approx(good[0], rel=1e-12)


def _with_effect(run, effect: str, c: float):  # type: ignore[no-untyped-def]
    """``run`` with a bias added on every axis, in the simulator's true T and ΔT:
    ``cubic`` c·(T − 25 °C)³ or ``gradient_quadratic`` c·ΔT² (truth updated alike)."""
    t, d = run.extra["true_temperature_c"], run.extra["true_delta_t_c"]
    add = c * (t - 25.0) ** 3 if effect == "cubic" else c * d * d
    return replace(run, rates_dps={a: r + add for a, r in run.rates_dps.items()},
                   true_bias_dps={a: b + add for a, b in run.true_bias_dps.items()})


@pytest.mark.parametrize(("effect", "c", "param"), [
    ("cubic", 3e-5, "coefficient_dps_per_c3"),  # 1.3 °/s at −10 °C
    ("gradient_quadratic", 1e-2, "coefficient_dps_per_c2"),  # 0.64 °/s at ΔT = 8 °C
])
def test_an_effect_in_the_truth_is_learnt_where_the_warmups_support_it(
        effect: str, c: float, param: str) -> None:
    """A cubic in T or a ΔT² added to the simulator's true bias (off the paper model):
    after 10 power-ons it is learnt on every axis, its coefficient within 25 % of the
    one added, and on 4 power-ons nobody saw the calibration with it is closer to the
    truth than the same warm-ups' paper model alone."""
    fs = _effect_life(effect, c)
    stats = [WarmupStats.from_features(f) for f in fs[:10]]
    d = decide(stats, None, AXES)
    assert d.adopt and d.axes_adopted == AXES, d.reasons
    assert all(d.effects[a] == (effect,) for a in AXES), d.reasons
    assert any(f"{effect} learnt" in r and "sign test" in r for r in d.reasons)
    cal = learnt_calibration(stats, AXES, estimator=EST, decision=d)
    paper_only = learnt_calibration(stats, AXES, estimator=EST,
                                    decision=replace(d, effects={}))
    assert not paper_only.effects
    for a in AXES:
        got = getattr(getattr(cal.effects[a], effect), param)
        assert got == pytest.approx(c, rel=0.25), a
        errs = [_error_vs_truth(k, a, fs[10:]) for k in (cal, paper_only)]
        assert errs[0] < 0.7 * errs[1], (a, errs)


def _effect_life(effect: str, c: float) -> list[RunFeatures]:
    """10 power-ons of a life (ambients 0…36 °C: the learnt range is 0.7…43 °C), then 4
    at ambients 5, 15, 25, 35 °C that nobody learns from (inside that range: what is
    scored is the model, not the clamp), all with the effect added."""
    runs = life(10, seed=33) + [power_on(a, seed=330 + k, name=f"held-{k}")
                                for k, a in enumerate((5.0, 15.0, 25.0, 35.0))]
    return [features(_with_effect(r, effect, c), EST) for r in runs]


def _error_vs_truth(cal, axis: str, fs: list[RunFeatures]) -> float:  # type: ignore[no-untyped-def]
    sq = [np.var((cal.bias_series(axis, f.temperature_c, f.delta_t_c, f.time_s)[0]
                  - f.true_bias_dps[axis])[warmup_rows(f)]) for f in fs]
    return math.sqrt(float(np.mean(sq)))


def test_an_effect_the_paper_model_absorbs_is_not_learnt() -> None:
    """A cubic of the paper terms' own size (1.5e-6 °/s/°C³: 0.064 °/s at −10 °C): within
    8 °C warm-ups with one offset each, the learnt paper model follows it (held-out
    warm-ups cannot tell the two apart), so it is not learnt, and the paper model alone
    is within a tenth of what no compensation leaves on power-ons nobody saw."""
    fs = _effect_life("cubic", 1.5e-6)
    stats = [WarmupStats.from_features(f) for f in fs[:10]]
    d = decide(stats, None, AXES)
    assert d.axes_adopted == AXES and not any(d.effects.values()), d.reasons
    cal = learnt_calibration(stats, AXES, estimator=EST, decision=d)
    for a in AXES:
        none = math.sqrt(float(np.mean([np.var(f.true_bias_dps[a][warmup_rows(f)])
                                        for f in fs[10:]])))
        assert _error_vs_truth(cal, a, fs[10:]) < 0.1 * none, a


@pytest.mark.parametrize("seed", [5, 6, 7])
def test_no_effect_is_learnt_from_a_gyro_without_one(seed: int) -> None:
    """The simulator's default truth is the paper model: over 10 and 30 power-ons nothing
    beyond it is learnt (development seeds 1–10 of scripts/learning_study.py: the same, for
    both gyros, at K = 3, 10 and 30; below 6 warm-ups the sign test cannot pass at all)."""
    stats = [WarmupStats.from_features(features(r, EST)) for r in life(30, seed=seed + 40)]
    for k in (10, 30):
        d = decide(stats[:k], None, AXES)
        assert not any(d.effects.values()), (k, d.reasons)


def test_a_learnt_effect_survives_its_file_and_the_online_kernel_agrees() -> None:
    """The learnt calibration with a ΔT² effect written as the daemon writes it (JSON of
    to_dict: version 2), read back by the calibration loader (schema and plausibility
    checks): the same effects, and the vehicle's row-by-row kernel gives the offline bias
    to 1e-9 °/s on a power-on nobody learnt from."""
    import json

    from gyrotherm.compensation import Compensator, parse_calibration

    fs = _effect_life("gradient_quadratic", 1e-2)
    stats = [WarmupStats.from_features(f) for f in fs[:10]]
    d = decide(stats, None, AXES)
    cal = learnt_calibration(stats, AXES, estimator=EST, decision=d)
    doc = json.loads(json.dumps(cal.to_dict(), allow_nan=False))
    assert doc["version"] == 2
    back = parse_calibration(json.dumps(doc), source="learnt.cal.json")
    assert back.effects == cal.effects and back.coefficients == cal.coefficients
    f = fs[12]
    comp = Compensator(back)
    online = {a: [] for a in AXES}  # type: dict[str, list[float]]
    for t, temp, dt in zip(f.time_s, f.temperature_c, f.delta_t_c, strict=True):
        est = comp.step(float(t), float(temp), float(dt))
        for a in AXES:
            online[a].append(est.bias_dps[a])
    for a in AXES:
        offline = cal.bias_series(a, f.temperature_c, f.delta_t_c, f.time_s)[0]
        np.testing.assert_allclose(online[a], offline, rtol=0, atol=1e-9)


def test_hostile_sums_are_refused_by_the_gate_not_raised() -> None:
    """A warm-up whose sums are finite but huge (1e300: a corrupt state that passed the
    finiteness check) makes the cross-products overflow: decide refuses on conditioning,
    naming it, instead of raising LinAlgError."""
    stats = [WarmupStats.from_features(features(r, EST)) for r in life(5, seed=8)]
    bad = replace(stats[2], szz=tuple(1e300 for _ in stats[2].szz))
    d = decide([*stats[:2], bad, *stats[3:]], None, AXES)
    assert not d.adopt and d.reasons[0].startswith("conditioning: ")


def test_leave_one_out_scales_with_the_warmups_not_their_square() -> None:
    """256 warm-ups (the state's bound): the fold slopes come from the pooled sums minus
    each warm-up's, equal to refitting without it (to 1e-9), and the decision counts the
    cross-products once per axis (by construction, not by a wall-clock bound)."""
    from gyrotherm.compensation._learn import _Folds

    base = [WarmupStats.from_features(features(r, EST)) for r in life(8, seed=9)]
    stats = [replace(base[k % 8], name=f"p{k}") for k in range(256)]
    folds = _Folds(stats, "x")
    for k in (0, 100, 255):
        np.testing.assert_allclose(
            folds.beta(k, PAPER), slopes([w for j, w in enumerate(stats) if j != k], "x")[0],
            rtol=1e-9, atol=1e-12)
    calls = 0
    real = WarmupStats.within

    def counting(self: WarmupStats, axis: str) -> tuple[np.ndarray, np.ndarray, float]:
        nonlocal calls
        calls += 1
        return real(self, axis)

    WarmupStats.within = counting  # type: ignore[method-assign]
    try:
        decide(stats, None, AXES)
    finally:
        WarmupStats.within = real  # type: ignore[method-assign]
    assert calls < 200 * 256  # O(warm-ups) per axis and model: O(warm-ups²) is 7.9e5


def test_the_extension_is_validated_with_the_margin_the_decision_used(
        feats: list[RunFeatures]) -> None:
    """`[learn] margin_frac` / `learn --margin` reach the widening too: with a margin no
    extrapolation can meet (99 %) nothing is adopted; with the decision's own margin
    replaced by 99 % after adopting, the range stays the data's."""
    stats = [WarmupStats.from_features(f) for f in feats[:10]]
    d = decide(stats, None, AXES)
    assert d.margin == 0.10 and d.to_dict()["margin"] == 0.10
    wide = learnt_calibration(stats, AXES, estimator=EST, decision=d)
    assert wide.provenance["validated_extrapolation_c"] != [0.0, 0.0]
    strict = learnt_calibration(stats, AXES, estimator=EST, decision=replace(d, margin=0.99))
    assert strict.provenance["validated_extrapolation_c"] == [0.0, 0.0]
    assert (strict.valid_range.t_min_c, strict.valid_range.t_max_c) == tuple(
        strict.provenance["coverage_c"])
    assert not decide(stats, None, AXES, margin=0.99).adopt
