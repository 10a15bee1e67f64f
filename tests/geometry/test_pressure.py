"""Laplace-law pressure on NURBS rings (app.geometry.garment.pressure) checked against numbers
worked by hand: a cylinder (T / r, Thomas's formula), an ellipse (the curvature ratio,
Ramanujan's perimeter), a groove the fabric bridges, hot-spot regions across the seam."""

import numpy as np
import pytest

from app.geometry.garment.pressure import (
    PA_PER_MMHG,
    find_hot_spots,
    local_pressure_pa,
    mean_pressure_pa,
    surface_rings,
)
from app.geometry.spline.nurbs import surface_from_layers
from tests.phantoms import PAPER_TUBE_HEIGHTS as HEIGHTS
from tests.phantoms import paper_tube as tube


def test_circular_cylinder_pressure_is_tension_over_radius_and_matches_thomas():
    surface = tube(50.0, 50.0)
    rings = surface_rings(surface, np.array([60.0, 150.0]), 720)
    assert np.all(rings.contact)  # a convex section: the fabric touches everywhere
    # the cubic spline's own curvature ripples by well under 0.1% with 72 points
    assert np.allclose(rings.curvature, 1 / 50.0, rtol=1e-3)
    tension = np.array([4.0, 4.0])  # N/cm
    local = local_pressure_pa(rings, tension)
    expected_pa = 4.0 * 100 / 0.050  # T [N/m] / r [m] = 8000 Pa
    assert np.allclose(local, expected_pa, rtol=1e-3)
    mean = mean_pressure_pa(rings, tension)
    assert np.allclose(mean, expected_pa, rtol=1e-3)
    # Thomas: P[mmHg] = T[kgf] * n * 4620 / (C[cm] * W[cm]), one layer, tension per 1 cm of width
    c_cm = rings.hull_perimeter / 10
    thomas_mmhg = (4.0 / 9.80665) * 1 * 4620 / (c_cm * 1.0)
    assert np.allclose(mean / PA_PER_MMHG, thomas_mmhg, rtol=2e-3)
    # the discrete integral of the local pressure over the contour is the mean times L
    integral = (local * rings.arc).sum(axis=1) / rings.hull_perimeter
    assert np.allclose(integral, mean, rtol=2e-3)


def test_ellipse_peak_pressure_sits_at_the_sharp_ends_by_the_curvature_ratio():
    a, b = 55.0, 40.0
    surface = tube(a, b)
    rings = surface_rings(surface, np.array([150.0]), 1440)
    tension = np.array([3.0])
    local = local_pressure_pa(rings, tension)[0]
    angle = rings.angle[0]
    peak = int(np.argmax(local))
    assert min(abs(angle[peak]), abs(angle[peak] - np.pi), abs(angle[peak] - 2 * np.pi)) < np.deg2rad(1.0)
    kappa_max, kappa_min = a / b**2, b / a**2  # at the ends of the major / minor axis
    assert local.max() == pytest.approx(1e5 * 3.0 * kappa_max, rel=0.01)
    assert local.min() == pytest.approx(1e5 * 3.0 * kappa_min, rel=0.01)
    assert local.max() / local.min() == pytest.approx((a / b) ** 3, rel=0.02)
    # mean 2 pi T / L with L the ellipse perimeter (Ramanujan)
    h = ((a - b) / (a + b)) ** 2
    perimeter = np.pi * (a + b) * (1 + 3 * h / (10 + np.sqrt(4 - 3 * h)))
    assert rings.hull_perimeter[0] == pytest.approx(perimeter, rel=1e-3)
    assert mean_pressure_pa(rings, tension)[0] == pytest.approx(1e5 * 2 * np.pi * 3.0 / perimeter, rel=1e-3)


def test_a_concave_section_is_bridged_by_the_fabric():
    m = 72
    t = np.arange(m) * 2 * np.pi / m
    r = 50 - 6 * np.exp(-(((t - np.pi / 2 + np.pi) % (2 * np.pi) - np.pi) / 0.3) ** 2)  # a groove at the front
    layers = np.stack([np.stack([r * np.cos(t), r * np.sin(t), np.full(m, z)], axis=1) for z in HEIGHTS])
    rings = surface_rings(surface_from_layers(layers), np.array([150.0]), 720)
    front = np.abs(rings.angle[0] - np.pi / 2) < np.deg2rad(5)
    assert not rings.contact[0][front].any()  # bridged: no pressure in the groove
    assert local_pressure_pa(rings, np.array([3.0]))[0][front].max() == 0.0
    assert rings.hull_perimeter[0] < rings.perimeter[0]


def test_hot_spots_are_regions_and_one_region_across_the_seam():
    surface = tube(40.0, 40.0)
    rings = surface_rings(surface, np.linspace(0, 280, 15), 360)
    local = np.full(rings.curvature.shape, 1000.0)
    local[3:6, 355:] = 9000.0  # one region crossing the seam at 0 degrees ...
    local[3:6, :4] = 9500.0
    local[10, 100:104] = 8000.0  # ... and one elsewhere
    spots = find_hot_spots(rings, local, 5000.0, {"east": 0.0, "north": np.pi / 2})
    assert len(spots) == 2
    seam, other = spots
    assert seam.peak_pa == pytest.approx(9500) and seam.samples == 3 * 9 and seam.side == "east"
    assert (seam.from_height_mm, seam.to_height_mm) == (rings.heights_mm[3], rings.heights_mm[5])
    assert other.samples == 4 and other.height_mm == rings.heights_mm[10] and other.side == "north"
