"""Laplace-law stocking design checked against numbers worked by hand."""

import numpy as np
import pytest

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.garment import (
    PA_PER_MMHG,
    DesignInputs,
    Fabric,
    design_stocking,
    local_pressure_pa,
    mean_pressure_pa,
    normalize_class,
    surface_rings,
)
from app.geometry.nurbs import surface_from_layers
from tests.conftest import fitted

HEIGHTS = np.array([0.0, 40.0, 80.0, 130.0, 180.0, 230.0, 280.0])
LANDMARKS = {"B": {"height_mm": 0.0}, "B1": {"height_mm": 80.0}, "C": {"height_mm": 180.0}, "D": {"height_mm": 280.0}}


def tube(a: float, b: float, m: int = 72):
    """An elliptic tube as the paper's surface (7 layers x m points), semi-axes a, b mm."""
    t = np.arange(m) * 2 * np.pi / m
    layers = np.stack([np.stack([a * np.cos(t), b * np.sin(t), np.full(m, z)], axis=1) for z in HEIGHTS])
    return surface_from_layers(layers)


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


def test_a_linear_tension_table_reproduces_the_stiffness():
    surface = tube(45.0, 38.0)
    linear = design_stocking(surface, LANDMARKS, "right", DesignInputs(fabric=Fabric.linear(12.0)))
    table = design_stocking(surface, LANDMARKS, "right", DesignInputs(fabric=Fabric.table([0.0, 0.3, 0.6, 1.0], [0.0, 3.6, 7.2, 12.0])))
    for a, b in zip(linear["knitting_spec"], table["knitting_spec"]):
        assert a["relaxed_circumference_mm"] == pytest.approx(b["relaxed_circumference_mm"], abs=1e-6)
        assert a["tension_N_per_cm"] == pytest.approx(b["tension_N_per_cm"], rel=1e-6)
    fabric = Fabric.table([0.1, 0.5, 0.9], [1.0, 4.0, 12.0])
    strains = np.array([0.1, 0.3, 0.7, 0.9])
    assert np.allclose(fabric.strain_for(fabric.tension(strains)), strains)


def test_design_meets_its_targets_and_grades_down_the_leg():
    surface = tube(33.0, 30.0)
    result = design_stocking(surface, LANDMARKS, "left", DesignInputs(compression_class="II", fabric=Fabric.linear(8.0)))
    b = result["landmarks"]["B"]
    assert 23 <= b["mean_pressure_mmHg"] <= 32
    assert b["mean_pressure_mmHg"] == pytest.approx(27.5, abs=0.5)  # the middle of class II
    p = [result["landmarks"][n]["mean_pressure_mmHg"] for n in ("B", "B1", "C", "D")]
    assert p[0] > p[1] > p[2] > p[3]
    assert result["ratios"]["D/B"] == pytest.approx(0.5, abs=0.02)
    assert result["passed"] and not result["side_assumed"]
    spec = result["knitting_spec"]
    spec_heights = np.array([row["height_mm"] for row in spec])
    assert set(np.arange(0.0, 281.0, 5.0)) <= set(np.round(spec_heights, 6))  # every 5 mm from B to D
    assert {0.0, 80.0, 180.0, 280.0} <= set(np.round(spec_heights, 6))  # and at the landmarks
    for row in spec:  # L0 = L / (1 + eps), knitted to 1 mm
        assert row["relaxed_circumference_mm"] == pytest.approx(round(row["stretched_circumference_mm"] / (1 + row["target_mmHg"] * PA_PER_MMHG * row["stretched_circumference_mm"] / (2 * np.pi * 1e5) / 8.0)), abs=1.0)


def test_explicit_targets_and_other_standards():
    surface = tube(33.0, 30.0)
    explicit = design_stocking(surface, LANDMARKS, None, DesignInputs(targets_mmhg={"B": 30, "B1": 25, "C": 20, "D": 12}, fabric=Fabric.linear(10)))
    assert explicit["landmarks"]["C"]["mean_pressure_mmHg"] == pytest.approx(20, abs=0.5)
    assert explicit["class"] is None and explicit["side_assumed"]
    assert normalize_class("bs", "class 2")[1:] == ("2", (18.0, 24.0))
    assert normalize_class("AFNOR", "III")[1] == "3"
    assert normalize_class("RAL", "ccl4")[2] == (49.0, None)


