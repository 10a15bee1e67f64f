"""Feature points of a layer (paper section 2.3, app.geometry.anatomy.feature_points) on
contours whose extrema are known."""

from __future__ import annotations

import numpy as np

from app.geometry.anatomy.feature_points import candidate_angles, radii_at, shared_angles
from app.geometry.sections import ray_angles


def _ellipse_radii(a: float, b: float, angles: np.ndarray) -> np.ndarray:
    """Polar radius (mm) of an a x b ellipse centred on the origin, at ``angles``."""
    return a * b / np.sqrt((b * np.cos(angles)) ** 2 + (a * np.sin(angles)) ** 2)


def test_an_ellipses_candidates_include_its_four_vertices():
    """S1 (radius extrema) of a 60 x 45 mm ellipse: 0, 90, 180 and 270 degrees."""
    angles = ray_angles(72)
    radii = np.stack([_ellipse_radii(60.0, 45.0, angles)] * 7)
    found = np.degrees(candidate_angles(radii, angles, 15))
    for vertex in (0.0, 90.0, 180.0, 270.0):
        assert np.min(np.abs((found - vertex + 180.0) % 360.0 - 180.0)) < 2.6


def test_shared_angles_are_m_distinct_angles_in_order():
    angles = ray_angles(72)
    radii = np.stack([_ellipse_radii(60.0, 45.0 + k, angles) for k in range(7)])
    chosen = shared_angles(candidate_angles(radii, angles, 15), 15)
    assert chosen.shape == (15,)
    assert np.all(np.diff(chosen) > 0) and chosen.min() >= 0 and chosen.max() < 2 * np.pi


def test_radii_at_interpolates_the_contour_periodically():
    """At the ray angles the radii are returned as they are; between rays, and across
    the 0/360 seam, they are interpolated (within 0.05 mm on a 60 x 45 mm ellipse)."""
    angles = ray_angles(72)
    radii = np.stack([_ellipse_radii(60.0, 45.0, angles)])
    assert np.allclose(radii_at(radii, angles, angles[:5])[0], radii[0, :5])
    between = np.array([np.radians(2.5), np.radians(358.0)])
    assert np.allclose(radii_at(radii, angles, between)[0], _ellipse_radii(60.0, 45.0, between), atol=0.05)
