"""The sole a standing person's lengths are measured from (app.geometry.anatomy.sole), on
the Visible Human female's right foot: as its mesh, as a dense cloud of its skin, with a
scanner's stray points under it, cut through the foot, and pointed."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from app.geometry.anatomy.foot import foot_measures
from app.geometry.anatomy.sole import FLAT_FOOT_MM, find_sole
from app.geometry.placement.place import place_leg
from tests.conftest import fitted


@pytest.fixture(scope="module")
def foot() -> tuple[np.ndarray, np.ndarray]:
    """The leg's vertices (n, 3) in the calf frame (mm) and its faces (f, 3)."""
    scan, _ = fitted("vh_female_skin.glb", "right")
    leg = place_leg(scan, "right")
    return leg.placement.frame.to_calf(leg.points), leg.faces


def _skin_cloud(points: np.ndarray, faces: np.ndarray, count: int = 150_000) -> np.ndarray:
    """(count, 3) points sampled evenly on the mesh's skin (about 1 mm apart on the foot)."""
    return trimesh.Trimesh(points, faces, process=False).sample(count, seed=5)


def test_a_standing_foot_stands_on_its_heels_lowest_skin(foot):
    points, faces = foot
    heel = points[(points[:, 1] <= 0.0) & (points[:, 2] < 0.0)]
    as_mesh = find_sole(points, faces)
    assert as_mesh.reason is None and as_mesh.height_mm == pytest.approx(float(heel[:, 2].min()))
    assert 90.0 < -as_mesh.height_mm < 170.0  # B above the floor (ANSUR II's malleolus height is 55-85 mm)
    as_cloud = find_sole(_skin_cloud(points, faces), None)
    assert as_cloud.reason is None and as_cloud.height_mm == pytest.approx(as_mesh.height_mm, abs=1.0)


def test_a_scanners_noise_does_not_lower_the_floor(foot):
    """1 mm of noise on every point of a dense cloud of the heel's skin (a scanner's
    noise moves points off the skin both ways): the lowest noisy point lies 1.5 mm or more
    below the clean skin's, and the heel's underside fitted over its skin stays within
    0.5 mm of the clean cloud's sole."""
    points, faces = foot
    cloud = _skin_cloud(points, faces)
    clean = find_sole(cloud, None).height_mm
    noisy = cloud + np.random.default_rng(3).normal(0.0, 1.0, cloud.shape)
    heel = noisy[(noisy[:, 1] <= 0.0) & (noisy[:, 2] < 0.0)]
    assert heel[:, 2].min() < clean - 1.5
    sole = find_sole(noisy, None)
    assert sole.reason is None and sole.height_mm == pytest.approx(clean, abs=0.5)


def test_a_clouds_stray_points_under_the_heel_are_not_its_sole(foot):
    """Ghosts 5-30 mm off the heel's skin and a floor's stray points a few mm under it, as
    a scanner leaves them: the sole stays within 1 mm of the clean cloud's, where the
    cloud's lowest point lies more than 5 mm lower."""
    points, faces = foot
    cloud = _skin_cloud(points, faces)
    clean = find_sole(cloud, None).height_mm
    rng = np.random.default_rng(7)
    heel = cloud[(cloud[:, 1] <= 0.0) & (cloud[:, 2] < clean + 15.0)]
    base = heel[rng.choice(len(heel), 40)]
    away = rng.normal(size=base.shape)
    away[:, 2] = -np.abs(away[:, 2])  # off the skin, downwards
    ghosts = base + away / np.linalg.norm(away, axis=1, keepdims=True) * rng.uniform(5.0, 30.0, (40, 1))
    floor = np.column_stack([rng.uniform(-150.0, 150.0, 300), rng.uniform(-150.0, 250.0, 300),
                             clean - rng.uniform(2.0, 4.0, 300)])
    noisy = np.vstack([cloud, ghosts, floor])
    assert noisy[:, 2].min() < clean - 5.0
    sole = find_sole(noisy, None)
    assert sole.reason is None and sole.height_mm == pytest.approx(clean, abs=1.0)


