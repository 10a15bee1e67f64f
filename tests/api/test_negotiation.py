"""Content negotiation (RFC 9110 section 12.5.1): one rule for every resource."""

import pytest

from app.api.negotiation import accepted_ranges, negotiate
from app.errors import NotAcceptable

MAP = {"glb": "model/gltf-binary", "csv": "text/csv"}


def test_ranges_are_ordered_by_weight_then_by_position_and_q0_is_dropped():
    assert accepted_ranges("text/csv;q=0.5, model/gltf-binary, */*;q=0") == [("model/gltf-binary", 1.0), ("text/csv", 0.5)]
    assert accepted_ranges("text/csv, model/gltf-binary") == [("text/csv", 1.0), ("model/gltf-binary", 1.0)]
    assert accepted_ranges("text/csv; Q=oops") == []  # an unreadable weight is "not this"


@pytest.mark.parametrize(("accept", "expected"), [
    (None, "glb"), ("*/*", "glb"), ("text/*", "csv"), ("model/*", "glb"),
    ("text/csv;q=0.9, model/gltf-binary;q=0.1", "csv"), ("text/html, text/csv;q=0.2", "csv"),
    ("model/gltf-binary;q=0, text/csv;q=0.1", "csv"),
])
def test_the_best_acceptable_representation_is_chosen(accept, expected):
    assert negotiate(accept, None, MAP, "the map") == expected


def test_the_query_parameter_overrides_accept_and_unknown_forms_are_refused_by_name():
    assert negotiate("text/csv", "GLB", MAP, "the map") == "glb"
    with pytest.raises(NotAcceptable, match="format must be one of glb, csv"):
        negotiate(None, "pdf", MAP, "the map")
    with pytest.raises(NotAcceptable, match="the map is available as model/gltf-binary, text/csv"):
        negotiate("application/pdf, text/*;q=0", None, MAP, "the map")
