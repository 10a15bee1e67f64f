"""A section's points moved onto the curve they sample (app.geometry.sections.loop_smoothing),
on an ellipse shaped as a foot's heel-instep loop (130 x 60 mm) whose perimeter is known."""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull

from app.geometry.sections import project_on_local_quadratics

A, B = 65.0, 30.0


def _perimeter() -> float:
    """Ramanujan's second approximation (relative error ~1e-6 at this shape)."""
    h = ((A - B) / (A + B)) ** 2
    return float(np.pi * (A + B) * (1 + 3 * h / (10 + np.sqrt(4 - 3 * h))))


def _ellipse(spacing_mm: float, noise_mm: float = 0.0, seed: int = 0) -> np.ndarray:
    """Points (n, 2) about ``spacing_mm`` apart along the ellipse, moved along its normal
    by Gaussian noise of ``noise_mm``, in random order (a cloud's crossings come so)."""
    rng = np.random.default_rng(seed)
    t = rng.uniform(0.0, 2 * np.pi, int(_perimeter() / spacing_mm))
    normal = np.column_stack([B * np.cos(t), A * np.sin(t)])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    return np.column_stack([A * np.cos(t), B * np.sin(t)]) + rng.normal(0.0, noise_mm, (len(t), 1)) * normal


def test_a_clean_loop_keeps_its_length_and_a_repeated_point_counts_once():
    """Points on the curve stay on it (a quadratic is exact to second order): the hull of
    the moved points is the ellipse's perimeter within 0.1 mm; each point given twice (a
    mesh section's segment ends) reads the same."""
    points = _ellipse(1.0)
    moved = project_on_local_quadratics(points)
    assert abs(ConvexHull(moved).area - _perimeter()) < 0.1
    twice = project_on_local_quadratics(np.vstack([points, points[::-1]]))
    assert len(twice) == len(moved) and abs(ConvexHull(twice).area - ConvexHull(moved).area) < 1e-9


def test_a_scanners_noise_no_longer_widens_the_tape():
    """0.6 mm of noise across a dense loop (4 points a mm, a cloud's crossings) widens the
    raw points' hull by its outermost excursions (more than 3 mm); moved onto the local
    quadratics, the hull reads the perimeter within 0.6 mm, over five draws."""
    for seed in range(5):
        points = _ellipse(0.25, noise_mm=0.6, seed=seed)
        assert ConvexHull(points).area - _perimeter() > 3.0
        assert abs(ConvexHull(project_on_local_quadratics(points)).area - _perimeter()) < 0.6, seed


def test_a_sparse_loop_keeps_its_bends():
    """Points 9 mm apart at random (a body scanner's vertices: 34 round the loop, gaps up
    to ~25 mm): the reach grows to each point's 4th neighbour and no wider than Lepski's
    rule and MAX_REACH_MM allow, so the ellipse's tight ends (14 mm radius) are not spanned:
    over ten draws the loop reads on average no shorter than its chords' hull (2.2 mm
    short) and never 4 mm short, where the 16th neighbour's reach alone reads 36 mm short."""
    errors, chords = [], []
    for seed in range(10):
        points = _ellipse(9.0, seed=seed)
        moved = project_on_local_quadratics(points)
        assert np.isfinite(moved).all()
        errors.append(ConvexHull(moved).area - _perimeter())
        chords.append(ConvexHull(points).area - _perimeter())
    assert min(errors) > -4.0 and np.mean(errors) >= np.mean(chords) - 0.2, (errors, chords)


def test_noise_on_a_sparse_loop_is_averaged_over_the_wider_reach():
    """0.6 mm of noise on points 2 mm apart (a noisy mesh's section): the rule widens the
    reach where the wider fit agrees with the narrower within the noise, so over ten draws
    the loop reads within 0.5 mm of the perimeter on average and 1.0 on each."""
    errors = [ConvexHull(project_on_local_quadratics(_ellipse(2.0, noise_mm=0.6, seed=seed))).area - _perimeter()
              for seed in range(10)]
    assert abs(np.mean(errors)) < 0.5 and max(np.abs(errors)) < 1.0, errors
