"""Each point's share of the skin (app.geometry.scan.sampling): statistics over the skin,
not over how densely a scanner sampled it."""

from __future__ import annotations

import numpy as np

from app.geometry.scan.sampling import MAX_SHARE_RATIO, area_weights, weighted_quantile


def _cylinder(n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) points spread evenly over a cylinder's side (radius 50 mm, 200 mm high)."""
    angle, z = rng.uniform(0.0, 2 * np.pi, n), rng.uniform(0.0, 200.0, n)
    return np.column_stack([50.0 * np.cos(angle), 50.0 * np.sin(angle), z])


def test_a_side_sampled_four_times_sparser_weighs_as_much_as_the_dense_side():
    rng = np.random.default_rng(0)
    points = _cylinder(40_000, rng)
    sparse = points[:, 0] > 0
    kept = points[~sparse | (rng.random(len(points)) < 0.25)]
    weight = area_weights(kept)
    half = kept[:, 0] > 0
    assert half.mean() < 0.25  # the points: a fifth on the sparse half
    assert abs(weight[half].sum() / weight.sum() - 0.5) < 0.03  # the skin: half
    # the skin's mean lies on the axis; the points' leans 19 mm to the dense side
    mean_x = float((kept[:, 0] * weight).sum() / weight.sum())
    assert abs(mean_x) < 2.0 and kept[:, 0].mean() < -15.0


def test_a_stray_far_off_the_skin_stands_for_no_more_than_the_cap():
    rng = np.random.default_rng(1)
    points = np.vstack([_cylinder(5_000, rng), [[400.0, 0.0, 100.0]]])
    weight = area_weights(points)
    # its 8th neighbour is ~350 mm off (a skin point's ~3 mm): it would stand for ~10^4
    # skin points' area, and stands for MAX_SHARE_RATIO; the median point for 1
    assert weight[-1] == MAX_SHARE_RATIO
    assert np.median(weight) == 1.0


def test_weighted_quantiles_with_equal_weights_are_the_points_own():
    values = np.random.default_rng(2).normal(size=1001)
    for q in (0.02, 0.5, 0.98):
        assert weighted_quantile(values, np.ones(len(values)), q) == np.percentile(values, 100 * q, method="inverted_cdf")
    # a weight moves the quantile towards its value
    assert weighted_quantile(np.array([1.0, 2.0, 3.0]), np.array([1.0, 1.0, 10.0]), 0.5) == 3.0
