"""Scan clean-up on a real leg: a scanner platform sampled as a point cloud is removed."""

import numpy as np
import trimesh

from app.geometry.fit.pipeline import FitOptions, check_scan, fit_scan
from app.geometry.scan import cleanup as cleanup
from app.geometry.scan.reader import Scan
from tests.conftest import REAL


def _leg_on_platform(platform_share: float, seed: int = 3):
    """The BodyParts3D right leg (mm) as a 60k-point cloud standing on a 700 x 40 x 700 mm
    box, whose surface is sampled as ``platform_share`` of the leg's points (its top, its
    bottom and its sides, as a scanner sees a platform)."""
    leg = trimesh.load(REAL / "bodyparts3d_right_leg.stl")
    rng = np.random.default_rng(seed)
    cloud = trimesh.sample.sample_surface(leg, 60_000, seed=seed)[0]
    centred = cloud - cloud.mean(axis=0)
    axis = np.linalg.eigh(centred.T @ centred)[1][:, -1]
    heights = cloud @ axis
    # the foot is the end whose points spread widest across the axis
    low, high = heights < np.percentile(heights, 5), heights > np.percentile(heights, 95)
    if np.ptp(centred[low], axis=0).sum() < np.ptp(centred[high], axis=0).sum():
        axis, heights = -axis, -heights
    sole = heights.min()
    box = trimesh.creation.box(extents=(700.0, 700.0, 40.0))
    # box z along the leg's axis, its top face 1 mm under the sole
    rotation = trimesh.geometry.align_vectors([0, 0, 1], axis)
    box.apply_transform(rotation)
    box.apply_translation(cloud.mean(axis=0) + (sole - cloud.mean(axis=0) @ axis - 21.0) * axis)
    platform = trimesh.sample.sample_surface(box, int(platform_share * len(cloud)), seed=seed)[0]
    points = np.vstack([cloud, platform + rng.normal(0.0, 0.5, platform.shape)])
    return points, len(cloud)


def test_a_platform_cloud_is_removed_top_and_bottom():
    points, n_leg = _leg_on_platform(0.3)
    clean = cleanup.clean_scan(points, None)
    assert clean.floor is not None
    # every platform point goes, and the leg keeps nearly all of its points (the sole
    # within the floor tolerance goes with the floor)
    assert len(clean.points) <= n_leg
    assert len(clean.points) >= 0.97 * n_leg
    assert np.ptp(clean.points, axis=0).max() < 1000


def test_a_leg_on_a_platform_cloud_is_fitted_as_without_it():
    points, n_leg = _leg_on_platform(0.3)
    options = FitOptions()
    alone = Scan(points[:n_leg], None, "mm", False, "xyz")
    on_platform = Scan(points, None, "mm", False, "xyz")
    girths = [fit_scan(s, options, placement=check_scan(s, options)).landmarks.tape_girths_mm
              for s in (alone, on_platform)]
    for name in ("B", "C"):
        assert abs(girths[0][name] - girths[1][name]) < 1.0


def test_a_leg_alone_has_no_floor():
    points, n_leg = _leg_on_platform(0.0)
    assert cleanup.find_floor(points[:n_leg]) is None


def test_a_replayed_clean_up_keeps_the_same_points_and_pieces():
    """The fit repeats the upload check's clean-up from the floor planes and voxel size
    the check found (carried in the placement as JSON), without RANSAC or the spacing
    search: the same points, in the same pieces."""
    import json

    from app.geometry.placement.leg_placement import LegPlacement
    from app.geometry.placement.place import place_leg

    points, _ = _leg_on_platform(0.3)
    scan = Scan(points, None, "mm", False, "xyz")
    searched = cleanup.clean_scan(points, None)
    placement = LegPlacement.from_dict(json.loads(json.dumps(place_leg(scan, None).placement.to_dict())))
    assert len(placement.cleanup.floors) == len(searched.floors) >= 1
    assert placement.cleanup.voxel_mm == searched.voxel_mm
    replayed = cleanup.clean_scan(points, None, placement.cleanup)
    assert np.array_equal(replayed.points, searched.points)
    assert len(replayed.pieces) == len(searched.pieces)
    assert all(np.array_equal(a, b) for a, b in zip(replayed.pieces, searched.pieces))
    assert replayed.floor.n_removed == searched.floor.n_removed


def test_a_placement_stored_without_the_clean_up_still_replays():
    """Placements stored before the clean-up was kept in them (queued jobs across an
    upgrade) have no floors: the clean-up is searched for again, with the same leg."""
    from app.geometry.placement.leg_placement import LegPlacement
    from app.geometry.placement.place import place_leg, replace_leg

    points, _ = _leg_on_platform(0.3)
    scan = Scan(points, None, "mm", False, "xyz")
    data = place_leg(scan, None).placement.to_dict()
    for key in ("floors", "voxel_mm", "spacing_p95_mm"):
        data.pop(key)
    old = LegPlacement.from_dict(data)
    assert old.cleanup is None
    new = LegPlacement.from_dict(place_leg(scan, None).placement.to_dict())
    assert np.array_equal(replace_leg(scan, old).points, replace_leg(scan, new).points)


def test_rings_further_apart_than_their_points_are_one_piece():
    """A 400 mm tube of rings 25 mm apart, 120 points (3 mm) round each: the first
    voxel (3 x the median spacing, 9 mm; touching voxels join points up to 19 mm apart)
    leaves every ring alone; it grows until the
    rings join, and a ring 110 mm beside the tube stays a piece of its own."""
    theta = np.linspace(0.0, 2 * np.pi, 120, endpoint=False)
    z = np.arange(0.0, 400.0, 25.0)
    ring = np.column_stack([60.0 * np.cos(theta), 60.0 * np.sin(theta)])
    tube = np.column_stack([np.tile(ring, (len(z), 1)), np.repeat(z, len(theta))])
    apart = np.column_stack([ring * 0.5 + [200.0, 0.0], np.full(len(theta), 200.0)])
    points = np.vstack([tube, np.repeat(apart, 8, axis=0) + np.random.default_rng(1).normal(0, 0.1, (8 * 120, 3))])
    first = max(cleanup.VOXEL_FACTOR * float(np.median(cleanup.neighbour_distances(points))), cleanup.MIN_VOXEL_MM)
    assert len(np.unique(cleanup.voxel_pieces(tube, first))) == len(z)
    voxel, labels = cleanup.joining_voxel(points, first)
    assert np.array_equal(labels, cleanup.voxel_pieces(points, voxel))
    assert len(np.unique(labels[: len(tube)])) == 1
    assert not np.isin(labels[len(tube):], labels[: len(tube)]).any()
