"""Girths on a surface (app.geometry.measures.surface_girths) of an elliptic tube whose
perimeter is known (Ramanujan's formula, exact to 1e-5 here)."""

from __future__ import annotations

import numpy as np

from app.geometry.measures.surface_girths import girths, surface_height_range
from tests.phantoms import paper_tube


def _ellipse_perimeter(a: float, b: float) -> float:
    h = ((a - b) / (a + b)) ** 2
    return float(np.pi * (a + b) * (1 + 3 * h / (10 + np.sqrt(4 - 3 * h))))


def test_the_girths_of_an_elliptic_tube_are_its_perimeter():
    surface = paper_tube(60.0, 45.0)
    z0, z1 = surface_height_range(surface)
    heights = np.linspace(z0 + 5.0, z1 - 5.0, 7)
    measured = girths(surface, heights)
    expected = _ellipse_perimeter(60.0, 45.0)
    for girth in measured:
        assert abs(girth.circumference_mm - expected) < 0.5  # the paper's interpolating surface, 72 points
        assert abs(girth.tape_mm - girth.circumference_mm) < 0.05  # a convex section: tape = perimeter


def test_heights_outside_the_surface_have_no_girth():
    surface = paper_tube(60.0, 45.0)
    z0, z1 = surface_height_range(surface)
    outside = girths(surface, np.array([z0 - 10.0, z1 + 10.0]))
    assert all(np.isnan(g.circumference_mm) for g in outside)
