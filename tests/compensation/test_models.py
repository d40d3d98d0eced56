"""Model terms, centring and the physical-unit map, checked by hand and with the paper."""

from __future__ import annotations

import numpy as np
import pytest

from gyrotherm import CalibrationError
from gyrotherm.compensation import MODELS, Scaling, Term, get_model, mean_coefficients

# Tang et al. 2013, Table 1: a1..a5 per heating time (5, 10, 20, 30, 40, 50, 60 min).
TABLE1 = np.array([
    [0.0000019504876, -0.23537397, -7.4260978, 0.00098190674, 10315.948],
    [0.000002676828, -0.24618153, -3.6553626, 0.00044286063, 10354.223],
    [0.0000041203692, -0.27028934, -10.03044, 0.0013282806, 10453.302],
    [0.0000038654453, -0.26552597, -5.6036385, 0.00076193292, 10430.86],
    [0.0000021652523, -0.23869247, 2.9620516, -0.00037816028, 10326.501],
    [0.0000024462827, -0.24380525, -3.1428874, 0.00039041132, 10347.9],
    [0.0000040797022, -0.26828756, -9.0600264, 0.001377608, 10439.366],
])
# eq. (12), as printed, and the place value of the last printed digit of each.
EQ12 = np.array([0.00000304348, -0.25259, -5.13663, 0.000701, 10381.16])
EQ12_LAST_DIGIT = np.array([1e-11, 1e-5, 1e-5, 1e-6, 1e-2])


def test_term_names_round_trip() -> None:
    for spec in MODELS.values():
        assert tuple(Term.parse(n) for n in spec.term_names) == spec.terms
    assert MODELS["paper"].term_names == ("T^2", "T", "dT", "T*dT", "1")
    assert MODELS["t3"].term_names == ("T^3", "T^2", "T", "1")
    with pytest.raises(CalibrationError, match="unknown factor 'Q'"):
        Term.parse("Q*T")
    with pytest.raises(CalibrationError, match="unknown model 'quartic'"):
        get_model("quartic")


def test_physical_map_by_hand() -> None:
    # bias = c0·x² + c1·x + c2 with x = (T − 20)/10:
    # = c0/100·T² + (c1/10 − 40·c0/100)·T + (c2 − 2·c1 + 4·c0)
    s = Scaling(t_ref_c=20.0, t_scale_c=10.0, dt_scale_c=1.0)
    phys = s.to_physical(MODELS["t2"], np.array([3.0, 5.0, 7.0]))
    assert phys[Term(2, 0)] == pytest.approx(0.03)
    assert phys[Term(1, 0)] == pytest.approx(0.5 - 1.2)
    assert phys[Term(0, 0)] == pytest.approx(7 - 10 + 12)


def test_physical_map_round_trip_for_every_model() -> None:
    rng = np.random.default_rng(0)
    s = Scaling(t_ref_c=15.0, t_scale_c=35.0, dt_scale_c=20.0)
    for spec in MODELS.values():
        c = rng.normal(size=len(spec.terms))
        back = s.from_physical(spec, s.to_physical(spec, c))
        np.testing.assert_allclose(back, c, rtol=1e-9, atol=1e-12)
        # the design matrix reproduces the physical polynomial at random points
        t = rng.uniform(-20, 50, 50)
        d = rng.uniform(-5, 20, 50)
        phys = s.to_physical(spec, c)
        direct = sum(v * t**k.t_power * d**k.dt_power for k, v in phys.items())
        np.testing.assert_allclose(spec.design(*s.centre(t, d)) @ c, direct, rtol=1e-9)


def test_eq12_is_the_column_mean_of_table1() -> None:
    # Average in centred coordinates with one common scaling, as fit() does, and map
    # back: the result must be eq. (12) to the digits the paper prints.
    spec = MODELS["paper"]
    s = Scaling(t_ref_c=10000.0, t_scale_c=500.0, dt_scale_c=10.0)  # raw sensor units
    centred = [s.from_physical(spec, dict(zip(spec.terms, row, strict=True))) for row in TABLE1]
    phys = s.to_physical(spec, mean_coefficients(centred))
    got = np.array([phys[t] for t in spec.terms])
    # equal to the printed digits: within half a unit of the last printed digit
    assert np.all(np.abs(got - EQ12) <= 0.5 * EQ12_LAST_DIGIT + 1e-12 * np.abs(EQ12)), got


def test_table1_coefficients_are_nearly_collinear_uncentred() -> None:
    # The paper's point of departure for centring: a1 vs a2 and a2 vs a5 correlate at ≈ −0.999.
    corr = np.corrcoef(TABLE1.T)
    assert corr[0, 1] < -0.99 and corr[1, 4] < -0.99


def test_scaling_rejects_nonsense() -> None:
    with pytest.raises(CalibrationError, match="t_scale_c must be a positive number"):
        Scaling(0.0, 0.0, 1.0)
