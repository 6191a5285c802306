"""Plants drawn from the identification's covariance (components/identification/plant_sampling.py), no FMU."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

from components.identification.plant_samples import load_plant_samples
from components.identification.plant_sampling import (
    COEFFICIENTS,
    distribution,
    lhs_normal,
    sobol_design,
    sobol_indices,
)

from ..conftest import PROJECT

SAMPLES = PROJECT / "scenarios" / "plants" / "plant_samples_bouc_wen-joint.yaml"


@pytest.fixture(scope="module")
def shipped():
    nominal, samples = load_plant_samples(SAMPLES)
    rows = np.array([[getattr(s, n) for n in COEFFICIENTS] for s in samples])
    return nominal, samples, rows


def test_the_latin_hypercube_hits_each_stratum_of_each_margin_once():
    xi = lhs_normal(50, 3, seed=7)
    strata = np.floor(norm.cdf(xi) * 50).astype(int)
    for j in range(3):
        assert sorted(strata[:, j]) == list(range(50))
    assert np.array_equal(xi, lhs_normal(50, 3, seed=7)) and not np.array_equal(xi, lhs_normal(50, 3, seed=8))


def test_drawn_plants_have_the_bootstrap_covariance_and_keep_the_fixed_coefficients(shipped):
    """4,000 draws on all the axes: their standard deviations within 5 % of the bootstrap's and their correlations
    within 0.05 (the sampling error of 4,000 draws is about 1.6 % and 0.016 at 1 sigma); beta_1 and delta, which
    no refit moved, stay at the nominal fit's value, and the mean is the nominal fit (not the bootstrap mean)."""
    nominal, samples, rows = shipped
    dist = distribution(nominal, samples)
    assert [n for n in COEFFICIENTS if n not in dist.free_names] == ["beta_1", "delta"]
    assert dist.variances.sum() == pytest.approx(len(dist.free_names))
    theta = dist.coefficients(lhs_normal(4000, len(dist.variances), seed=1))
    free = dist.free
    assert np.all(theta[:, ~free] == dist.nominal[~free])
    np.testing.assert_allclose(theta[:, free].std(axis=0, ddof=1), rows[:, free].std(axis=0, ddof=1), rtol=0.05)
    np.testing.assert_allclose(np.corrcoef(theta[:, free], rowvar=False), np.corrcoef(rows[:, free], rowvar=False),
                               atol=0.05)
    # per coefficient: the draw's mean within 5 % of its own spread of the nominal fit (the bootstrap mean is
    # 0.1 to 0.19 of a spread away for six coefficients, so a draw centred on it would fail here)
    assert np.all(np.abs(theta.mean(axis=0) - dist.nominal)[free] <= 0.05 * dist.std[free])


def test_the_first_axes_carry_the_largest_share_and_the_rest_stay_at_zero(shipped):
    nominal, samples, _ = shipped
    dist = distribution(nominal, samples)
    assert np.all(np.diff(dist.variances) <= 0) and 0 < dist.explained(1) < dist.explained(4) < dist.explained(10)
    one = dist.coefficients(np.array([[1.0]]))[0]
    step = (one - dist.nominal)[dist.free] / dist.std[dist.free]
    np.testing.assert_allclose(step, np.sqrt(dist.variances[0]) * dist.axes[:, 0], rtol=1e-12)


def test_sobol_indices_of_a_linear_model_equal_its_variance_shares():
    """y = 3 xi_1 + 2 xi_2 + xi_3 with independent standard normals: S1 = ST = a_j^2 / sum(a^2) = 9/14, 4/14,
    1/14 exactly; SALib's estimate from 1,024 base points within 0.05 and within its own 95 % half-width x 3."""
    xi = sobol_design(1024, 3, seed=3)
    assert xi.shape == (1024 * 5, 3)
    y = xi @ np.array([3.0, 2.0, 1.0])
    ind = sobol_indices(y, 3, seed=3)
    exact = np.array([9.0, 4.0, 1.0]) / 14.0
    for key in ("S1", "ST"):
        err = np.abs(ind[key] - exact)
        assert np.all(err < 0.05), (key, ind[key])
        assert np.all(err < 3 * ind[f"{key}_conf"] + 0.01), (key, err, ind[f"{key}_conf"])


@pytest.mark.parametrize("path", ["/dev/zero", "/"])
def test_a_device_or_a_folder_is_refused_before_it_is_read(path):
    """/dev/zero read as a sample file would never end: it is refused by its kind, at once."""
    from components.identification.plant_samples import PlantSampleError

    with pytest.raises(PlantSampleError, match="not a regular file"):
        load_plant_samples(path)