@pytest.mark.parametrize(
    "inputs,reason",
    [
        (dict(compression_class="IV", fabric=Fabric(stiffness_n_per_cm=1.0)), FailureReason.UNREACHABLE_PRESSURE),
        (dict(compression_class="III", fabric=Fabric(strains=(0.0, 0.05), tensions_n_per_cm=(0.0, 1.0), max_strain=0.05)), FailureReason.UNREACHABLE_PRESSURE),
        (dict(fabric=Fabric(stiffness_n_per_cm=-3.0)), FailureReason.INVALID_FABRIC),
        (dict(fabric=Fabric(stiffness_n_per_cm=5000.0)), FailureReason.INVALID_FABRIC),
        (dict(fabric=Fabric(strains=(0.0, 0.5, 0.4), tensions_n_per_cm=(0.0, 2.0, 3.0))), FailureReason.INVALID_FABRIC),
        (dict(compression_class="VII"), FailureReason.INVALID_TARGET),
        (dict(standard="ISO"), FailureReason.INVALID_TARGET),
        (dict(targets_mmhg={"B": 30, "B1": -5, "C": 20, "D": 10}), FailureReason.INVALID_TARGET),
        (dict(targets_mmhg={"B": 30, "C": 20, "D": 10}), FailureReason.INVALID_TARGET),
        (dict(hot_spot_limit_mmhg=-1), FailureReason.INVALID_TARGET),
    ],
)
def test_bad_designs_are_refused_with_a_reason(inputs, reason):
    with pytest.raises(FitFailure) as info:
        design_stocking(tube(33.0, 30.0), LANDMARKS, "right", DesignInputs(**inputs))
    assert info.value.reason == reason and info.value.detail


@pytest.mark.parametrize("file,side", [("bodyparts3d_right_leg.stl", None), ("vh_female_skin.glb", "left"),
                                       ("vh_female_skin.glb", "right"), ("vh_male_skin.glb", "left"), ("vh_male_skin.glb", "right")])
def test_real_legs_meet_class_ii_at_b_and_grade_down(file, side):
    _, result = fitted(file, side)
    landmarks = result.landmarks.as_dict()
    design = design_stocking(result.surface, landmarks, side or "right", DesignInputs(compression_class="II", fabric=Fabric.linear(10.0)))
    p = {n: design["landmarks"][n]["mean_pressure_mmHg"] for n in ("B", "B1", "C", "D")}
    assert 23 <= p["B"] <= 32
    assert p["B"] > p["B1"] > p["C"] > p["D"]
    assert design["passed"]
    # local pressures vary around the leg (the paper's Table 1): tendons and the tibia carry more
    sides = design["landmarks"]["B"]["sides_mmHg"]
    assert max(sides.values()) > 1.2 * min(sides.values())
    assert all(v >= 0 for v in sides.values())


def test_hot_spots_are_regions_and_one_region_across_the_seam():
    from app.geometry.garment import find_hot_spots

    surface = tube(40.0, 40.0)
    rings = surface_rings(surface, np.linspace(0, 280, 15), 360)
    local = np.full(rings.curvature.shape, 1000.0)
    local[3:6, 355:] = 9000.0  # one region crossing the seam at 0 degrees ...
    local[3:6, :4] = 9500.0
    local[10, 100:104] = 8000.0  # ... and one elsewhere
    spots = find_hot_spots(rings, local, 5000.0, {"east": 0.0, "north": np.pi / 2})
    assert len(spots) == 2
    seam, other = spots
    assert seam["peak_kPa"] == pytest.approx(9.5) and seam["samples"] == 3 * 9 and seam["side"] == "east"
    assert (seam["from_height_mm"], seam["to_height_mm"]) == (rings.heights_mm[3], rings.heights_mm[5])
    assert other["samples"] == 4 and other["height_mm"] == rings.heights_mm[10] and other["side"] == "north"
