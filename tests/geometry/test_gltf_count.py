"""Counting a glTF scene's instances before it is expanded (app.geometry.scan.gltf_count)."""

from __future__ import annotations

import json
import struct

import pytest
import trimesh

from app.geometry.errors import FitFailure
from app.geometry.scan.gltf_count import gltf_json, gltf_scene_size
from app.geometry.scan.reader import load_scan
from benchmarks.hostile_inputs import LEG_STL, instanced_glb


@pytest.fixture(scope="module")
def leg() -> trimesh.Trimesh:
    return trimesh.load(LEG_STL)


def test_every_instance_is_counted_as_trimesh_would_expand_it(leg):
    data = instanced_glb(3, leg)
    size = gltf_scene_size(gltf_json(data, "glb"))
    expanded = trimesh.load(trimesh.util.wrap_as_stream(data), file_type="glb").to_geometry()
    assert size.triangles == len(expanded.faces) == 3 * len(leg.faces)
    assert size.points == len(expanded.vertices)


def test_a_small_file_that_expands_past_the_limit_is_refused_before_reading(leg):
    data = instanced_glb(400, leg)  # ~0.5 MB on disk, 10.8 million triangles expanded
    assert len(data) < 2_000_000
    with pytest.raises(FitFailure) as caught:
        load_scan(data, file_type="glb", max_points=4_000_000, max_faces=4_000_000)
    assert caught.value.reason.value == "scan_too_large"
    assert f"{400 * len(leg.faces)} triangles" in caught.value.detail


def test_a_scene_of_copies_under_the_triangle_limit_is_refused_too(leg):
    data = instanced_glb(140, leg)  # 3.8 million triangles: under the limit, still 140 copies
    with pytest.raises(FitFailure) as caught:
        load_scan(data, file_type="glb", max_points=4_000_000, max_faces=4_000_000)
    assert caught.value.reason.value == "scan_too_large" and "140 times" in caught.value.detail
    assert len(load_scan(instanced_glb(2, leg), file_type="glb", max_points=4_000_000, max_faces=4_000_000).points_mm)


def _document(nodes: list, scene_nodes: list) -> dict:
    return {"asset": {"version": "2.0"}, "accessors": [{"count": 300}, {"count": 900}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
            "nodes": nodes, "scenes": [{"nodes": scene_nodes}], "scene": 0}


def test_a_shared_subtree_counts_once_per_parent_and_costs_no_more_to_count():
    # 30 levels, each node naming the next twice: 2^30 instances of one mesh
    nodes = [{"children": [i + 1, i + 1]} for i in range(30)] + [{"mesh": 0}]
    size = gltf_scene_size(_document(nodes, [0]))
    assert size.triangles == 2 ** 30 * 300 and size.points == 2 ** 30 * 300 and size.max_instances == 2 ** 30


def test_gpu_instancing_multiplies_the_mesh():
    document = _document([{"mesh": 0, "extensions": {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": 1}}}}], [0])
    assert gltf_scene_size(document).triangles == 900 * 300


@pytest.mark.parametrize("nodes, words", [([{"children": [1]}, {"children": [0]}], "cycle"),
                                          ([{"mesh": 5}], "mesh"), ([{"children": [9]}], "node")])
def test_broken_node_graphs_are_unreadable(nodes, words):
    with pytest.raises(FitFailure) as caught:
        gltf_scene_size(_document(nodes, [0]))
    assert caught.value.reason.value == "unreadable_file" and words in caught.value.detail


def test_a_glb_whose_json_chunk_is_cut_is_unreadable(leg):
    data = instanced_glb(1, leg)
    length, _ = struct.unpack_from("<II", data, 12)
    with pytest.raises(FitFailure):
        gltf_json(data[: 20 + length // 2], "glb")
    assert gltf_json(json.dumps(_document([{"mesh": 0}], [0])).encode(), "gltf")["scene"] == 0