@pytest.mark.parametrize("as_cloud", [False, True])
def test_a_scan_cut_through_the_foot_has_no_sole(foot, as_cloud):
    """Cut 35 mm above the sole (the corpus's midfoot crops: 30-50 mm), the scan's lowest
    point is the cut, not the floor: no sole, and the reason says so."""
    points, faces = foot
    sole = find_sole(points, faces).height_mm
    kept = (points[faces, 2] > sole + 35.0).all(axis=1)
    if as_cloud:
        cut, cut_faces = _skin_cloud(points, faces[kept]), None
    else:
        cut, cut_faces = points, faces[kept]
        cut = cut[np.unique(cut_faces)]
        cut_faces = np.searchsorted(np.unique(faces[kept]), faces[kept])
    found = find_sole(cut, cut_faces)
    assert found.height_mm is None and "cut through the foot" in found.reason


@pytest.mark.parametrize("angle_deg,pointed", [(5.0, False), (25.0, True)])
def test_a_pointed_foot_has_no_floor_and_its_foot_is_not_measured(foot, angle_deg, pointed):
    """The foot turned toes-down about the ankle (60 mm above the sole): 5 degrees stands
    (the ball lowers ~15 mm, within FLAT_FOOT_MM), 25 degrees is pointed - no floor, and
    the foot's girths are not read on it."""
    points, faces = foot
    sole = find_sole(points, faces).height_mm
    pivot = sole + 60.0
    t = np.radians(angle_deg)
    turned = points.copy()
    below = points[:, 2] < pivot
    y, z = points[below, 1], points[below, 2] - pivot
    turned[below, 1], turned[below, 2] = y * np.cos(t) + z * np.sin(t), pivot - y * np.sin(t) + z * np.cos(t)
    found = find_sole(turned, faces)
    if not pointed:
        assert found.reason is None
        return
    assert found.height_mm is None and "pointed" in found.reason and f"within {FLAT_FOOT_MM:.0f} mm" in found.reason
    measures = foot_measures(turned, faces, found.height_mm, found.reason)
    assert measures.ball_girth.value_mm is None and measures.ball_girth.reason == found.reason


def test_a_scanners_streaks_are_neither_the_heels_back_nor_the_foots_ends(foot):
    """Streaks (lines of 40 points leaving the skin, 30-80 mm long, as a scanner leaves
    them) backwards off the heel a few mm above the sole and forwards off the toes: the
    sole, the foot's length and cY stay within 1 mm of the clean cloud's - read as skin,
    the heel's streak made the heel's back run down to the sole (no floor) and the toes'
    lengthened the foot by the streak."""
    points, faces = foot
    cloud = _skin_cloud(points, faces)
    clean_sole = find_sole(cloud, None).height_mm
    clean = foot_measures(cloud, None, clean_sole)
    heel = cloud[(cloud[:, 1] <= 0.0) & (np.abs(cloud[:, 2] - clean_sole - 5.0) < 1.0)]
    toes = cloud[cloud[:, 2] < clean_sole + 30.0]
    starts = [heel[np.argmin(heel[:, 1])], toes[np.argmax(toes[:, 1])]]
    rng = np.random.default_rng(3)
    streaks = [start + np.outer(rng.uniform(0.0, 60.0, 40), [0.0, direction, 0.0])
               for start, direction in zip(starts, (-1.0, 1.0))]
    streaked = np.vstack([cloud, *streaks])
    sole = find_sole(streaked, None)
    assert sole.reason is None and sole.height_mm == pytest.approx(clean_sole, abs=1.0)
    measures = foot_measures(streaked, None, sole.height_mm)
    assert measures.foot_length.value_mm == pytest.approx(clean.foot_length.value_mm, abs=1.0)
    assert measures.heel_instep_girth.value_mm == pytest.approx(clean.heel_instep_girth.value_mm, abs=1.0)
