"""Plants drawn from what the identification does not know: designs over the fitted coefficients' covariance.

The distribution is the bootstrap's (:mod:`plant_samples`: each sample one refit on a fresh noise realisation),
summarised by its covariance in SI units and centred on the nominal fit (the plant the studies run):

    theta = nominal + std * (V sqrt(lambda) xi),   xi ~ N(0, I)

with ``std`` the samples' standard deviations and ``V``, ``lambda`` the principal axes (eigenvectors, largest
eigenvalue first) of the correlation matrix of the coefficients that vary. ``xi`` are the decorrelated,
standardised coordinates: independent, so a variance-based sensitivity analysis can use them as its inputs
(Saltelli et al. 2010). Coefficients the bootstrap never moved (held by a bound in every refit: beta_1, delta)
stay at their nominal value. A Gaussian is an assumption: 64 bootstrap refits support a covariance, not a
shape (docs/assumptions.md).

Designs: a Latin hypercube (``scipy.stats.qmc``) mapped through the normal quantile, for each criterion's
spread; SALib's Saltelli extension of the Sobol' sequence (``SALib.sample.sobol``, first-order and total
indices, N (k + 2) points for k axes), for the Sobol indices (``SALib.analyze.sobol``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from components.physics.bouc_wen_core import COEFFICIENT_DOCS, BoucWenCurrentModel

COEFFICIENTS = tuple(COEFFICIENT_DOCS)
VARYING = 1e-3  # a coefficient varies when its std exceeds this share of |mean| (plant_samples.statistics)


@dataclass(frozen=True)
class PlantDistribution:
    """The coefficients' distribution: nominal, spread and principal axes, SI units, ``COEFFICIENTS`` order."""

    nominal: np.ndarray  # the nominal fit's coefficients
    std: np.ndarray  # standard deviation over the bootstrap samples (0 where fixed)
    free: np.ndarray  # bool: the coefficient varies over the samples
    axes: np.ndarray  # (n_free, n_free): columns are the principal axes of the free coefficients' correlation
    variances: np.ndarray  # the axes' eigenvalues, largest first (they sum to n_free)
    n_samples: int  # bootstrap samples behind it

    @property
    def free_names(self) -> list[str]:
        return [n for n, ok in zip(COEFFICIENTS, self.free, strict=True) if ok]

    def explained(self, k: int) -> float:
        """Share of the standardised variance the first ``k`` axes carry."""
        return float(self.variances[:k].sum() / self.variances.sum())

    def coefficients(self, xi: np.ndarray) -> np.ndarray:
        """(n, 12) coefficients for (n, k) standard-normal coordinates on the first k axes (the rest at 0)."""
        xi = np.atleast_2d(np.asarray(xi, dtype=float))
        k = xi.shape[1]
        if not 1 <= k <= len(self.variances):
            raise ValueError(f"{k} coordinates: the distribution has 1 to {len(self.variances)} axes")
        z = xi * np.sqrt(self.variances[:k]) @ self.axes[:, :k].T  # standardised free coefficients
        out = np.tile(self.nominal, (len(xi), 1))
        out[:, self.free] += z * self.std[self.free]
        return out


def _row(model: BoucWenCurrentModel) -> np.ndarray:
    return np.array([float(getattr(model, n)) for n in COEFFICIENTS])


def distribution(nominal: BoucWenCurrentModel, samples: Sequence[BoucWenCurrentModel]) -> PlantDistribution:
    """The distribution of :mod:`the module <plant_sampling>` from the nominal fit and its bootstrap samples."""
    rows = np.array([_row(s) for s in samples])
    if len(rows) < 3:
        raise ValueError(f"{len(rows)} samples: a covariance needs at least 3")
    std = rows.std(axis=0, ddof=1)
    free = std > VARYING * np.maximum(np.abs(rows.mean(axis=0)), 1e-300)
    if not free.any():
        raise ValueError("no coefficient varies over the samples")
    corr = np.atleast_2d(np.corrcoef(rows[:, free], rowvar=False))
    values, vectors = np.linalg.eigh(corr)
    order = np.argsort(values)[::-1]
    values, vectors = np.clip(values[order], 0.0, None), vectors[:, order]
    vectors = vectors * np.where(vectors[np.abs(vectors).argmax(axis=0), range(len(values))] < 0, -1.0, 1.0)
    return PlantDistribution(_row(nominal), np.where(free, std, 0.0), free, vectors, values, len(rows))


def lhs_normal(n: int, k: int, seed: int) -> np.ndarray:
    """(n, k) standard-normal coordinates from a seeded Latin hypercube (each margin's n strata hit once)."""
    from scipy.stats import norm, qmc

    return norm.ppf(qmc.LatinHypercube(d=k, rng=np.random.default_rng(seed)).random(n))


def sobol_problem(k: int) -> dict:
    """SALib's problem of k independent standard-normal axes (``dists: norm``, bounds [mean, sd])."""
    return {"num_vars": k, "names": [f"axis_{j + 1}" for j in range(k)], "bounds": [[0.0, 1.0]] * k,
            "dists": ["norm"] * k}


def sobol_design(n: int, k: int, seed: int) -> np.ndarray:
    """(n (k + 2), k) standard-normal coordinates of SALib's Saltelli design (first-order and total indices)."""
    from SALib.sample import sobol

    return np.asarray(sobol.sample(sobol_problem(k), n, calc_second_order=False, seed=seed))


def sobol_indices(y: np.ndarray, k: int, seed: int) -> dict[str, np.ndarray]:
    """First-order and total Sobol indices of the outputs ``y`` of :func:`sobol_design` (its row order), with
    their 95 % bootstrap half-widths (SALib.analyze.sobol): keys S1, S1_conf, ST, ST_conf."""
    from SALib.analyze import sobol

    result = sobol.analyze(sobol_problem(k), np.asarray(y, dtype=float), calc_second_order=False,
                           conf_level=0.95, seed=seed)
    return {key: np.asarray(result[key], dtype=float) for key in ("S1", "S1_conf", "ST", "ST_conf")}
