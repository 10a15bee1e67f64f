"""Finding B, C and D on a circumference profile (app.geometry.anatomy.landmarks):
synthetic girth profiles (mm) of a lower leg with the shapes scans gave trouble with."""

import numpy as np
import pytest
from scipy.interpolate import PchipInterpolator

from app.geometry.anatomy.calf_candidates import MAX_CALF_ELONGATION, merged_above
from app.geometry.anatomy.landmarks import find_feature_heights
from app.geometry.errors import CalfWithoutBulge, FailureReason, FitFailure, JoinedAboveCalf


def _calf_with_a_flank_bump(top_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """A lower leg's girth every 2 mm from below the ankle to ``top_mm`` (mm): the
    ankle's waist (225 mm round at 40 mm), a calf maximum of 385 mm at 280 mm, a knee
    waist of 335 mm at 390 mm, and on the calf's rising flank a bump of a sparse cloud's
    noise (+6 mm at 170 mm, over +-12 mm)."""
    z = np.arange(0.0, top_mm, 2.0)
    calf = np.interp(z, [0, 40, 280, 390, 460], [250, 225, 385, 335, 400])
    calf = np.convolve(np.pad(calf, 15, mode="edge"), np.ones(31) / 31, mode="valid")  # round the corners
    bump = 6.0 * np.clip(1.0 - np.abs(z - 170.0) / 12.0, 0.0, None)
    return z, calf + bump


def test_a_bump_on_the_calfs_rising_flank_is_not_the_calf():
    """The bump is a local maximum with an ankle below it and the flank rising above it:
    read as a calf whose "knee waist" is the flank 30 mm up, wider than the bump.  A knee
    waist wider than the calf's maximum by more than MAX_KNEE_OVER_CALF is no knee
    waist: with the knee in the scan the real calf is found; with the scan stopping on
    the calf's falling side, the refusal says the knee waist is missing, not a record of
    a 290 mm "calf" 110 mm below the real one."""
    z, girth = _calf_with_a_flank_bump(460.0)
    found = find_feature_heights(z, girth)
    assert abs(found.c_mm - 280.0) < 15.0 and abs(found.d_mm - 390.0) < 15.0
    z, girth = _calf_with_a_flank_bump(350.0)  # stops 70 mm above C, the leg still narrowing
    with pytest.raises(FitFailure) as caught:
        find_feature_heights(z, girth)
    assert caught.value.reason is FailureReason.NO_KNEE, caught.value.detail


@pytest.mark.parametrize("dip_mm", [0.0, 5.0])
def test_a_shoulder_below_the_calfs_maximum_is_not_the_calf_when_the_knee_waist_is_missing(dip_mm):
    """A bump 50 mm below the calf maximum (+8 mm over +-10 mm, on a flank rising 0.6 mm
    per mm), in a scan that stops 95 mm above the maximum, before the knee waist (410
    mm): the bump has an ankle below it and, 30-40 mm up, a "knee waist" - its window's
    bottom, or a noise dip 5 mm deep at 292 mm - 1.03 times as wide (within
    MAX_KNEE_OVER_CALF), and was read as the calf (on sparse vertex clouds of knee-high
    scans: C 50-55 mm low, D 120-140 mm low).  That "waist" is wider than the bump and
    the leg rises above it to a larger maximum that falls again: the calf.  The scan is
    refused for its missing knee waist; with the knee in the scan the calf is found."""
    for top, refused in ((395.0, True), (520.0, False)):
        z = np.arange(0.0, top, 2.0)
        calf = np.interp(z, [0, 40, 300, 410, 520], [250, 225, 390, 335, 400])
        calf = np.convolve(np.pad(calf, 15, mode="edge"), np.ones(31) / 31, mode="valid")
        girth = (calf + 8.0 * np.clip(1.0 - np.abs(z - 250.0) / 10.0, 0.0, None)
                 - dip_mm * np.clip(1.0 - np.abs(z - 292.0) / 6.0, 0.0, None))
        if refused:
            with pytest.raises(FitFailure) as caught:
                find_feature_heights(z, girth)
            assert caught.value.reason is FailureReason.NO_KNEE, caught.value.detail
        else:
            found = find_feature_heights(z, girth)
            assert abs(found.c_mm - 300.0) < 10.0 and abs(found.d_mm - 410.0) < 10.0


def test_a_pointed_foots_narrow_toes_are_not_the_ankle():
    """A foot pointed in line with the shank (plantar flexion 44 degrees, as a corpus scan
    that was refused): going down from the calf the girth narrows to the ankle (225 mm),
    swells over the heel and instep (295 mm) and narrows again along the toes (a dip to
    208 mm, then less) - sections as elongated as a foot's (1.4-2.0, a calf's 1.0-1.1).  The
    toes' minimum is not B: B is the ankle's, and the calf and knee waist above it are
    found; read without the elongation the toes' minimum is taken for B and refused."""
    z = np.arange(0.0, 800.0, 2.0)
    girth = np.interp(z, [0, 40, 60, 80, 110, 130, 170, 300, 400, 470, 560, 700, 800],
                      [150, 212, 208, 215, 295, 293, 225, 232, 379, 345, 340, 420, 500])
    elongation = np.interp(z, [0, 60, 90, 110, 140, 170, 800], [2.0, 1.5, 1.4, 1.5, 1.42, 1.2, 1.03])
    assert elongation[np.argmin(np.abs(z - 60))] > MAX_CALF_ELONGATION
    found = find_feature_heights(z, girth, elongation=elongation)
    assert 150.0 < found.b_mm < 300.0 and abs(found.c_mm - 400.0) < 20.0 and 460.0 < found.d_mm < 600.0
    with pytest.raises(FitFailure):
        find_feature_heights(z, girth)


def test_a_toe_tips_partial_sections_at_the_scans_edge_do_not_hide_the_ankle():
    """A whole leg read from the toe tip up, every 3 mm (benchmarks/chart_accuracy.py 8
    17, leg 7, a cloud with stray points, its profile's first 6 sections as measured):
    partial sections of the toe tip, 100-140 mm round and not all elongated, make a local
    minimum at the scan's edge far narrower than the ankle (233 mm, 120 mm up).  Too near
    the edge to be B, it used to be taken as the narrowest minimum and then set aside,
    and the ankle above it with it: no_ankle.  The ankle is B, as without the toe tip."""
    z = np.arange(0.0, 760.0, 3.0)
    girth = np.interp(z, [18, 24, 36, 60, 100, 120, 330, 470, 560, 760], [465, 427, 400, 345, 245, 233, 397, 320, 330, 570])
    girth[:6] = [np.nan, 136.9, 114.1, 102.4, 110.1, 176.2]
    elongation = np.interp(z, [15, 60, 100, 120, 330, 760], [1.7, 1.5, 1.26, 1.15, 1.04, 1.07])
    elongation[:6] = [1.29, 1.45, 1.25, 1.3, 1.15, 1.28]
    found = find_feature_heights(z, girth, elongation=elongation)
    assert abs(found.b_mm - 120.0) <= 6.0 and abs(found.c_mm - 330.0) < 20.0 and 400.0 < found.d_mm < 560.0
    edge = z >= 18.0
    again = find_feature_heights(z[edge], girth[edge], elongation=elongation[edge])
    assert (again.b_mm, again.c_mm, again.d_mm) == pytest.approx((found.b_mm, found.c_mm, found.d_mm))


def test_a_calf_whose_crown_rises_over_three_bumps_is_read_at_the_highest():
    """Three calf maxima over one ankle and one knee waist, each higher than the one below
    (a calf bulge the scan left ribbed: the profile of a cloud missing a strip along the
    leg, benchmarks/coverage.py): C is the highest.  The crown merge walked from the
    highest back down over the lower ones and read an empty stretch of the profile - a
    ValueError, which the service answered as a 500."""
    z = np.arange(0.0, 700.0, 2.0)
    knots = np.array([(0, 300), (100, 220), (200, 330), (260, 362), (285, 358), (310, 367), (335, 363), (360, 372),
                      (400, 360), (470, 335), (560, 380), (700, 430)], dtype=float)
    girth = PchipInterpolator(knots[:, 0], knots[:, 1])(z)
    found = find_feature_heights(z, girth)
    assert abs(found.c_mm - 360.0) <= 6.0
    assert abs(found.b_mm - 100.0) <= 10.0 and abs(found.d_mm - 470.0) <= 10.0


def test_a_bump_of_the_heel_does_not_hide_a_scan_ending_inside_the_calf():
    """A leg cut 45 mm below its knee waist, foot down (robustness cut_below_knee-04): the
    toes and instep are elongated (1.45-2.0, a foot's), a bump of the heel between them
    (326 mm) is not, and above the ankle (220 mm) the girth rises to the top edge.  The
    heel's bump finds no ankle below it, but it lies under the foot's highest elongated
    section, so it is no calf and says nothing of the leg above: the scan ends inside the
    calf (NO_KNEE, with the rise).  Counted as a calf's missing ankle, it kept that
    refusal back and the scan was refused as "a foot, not a calf"."""
    z = np.arange(0.0, 380.0, 2.0)
    girth = np.interp(z, [0, 30, 45, 58, 70, 120, 380], [150, 363, 318, 326, 318, 220, 345])
    elongation = np.interp(z, [0, 30, 50, 66, 80, 95, 130, 380], [2.0, 1.6, 1.3, 1.3, 1.45, 1.3, 1.1, 1.05])
    with pytest.raises(FitFailure) as caught:
        find_feature_heights(z, girth, elongation=elongation)
    assert caught.value.reason is FailureReason.NO_KNEE, caught.value.detail
    assert "ends inside the calf" in caught.value.detail


def _swollen_leg_profile(ankle_mm: float, calf_mm: float, knee_waist_mm: float,
                         lower_thigh_mm: float | None = None) -> tuple[np.ndarray, ...]:
    """A whole leg's girth every 2 mm from the toes up (mm): the foot (elongated sections,
    1.5-2.2, up to 70 mm), the ankle's girth ``ankle_mm`` at 110 mm, the calf's greatest
    ``calf_mm`` at 300 mm, the knee waist ``knee_waist_mm`` at 440 mm and the thigh rising
    (through ``lower_thigh_mm`` at 560 mm when given) to 560 mm round at 800 mm; with the
    elongations (a calf's 1.05-1.1)."""
    z = np.arange(0.0, 800.0, 2.0)
    thigh = [] if lower_thigh_mm is None else [(560, lower_thigh_mm)]
    knots = np.array([(0, 200), (40, 420), (70, 400), (110, ankle_mm), (300, calf_mm), (440, knee_waist_mm),
                      *thigh, (800, 560)], dtype=float)
    girth = PchipInterpolator(knots[:, 0], knots[:, 1])(z)
    elongation = np.interp(z, [0, 40, 70, 100, 800], [2.2, 1.8, 1.5, 1.1, 1.05])
    return z, girth, elongation


def test_a_swollen_lower_leg_without_a_calf_bulge_is_refused_for_it():
    """A swollen (lymphoedematous) leg: the ankle 362 mm round, the calf 370 (C/B 1.02),
    the knee waist 350.  No calf bulges over this ankle even by MIN_CALF_RATIO_ON_FOOT,
    and the knee waist, 330 mm above the foot with no narrower leg below it, is no ankle
    for the thigh above it to be a calf over (MAX_ANKLE_ABOVE_FOOT_MM): read so, the thigh
    was measured as a calf.  The refusal says the leg has no calf bulge and that a tape
    measures it - not "a foot" or "the scan ends inside the calf", which ask for a scan
    that cannot help."""
    z, girth, elongation = _swollen_leg_profile(362.0, 370.0, 350.0)
    with pytest.raises(FitFailure) as caught:
        find_feature_heights(z, girth, elongation=elongation)
    assert isinstance(caught.value, CalfWithoutBulge) and caught.value.reason is FailureReason.NO_CALF
    assert "no calf bulge" in caught.value.detail and "by tape" in caught.value.detail, caught.value.detail


def test_a_swollen_calf_bulging_less_than_any_healthy_one_is_measured_on_its_foot():
    """The ankle swollen to 345 mm, the calf 380 (C/B 1.10, under ANSUR II's least, 1.40,
    and under MIN_CALF_RATIO), the knee waist 350.  Its ankle stands on its foot, so the
    knee's bulge cannot pass for the calf, and the calf need only bulge by
    MIN_CALF_RATIO_ON_FOOT: B, C and D are found where they are.  Cut to the calf, the same
    profile is refused, as before, unless an earlier profile found its ankle on the foot."""
    z, girth, elongation = _swollen_leg_profile(345.0, 380.0, 350.0)
    found = find_feature_heights(z, girth, elongation=elongation)
    assert abs(found.b_mm - 110.0) < 15.0 and abs(found.c_mm - 300.0) < 20.0 and abs(found.d_mm - 440.0) < 15.0
    calf = z >= 100.0
    with pytest.raises(FitFailure):
        find_feature_heights(z[calf], girth[calf], elongation=elongation[calf])
    again = find_feature_heights(z[calf], girth[calf], elongation=elongation[calf], on_foot=True)
    assert abs(again.c_mm - 300.0) < 20.0 and abs(again.d_mm - 440.0) < 15.0


def test_a_swollen_ankle_wider_than_the_knee_waist_is_still_the_ankle_on_its_foot():
    """The ankle swollen to 330 mm, the calf 410 (C/B 1.24: it still bulges), the knee
    waist 320, narrower than the ankle.  The knee waist's being thicker than the ankle
    (MIN_KNEE_RATIO) is what tells the two ends apart when nothing else does; here the
    foot under the ankle does, and the landmarks are found where they are.  Without the
    foot the same profile is refused (no knee thicker than the ankle), as before."""
    z, girth, elongation = _swollen_leg_profile(330.0, 410.0, 320.0)
    found = find_feature_heights(z, girth, elongation=elongation)
    assert abs(found.b_mm - 110.0) < 15.0 and abs(found.c_mm - 300.0) < 15.0 and abs(found.d_mm - 440.0) < 15.0
    assert found.on_foot
    calf = z >= 100.0
    with pytest.raises(FitFailure) as caught:
        find_feature_heights(z[calf], girth[calf], elongation=elongation[calf])
    assert caught.value.reason is FailureReason.NO_KNEE
    # a profile of the same leg cut to its calf, once its ankle was found on the foot
    again = find_feature_heights(z[calf], girth[calf], elongation=elongation[calf], on_foot=True)
    assert abs(again.d_mm - 440.0) < 15.0


def test_a_knee_waist_over_the_thigh_is_no_ankle_on_its_foot():
    """A healthy leg read upside down, the thigh below the knee waist: the thigh is as
    wide as a foot (over FOOT_RATIO times the knee waist within MAX_ANKLE_ABOVE_FOOT_MM)
    but round, so the knee waist does not stand on a foot, and the knee-end rule refuses
    the reading (its "D", the ankle, is narrower than its "B"; the refusal reported is
    the foot at the top, read as a calf).  Read so, a body's leg
    was measured cB 333 mm at the knee waist and cD 242 at the ankle
    (benchmarks/chart_accuracy.py 8 7, leg 7's body vertices).  Read foot down, the same
    leg stands on its foot."""
    # the thigh 1.35 times the knee waist 120 mm above it (the body's: 1.3 times 105 mm above)
    z, girth, elongation = _swollen_leg_profile(230.0, 380.0, 330.0, lower_thigh_mm=445.0)
    with pytest.raises(FitFailure):
        find_feature_heights(-z[::-1], girth[::-1], elongation=elongation[::-1])
    found = find_feature_heights(z, girth, elongation=elongation)
    assert found.on_foot and abs(found.b_mm - 110.0) < 15.0 and abs(found.d_mm - 440.0) < 15.0


@pytest.mark.parametrize("joins_mm", [350.0, 420.0])
def test_a_limb_joining_the_sections_above_the_calf_is_no_knee_waist(joins_mm):
    """The leg's profile (ankle at 40 mm, calf at 280, knee waist at 390) with another
    limb joining its sections at ``joins_mm`` (the other leg touching this one: the girth
    doubles within 2 mm, and widens on up the two thighs).  Joined at 350 mm, the leg still narrows into the
    join: the smoothed profile's rise into it is no knee waist, and the refusal says what
    lies in the sections (before, D was read 10 mm below the join, 17 mm rounder than the
    knee waist).  Joined at 420 mm, above the knee waist and the rise over it, D is found
    at its waist as without the limb."""
    z, girth = _calf_with_a_flank_bump(600.0)
    at_join = float(np.interp(joins_mm, z, girth))
    joined = np.where(z >= joins_mm, 2.0 * at_join + 0.5 * (z - joins_mm), girth)
    alone = find_feature_heights(z, girth)
    if joins_mm < 390.0:
        with pytest.raises(FitFailure) as caught:
            find_feature_heights(z, joined)
        assert caught.value.reason is FailureReason.NO_KNEE
        said = caught.value.detail
        assert isinstance(caught.value, JoinedAboveCalf) and "another body part joins them" in said
        # the join named from the calf below it, or from the ankle below the bulge above it
        assert (f"{joins_mm - alone.c_mm:.0f} mm above the calf maximum" in said
                or f"{joins_mm - alone.b_mm:.0f} mm above the ankle" in said), said
    else:
        found = find_feature_heights(z, joined)
        assert abs(found.d_mm - alone.d_mm) < 2.0 and abs(found.girth_d_mm - alone.girth_d_mm) < 1.0


def test_a_join_is_a_jump_no_leg_makes_and_a_sparse_profiles_noise_is_none():
    """merged_above on a level 300 mm girth every 3 mm (a sparse cloud's slabs): a leg's
    own sections doubling (the other leg's knee) is a join at the step, its rise 100%; a
    section reading 5% low before a 20% rise, a 12% step (a calf's flank, or noise), and a
    27% step across three unread sections (no level read 5-10 mm below it) are none."""
    z = np.arange(0.0, 150.0, 3.0)
    level = np.full(len(z), 300.0)
    step = np.flatnonzero(z >= 90.0)[0]
    doubled = np.where(z >= 90.0, 600.0, level)
    assert merged_above(z, doubled, 0, 150.0) == (step, pytest.approx(1.0))
    low_then_up = np.where(z >= 90.0, 360.0, level)  # 20% up: 26% over the low section alone
    low_then_up[step - 2] = 285.0
    assert merged_above(z, low_then_up, 0, 150.0) is None
    assert merged_above(z, np.where(z >= 90.0, 336.0, level), 0, 150.0) is None
    across_gap = np.where(z >= 90.0, 380.0, level)
    across_gap[step - 3 : step] = np.nan
    assert merged_above(z, across_gap, 0, 150.0) is None
    assert merged_above(z, doubled, 0, 60.0) is None  # beyond the reach asked


def test_a_shoulder_whose_knee_waist_is_a_larger_bulges_flank_is_refused_not_a_crash():
    """Found again near the C of a first reading (``near_c_mm``), a profile whose only
    candidate near it is a shoulder, whose knee waist lies on the rising flank of a larger
    bulge above - which the hint keeps out of the candidates: that shoulder is no calf,
    and nothing else was tried.  The search raised ValueError (max of no refusals: an
    internal error in the service; 13 of 4,000 random piecewise-linear slopes, read after
    a watertight export's cap was cut away); it is refused as no calf, saying why."""
    z = np.arange(0.0, 600.0, 2.0)
    slope = np.interp(z, [0.0, 53.0, 135.0, 204.0, 356.0, 419.0, 480.0, 490.0, 599.0, 600.0],
                      [0.4, -1.1, 0.7, 0.2, 0.8, -0.4, -0.4, -0.9, -0.8, -0.5])  # mm of girth per mm
    girth = 250.0 + np.concatenate([[0.0], np.cumsum((slope[1:] + slope[:-1]) / 2 * np.diff(z))])
    with pytest.raises(FitFailure) as caught:
        find_feature_heights(z, girth, near_c_mm=231.0)
    assert caught.value.reason is FailureReason.NO_CALF
    assert "rising flank of a larger bulge" in caught.value.detail
