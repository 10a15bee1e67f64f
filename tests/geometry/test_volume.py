"""Volume between two heights, from the surface (divergence theorem, Gauss quadrature)."""

from __future__ import annotations

import numpy as np
import pytest

from app.geometry.measures.volume import volume_between
from app.geometry.spline.nurbs import NurbsSurface
from tests.conftest import fitted


def _circle_net(radius: float) -> tuple[np.ndarray, np.ndarray]:
    """The NURBS Book's 9-point rational quadratic circle (section 7.5): (9, 2) xy, (9,) w."""
    corners = np.array([[1, 0], [1, 1], [0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, -1], [1, 0]], dtype=float)
    weights = np.array([1, np.sqrt(0.5)] * 4 + [1])
    return corners * radius, weights


def tube(radius_low: float, radius_high: float, length: float) -> NurbsSurface:
    """An exact circular frustum (a cylinder when the radii agree): rational quadratic
    around, linear along, z from 0 to length (mm)."""
    rows = []
    for radius, z in ((radius_low, 0.0), (radius_high, length)):
        xy, w = _circle_net(radius)
        rows.append(np.column_stack([xy, np.full(9, z)]))
    control = np.stack(rows, axis=1)  # (9, 2, 3)
    weights = np.stack([w, w], axis=1)
    knots_u = np.array([0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1], dtype=float)
    knots_v = np.array([0, 0, 1, 1], dtype=float)
    return NurbsSurface(2, 1, knots_u, knots_v, control, weights, periodic_u=False)


@pytest.mark.parametrize("low,high", [(0.0, 300.0), (12.5, 187.0)])
def test_volume_of_a_cylinder(low, high):
    exact = np.pi * 40.0**2 * (high - low)
    assert volume_between(tube(40.0, 40.0, 300.0), low, high) == pytest.approx(exact, rel=1e-4)


@pytest.mark.parametrize("low,high", [(0.0, 300.0), (50.0, 120.0)])
def test_volume_of_a_cone_frustum(low, high):
    def radius(z):
        return 30.0 + (55.0 - 30.0) * z / 300.0

    r0, r1 = radius(low), radius(high)
    exact = np.pi * (high - low) / 3.0 * (r0 * r0 + r0 * r1 + r1 * r1)
    assert volume_between(tube(30.0, 55.0, 300.0), low, high) == pytest.approx(exact, rel=1e-4)


def test_volume_of_a_real_calf_agrees_with_its_sections_and_adds_up():
    """The calf between B and D: the same volume as the integral of the resampled
    sections' areas (trapezoid rule over 200 sections, ~0.5%), and additive over a
    split at C."""
    _, result = fitted("bodyparts3d_right_leg.stl", None)
    lm = result.landmarks
    whole = volume_between(result.surface, lm.B.height_mm + 1.0, lm.D.height_mm - 1.0)
    parts = (volume_between(result.surface, lm.B.height_mm + 1.0, lm.C.height_mm)
             + volume_between(result.surface, lm.C.height_mm, lm.D.height_mm - 1.0))
    assert parts == pytest.approx(whole, rel=1e-9)
    sections = result.sections
    a = sections.angles_rad
    r = sections.radii_mm
    area = 0.5 * (r * np.roll(r, -1, axis=1) * np.sin(np.roll(a, -1) - a + 2 * np.pi * (np.roll(a, -1) < a))).sum(axis=1)
    h = sections.heights_mm
    inside = (h >= lm.B.height_mm + 1.0) & (h <= lm.D.height_mm - 1.0)
    from_sections = np.trapezoid(area[inside], h[inside])
    assert whole == pytest.approx(from_sections, rel=0.01)
    assert 0.5e6 < whole < 3e6  # 0.5-3 litres: a calf


def test_heights_outside_the_surface_are_refused():
    with pytest.raises(ValueError):
        volume_between(tube(40.0, 40.0, 300.0), -10.0, 100.0)
    with pytest.raises(ValueError):
        volume_between(tube(40.0, 40.0, 300.0), 100.0, 50.0)
