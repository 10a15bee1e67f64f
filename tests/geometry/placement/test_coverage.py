"""A leg the scanner did not see all round (app.geometry.placement.coverage): the arcs
without skin, the refusal of a leg seen from one side, the warning of a bridged arc -
on synthetic sections and on BodyParts3D's real leg with skin taken away."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from app.geometry.anatomy.landmark_refusals import failure_stage
from app.geometry.errors import FailureReason, FitFailure
from app.geometry.fit.pipeline import FitOptions, check_scan, fit_scan
from app.geometry.garment.design import DesignInputs, design_stocking
from app.geometry.garment.fabric import Fabric
from app.geometry.garment.measuring_points import chart_of_record
from app.geometry.placement.coverage import arc_bridge_bound_mm, bridged_strip_refusal, chord_arcs_deg, partial_view
from app.geometry.scan.reader import load_scan
from app.geometry.sections.polar import PolarSections, largest_gap, ray_angles
from app.records.codec import record_from_fit
from tests.conftest import REAL


def test_the_largest_gap_is_the_longest_empty_run_round_the_turn_and_where_it_points():
    filled = np.ones((4, 72), dtype=bool)
    filled[0, 10:30] = False  # 20 bins of 5 degrees, middle at bin 19.5
    filled[1, :5] = False
    filled[1, 65:] = False  # 12 bins across angle 0 (65 ... 76), middle at bin 70.5
    filled[1, 30:33] = False  # a shorter run elsewhere
    filled[3] = False
    size, middle = largest_gap(filled)
    assert size.tolist() == [100.0, 60.0, 0.0, 360.0]
    assert np.degrees(middle[0]) == pytest.approx(97.5)
    assert np.degrees(middle[1]) == pytest.approx(352.5)
    assert np.isnan(middle[2])


def test_the_bridge_bound_is_the_tangents_less_the_chord_of_a_circles_missing_arc():
    """On a circle of radius r missing an arc a, the skin over the arc lies between its
    chord and the tangents at its ends: measured here from the points themselves."""
    r = 60.0
    for arc in (30.0, 60.0, 100.0):
        half = np.radians(arc) / 2
        ends = r * np.array([[np.cos(-half), np.sin(-half)], [np.cos(half), np.sin(half)]])
        chord = np.linalg.norm(ends[1] - ends[0])
        apex = np.array([r / np.cos(half), 0.0])  # where the two tangents meet
        tangents = np.linalg.norm(apex - ends[0]) + np.linalg.norm(apex - ends[1])
        assert chord < r * np.radians(arc) < tangents
        assert arc_bridge_bound_mm(r, arc) == pytest.approx(tangents - chord)


def _sections(gaps_deg: np.ndarray, middles_rad: np.ndarray) -> PolarSections:
    k = len(gaps_deg)
    return PolarSections(np.arange(k) * 3.0, np.zeros((k, 2)), np.full((k, 36), 50.0), ray_angles(36),
                         1.0 - gaps_deg / 360.0, gaps_deg, middles_rad)


def test_open_sections_on_one_side_are_a_partial_view_and_scattered_ones_are_not():
    """Half the sections open by 150 degrees: towards one side (a strip the scanner never
    saw) they are refused; in directions scattered round the leg (a sparse cloud's gaps)
    they are not, unless nearly every section is open."""
    rng = np.random.default_rng(3)
    gaps = np.where(np.arange(100) < 50, 150.0, 20.0)
    one_side = rng.normal(1.0, 0.3, 100)
    refused = partial_view(_sections(gaps, one_side))
    assert refused is not None and refused.reason is FailureReason.PARTIAL_VIEW
    assert "50% of its heights" in refused.detail and "on the same side" in refused.detail
    assert partial_view(_sections(gaps, rng.uniform(0, 2 * np.pi, 100))) is None
    assert partial_view(_sections(np.full(100, 150.0), rng.uniform(0, 2 * np.pi, 100))) is not None
    assert partial_view(_sections(np.where(np.arange(100) < 20, 150.0, 20.0), one_side)) is None  # holes, a cut end


def test_a_shape_refusal_read_through_a_strip_on_one_side_names_the_strip():
    """No knee waist found on a profile whose sections all miss 90 degrees on one side (below
    the partial-view limit, but a bridge that may move a 50 mm section's girth by 35 mm):
    the strip is named, with the shape reading's words; scattered gaps of the same size,
    a strip at a fifth of the heights, narrow gaps (a 30-degree bridge moves the girth by
    about 1 mm) and a refusal that is not about the leg's shape keep their refusal."""
    rng = np.random.default_rng(5)
    no_knee = FitFailure(FailureReason.NO_KNEE, "the knee waist is not in the scan. Re-scan above the knee.")
    one_side = rng.normal(1.0, 0.3, 100)
    assert partial_view(_sections(np.full(100, 90.0), one_side)) is None  # within the limit
    named = bridged_strip_refusal(no_knee, _sections(np.full(100, 90.0), one_side))
    assert named is not None and named.reason is FailureReason.PARTIAL_VIEW
    # inferred, not measured: it outranks the refusal it re-reads and yields to a knee found bent
    bent = FitFailure(FailureReason.KNEE_BENT, "the knee is bent by about 83 degrees")
    assert failure_stage(no_knee) < failure_stage(named) < failure_stage(bent)
    assert failure_stage(named) < failure_stage(FitFailure(FailureReason.PARTIAL_VIEW, "seen from one side"))
    assert "no_knee: the knee waist is not in the scan)" in named.detail and "100% of its heights" in named.detail
    assert f"off by {arc_bridge_bound_mm(50.0, 90.0):.0f} mm" in named.detail
    assert bridged_strip_refusal(no_knee, _sections(np.full(100, 90.0), rng.uniform(0, 2 * np.pi, 100))) is None
    assert bridged_strip_refusal(no_knee, _sections(np.where(np.arange(100) < 20, 90.0, 0.0), one_side)) is None
    assert bridged_strip_refusal(no_knee, _sections(np.full(100, 30.0), one_side)) is None
    sparse = FitFailure(FailureReason.TOO_SPARSE, "too sparse")
    assert bridged_strip_refusal(sparse, _sections(np.full(100, 90.0), one_side)) is None


def _seen_from_the_skins_centroid(radius: float, missing_deg: float, n_rays: int = 360) -> PolarSections:
    """One section as the slicer reads it: a circle (mm) missing an arc centred on angle 0,
    its rays cast from the centroid of the skin that remains (shifted away from the arc),
    each ray hitting the circle; the rays that land in the arc hit no skin."""
    half = np.radians(missing_deg) / 2
    skin = np.linspace(half, 2 * np.pi - half, 100_000)
    origin = np.array([radius * np.cos(skin).mean(), radius * np.sin(skin).mean()])  # (-x, 0): away from the arc
    angles = ray_angles(n_rays)
    direction = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    along = direction @ origin
    reach = -along + np.sqrt(along**2 - origin @ origin + radius**2)  # (a,) to the circle
    landing = np.arctan2(*(origin + reach[:, None] * direction).T[::-1])
    gap, middle = largest_gap((np.abs(landing) > half)[None, :])
    return PolarSections(np.zeros(1), origin[None, :], reach[None, :], angles, np.array([1.0 - gap[0] / 360.0]), gap,
                         middle)


def test_a_missing_arc_is_read_from_its_chord_not_from_the_remaining_skins_centre():
    """Seen from the centre of the skin that remains, a missing arc looks narrower than
    it is (the centre shifts away from it); the chord across it cuts the true arc from a
    circle of the section's radius."""
    for missing in (30.0, 53.0, 80.0):
        section = _seen_from_the_skins_centroid(60.0, missing)
        assert section.largest_gap_deg[0] < missing - 2.0  # seen narrower
        assert chord_arcs_deg(section)[0] == pytest.approx(missing, abs=2.0)
    whole = _sections(np.zeros(3), np.full(3, np.nan))
    assert chord_arcs_deg(whole).tolist() == [0.0, 0.0, 0.0]


@pytest.fixture(scope="module")
def leg() -> trimesh.Trimesh:
    return trimesh.load(REAL / "bodyparts3d_right_leg.stl")


def _angle_round_the_leg(points: np.ndarray) -> np.ndarray:
    """Degrees of each point round its 10 mm slab's centroid (the leg stands along z)."""
    slab = np.floor((points[:, 2] - points[:, 2].min()) / 10.0).astype(np.int64)
    count = np.bincount(slab)
    centre = np.stack([np.bincount(slab, points[:, i]) / count for i in range(2)], axis=1)[slab]
    return np.degrees(np.arctan2(points[:, 1] - centre[:, 1], points[:, 0] - centre[:, 0]))


def _without(leg: trimesh.Trimesh, gone, as_cloud: bool):
    """The leg without the skin where ``gone(points)`` (n,) bool: a mesh without the
    triangles touching it, or a scanner's dense cloud (60,000 points on the surface)."""
    if as_cloud:
        points, _ = trimesh.sample.sample_surface(leg, 60_000, seed=5)
        return load_scan(trimesh.PointCloud(points[~gone(points)]).export(file_type="ply"), file_type="ply")
    gone = gone(leg.vertices)
    kept = leg.copy()
    kept.update_faces(~gone[kept.faces].any(axis=1))
    kept.remove_unreferenced_vertices()
    return load_scan(kept.export(file_type="stl"), file_type="stl")


@pytest.mark.parametrize("as_cloud", [False, True])
def test_a_leg_seen_from_one_side_is_refused_as_a_partial_view(leg, as_cloud):
    """One camera's view (the skin whose normal faces it), as a mesh and as its vertices:
    refused for what it is, not as a leg without ankle or knee."""
    facing = leg.vertex_normals @ np.array([0.0, 1.0, 0.0]) > 0.17  # by more than 10 degrees
    scan = _without(leg, lambda p: ~facing[leg.kdtree.query(p)[1]], as_cloud)
    with pytest.raises(FitFailure) as caught:
        check_scan(scan, FitOptions(side="right"))
    assert caught.value.reason is FailureReason.PARTIAL_VIEW, caught.value.detail
    assert "does not go all round the leg" in caught.value.detail


@pytest.mark.parametrize("as_cloud", [False, True])
def test_a_strip_missing_along_the_leg_is_bridged_with_a_warning_the_whole_leg_has_none(leg, as_cloud):
    """A 60-degree strip along the whole leg (a scanner's blind side): the girths are
    read across it and the record says they may be off by the bridge's bound; the whole
    leg says nothing of the kind."""
    options = FitOptions(side="right")
    whole = _without(leg, lambda p: np.zeros(len(p), dtype=bool), as_cloud)
    fit = fit_scan(whole, options, placement=check_scan(whole, options))
    assert not any("misses an arc" in w for w in fit.warnings)
    scan = _without(leg, lambda p: np.abs(_angle_round_the_leg(p) - 45.0) < 30.0, as_cloud)
    try:
        stripped = fit_scan(scan, options, placement=check_scan(scan, options))
    except FitFailure as failure:  # a strip the calf's sections cannot be closed over
        assert failure.reason is FailureReason.PARTIAL_VIEW, failure.detail
        return
    said = [w for w in stripped.warnings if "misses an arc" in w]
    assert said and "take it by tape" in said[0]
    # the record keeps each bridged girth's bound; the chart states it and the design
    # from it is for review, asking for those girths by tape
    record = record_from_fit(stripped, scan.source_format, scan.units)
    bounds = {name: entry["girth_uncertainty_mm"] for name, entry in record.landmarks.items()
              if "girth_uncertainty_mm" in entry}
    assert bounds and all(bound > 3.0 for bound in bounds.values())
    chart = {m.point.name: m for m in chart_of_record(record.landmarks, record.scan.get("sole_mm"), "AD", record.chart)}
    assert all(chart[f"c{name}"].uncertainty_mm == bound for name, bound in bounds.items())
    design = design_stocking(record.surface, record.landmarks, "right",
                             DesignInputs(compression_class="II", fabric=Fabric.linear(10.0)), record.chart,
                             record.fit)
    verdict, reasons = design.verdict
    assert verdict in ("review", "fail")
    assert {f"c{name}" for name in bounds} <= {r.split()[0] for r in reasons if "misses an arc" in r}
    whole_record = record_from_fit(fit, whole.source_format, whole.units)
    assert not any("girth_uncertainty_mm" in entry for entry in whole_record.landmarks.values())
