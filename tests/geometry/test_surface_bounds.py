"""The cost bounds and the tube checks of imported surfaces (app.geometry.spline.bounds),
and the bounded memory of the evaluations behind them."""

from __future__ import annotations

import numpy as np
import pytest

from app.geometry.errors import FitFailure
from app.geometry.measures.surface_girths import ROWS_PER_CHUNK, girths
from app.geometry.measures.volume import volume_between
from app.geometry.spline.bounds import MAX_PATCH_COST, patch_cost
from app.records.codec import parse_importable, parse_record, record_from_fit
from benchmarks.hostile_inputs import tube_record
from tests.conftest import fitted


def refusal(body: dict) -> FitFailure:
    with pytest.raises(FitFailure) as caught:
        parse_importable(body)
    return caught.value


@pytest.mark.parametrize("net", [(48, 48, 5), (64, 64, 3), (128, 128, 3)])
def test_a_net_past_the_patch_cost_is_refused_naming_it(net):
    failure = refusal(tube_record(*net))
    assert failure.reason.value == "surface_too_costly"
    assert f"{MAX_PATCH_COST:,}" in failure.detail and "patch cost" in failure.detail


def test_the_largest_net_the_service_makes_is_accepted():
    body = tube_record(72, 40, 3, height_mm=1150.0)  # an lsq 40 x 72 grid, as tall as a leg
    assert patch_cost(parse_importable(body).surface) <= MAX_PATCH_COST


@pytest.mark.parametrize("shape, words", [(dict(height_mm=1900.0), "tall"), (dict(radius_mm=600.0), "from the calf axis")])
def test_records_taller_or_wider_than_a_leg_are_refused(shape, words):
    failure = refusal(tube_record(16, 8, 3, **shape))
    assert failure.reason.value == "surface_too_costly" and words in failure.detail


@pytest.mark.parametrize("radius, circumference", [(0.0, 300.0), (0.001, 300.0)])
def test_a_zero_or_thread_thin_tube_is_refused(radius, circumference):
    failure = refusal(tube_record(16, 8, 3, radius_mm=radius, circumference_mm=circumference))
    assert failure.reason.value == "invalid_record" and "axis" in failure.detail


def test_a_tube_that_turns_back_or_overlaps_itself_is_refused():
    folded = tube_record(16, 8, 3)
    ctrl = np.array(folded["surface"]["control_points"])
    ctrl[:, 5:, 2] = [150.0, 120.0, 100.0]  # the upper rows run back down the leg
    folded["surface"]["control_points"] = ctrl.tolist()
    assert "rise" in refusal(folded).detail
    looped = tube_record(16, 8, 3)
    ctrl = np.array(looped["surface"]["control_points"])
    ctrl[[5, 9], :, :2] = ctrl[[9, 5], :, :2]  # two columns swapped: the ring crosses itself
    looped["surface"]["control_points"] = ctrl.tolist()
    assert "wind once" in refusal(looped).detail


def test_every_fitted_real_record_is_importable():
    scan, result = fitted("bodyparts3d_right_leg.stl", None)
    record = parse_importable(record_from_fit(result, "stl", "mm").to_dict())
    assert record.landmarks.keys() == {"B", "B1", "C", "D"}


def test_chunked_girths_cross_chunk_borders_exactly(monkeypatch):
    """A plane on a chunk border gets its segments from both chunks: the girths cut
    chunk by chunk equal those of the whole tessellation cut at once."""
    surface = parse_record(tube_record(16, 8, 3, height_mm=1000.0)).surface
    border = np.linspace(0.0, 1000.0, 2001)[ROWS_PER_CHUNK]  # z of the first chunk border row
    heights = np.array([border, border + 0.01, 333.3, 950.0])
    chunked = girths(surface, heights)
    monkeypatch.setattr("app.geometry.measures.surface_girths.ROWS_PER_CHUNK", 10_000)
    whole = girths(surface, heights)
    for a, b in zip(chunked, whole):
        assert a.tape_mm == pytest.approx(b.tape_mm, abs=1e-9)
        assert a.circumference_mm == pytest.approx(b.circumference_mm, abs=1e-9)


def test_the_volume_is_summed_over_chunks_like_in_one_piece(monkeypatch):
    surface = parse_record(tube_record(72, 40, 3, height_mm=1000.0)).surface
    chunked = volume_between(surface, 100.0, 900.0)
    monkeypatch.setattr("app.geometry.measures.volume.QUADRATURE_CHUNK_POINTS", 10 ** 9)
    monkeypatch.setattr("app.geometry.spline.nurbs.EVALUATION_CHUNK_BYTES", 10 ** 12)
    assert chunked == pytest.approx(volume_between(surface, 100.0, 900.0), rel=1e-12)
