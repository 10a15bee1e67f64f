"""Reading every supported format into millimetres, and refusing what is not a scan."""

import json
import struct

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.scan.reader import detect_units, load_scan, merge_duplicate_vertices
from tests.conftest import REAL


@pytest.fixture(scope="module")
def leg_mesh():
    return trimesh.load(REAL / "bodyparts3d_right_leg.stl")


@pytest.mark.parametrize("fmt", ["stl", "stl_ascii", "ply", "obj", "off", "glb", "gltf"])
def test_every_mesh_format_reads_to_the_same_vertices(leg_mesh, fmt):
    if fmt == "gltf":
        data = trimesh.Scene(leg_mesh).export(file_type="gltf", embed_buffers=True)["model.gltf"]
    else:
        data = leg_mesh.export(file_type=fmt)
    data = data.encode() if isinstance(data, str) else data
    scan = load_scan(data, file_type=fmt)
    assert scan.is_mesh and scan.units == "mm" and scan.units_detected
    assert len(scan.points_mm) == len(leg_mesh.vertices)
    assert np.allclose(np.sort(scan.points_mm, axis=0), np.sort(leg_mesh.vertices, axis=0), atol=1e-3)


def test_ply_points_only_xyz_and_csv_are_point_clouds(leg_mesh):
    cloud = trimesh.PointCloud(leg_mesh.vertices)
    ply = load_scan(cloud.export(file_type="ply"), file_type="ply")
    assert not ply.is_mesh and len(ply.points_mm) == len(leg_mesh.vertices)
    text = "\n".join(" ".join(f"{c:.4f}" for c in p) for p in leg_mesh.vertices)
    assert np.allclose(load_scan(text.encode(), file_type="xyz").points_mm, leg_mesh.vertices, atol=1e-3)
    csv = "x,y,z\n" + "\n".join(",".join(f"{c:.4f}" for c in p) for p in leg_mesh.vertices)
    scan = load_scan(csv.encode(), file_type="csv")
    assert not scan.is_mesh and np.allclose(scan.points_mm, leg_mesh.vertices, atol=1e-3)


@pytest.mark.parametrize("scale,unit", [(1.0, "mm"), (0.1, "cm"), (0.001, "m")])
def test_units_are_detected_from_the_extent(leg_mesh, scale, unit):
    scaled = trimesh.Trimesh(leg_mesh.vertices * scale, leg_mesh.faces)
    scan = load_scan(scaled.export(file_type="stl"), file_type="stl")
    assert scan.units == unit
    assert np.isclose(np.ptp(scan.points_mm[:, 2]), np.ptp(leg_mesh.vertices[:, 2]), rtol=1e-5)


def test_units_can_be_overridden(leg_mesh):
    scan = load_scan(leg_mesh.export(file_type="stl"), file_type="stl", units="mm")
    assert not scan.units_detected and scan.units == "mm"
    assert detect_units(1.75) == "m" and detect_units(850.0) == "mm" and detect_units(95.0) == "cm"


def test_stl_corner_merge_is_exact():
    rng = np.random.default_rng(0)
    vertices = rng.normal(size=(300, 3))
    faces = rng.integers(0, 300, size=(500, 3))
    soup = vertices[faces].reshape(-1, 3)
    merged, new_faces = merge_duplicate_vertices(soup, np.arange(len(soup)).reshape(-1, 3))
    assert len(merged) == len(np.unique(faces))
    assert np.array_equal(merged[new_faces], vertices[faces])


@pytest.mark.parametrize(
    "payload,fmt,reason",
    [
        (b"", "stl", FailureReason.EMPTY_SCAN),
        (b"   \n", "xyz", FailureReason.EMPTY_SCAN),
        (b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0", "stl", FailureReason.TRUNCATED_FILE),
        (b"\x00" * 80 + b"\x10\x00\x00\x00" + b"\x00" * 120, "stl", FailureReason.TRUNCATED_FILE),
        (b"\x00" * 84 + b"\x01\x02", "stl", FailureReason.UNREADABLE_FILE),
        (b"not a mesh at all", "ply", FailureReason.UNREADABLE_FILE),
        (b"1 2 3\n4 5 6\n", "xyz", FailureReason.TOO_FEW_POINTS),
        (b"1 2\n3 4\n", "csv", FailureReason.UNREADABLE_FILE),
        (b"hello", "docx", FailureReason.UNSUPPORTED_FORMAT),
    ],
)
def test_bad_files_fail_with_a_specific_reason(payload, fmt, reason):
    with pytest.raises(FitFailure) as info:
        load_scan(payload, file_type=fmt)
    assert info.value.reason == reason and info.value.detail


def test_a_real_stl_cut_short_is_truncated(leg_mesh):
    data = leg_mesh.export(file_type="stl")
    with pytest.raises(FitFailure) as info:
        load_scan(data[: len(data) // 2], file_type="stl")
    assert info.value.reason == FailureReason.TRUNCATED_FILE and "truncated" in info.value.detail


@pytest.mark.parametrize("encoding", ["ascii", "binary_little_endian"])
@pytest.mark.parametrize("kind", ["mesh", "points"])
def test_a_real_ply_cut_short_is_truncated_and_whole_it_reads(leg_mesh, encoding, kind):
    """A PLY holding fewer vertices or faces than its header announces is truncated
    (not read as the elements present); the whole file reads in full."""
    geometry = leg_mesh if kind == "mesh" else trimesh.PointCloud(leg_mesh.vertices)
    data = geometry.export(file_type="ply", encoding=encoding)
    whole = load_scan(data, file_type="ply")
    assert len(whole.points_mm) == len(leg_mesh.vertices)
    for cut in (len(data) - 40, len(data) // 2):
        with pytest.raises(FitFailure) as info:
            load_scan(data[:cut], file_type="ply")
        assert info.value.reason == FailureReason.TRUNCATED_FILE
        assert f"{len(leg_mesh.vertices)} vertices" in info.value.detail


def test_nan_coordinates_and_absurd_sizes_are_refused(leg_mesh):
    bad = leg_mesh.vertices.copy()
    bad[10, 1] = np.nan
    text = "\n".join(" ".join(str(c) for c in p) for p in bad)
    with pytest.raises(FitFailure) as info:
        load_scan(text.encode(), file_type="xyz")
    assert info.value.reason == FailureReason.NON_FINITE_COORDINATES
    tiny = trimesh.Trimesh(leg_mesh.vertices * 1e-6, leg_mesh.faces)
    with pytest.raises(FitFailure) as info:
        load_scan(tiny.export(file_type="stl"), file_type="stl")
    assert info.value.reason == FailureReason.IMPLAUSIBLE_SIZE
    with pytest.raises(FitFailure) as info:
        load_scan(leg_mesh.export(file_type="stl"), file_type="stl", units="m")
    assert info.value.reason == FailureReason.IMPLAUSIBLE_SIZE


def test_vertices_with_two_coordinates_are_unreadable_not_a_crash():
    from benchmarks.hostile_inputs import obj_with_2d_vertices

    with pytest.raises(FitFailure) as caught:
        load_scan(obj_with_2d_vertices(), file_type="obj")
    assert caught.value.reason == FailureReason.UNREADABLE_FILE and "2 coordinates" in caught.value.detail


def test_coordinates_whose_squares_overflow_are_refused():
    from benchmarks.hostile_inputs import huge_coordinate_xyz

    with pytest.raises(FitFailure) as caught:
        load_scan(huge_coordinate_xyz(), file_type="xyz")
    assert caught.value.reason == FailureReason.IMPLAUSIBLE_SIZE and "1e+308" in caught.value.detail


def test_a_draco_compressed_glb_reads_to_the_scan_within_its_quantisation(leg_mesh):
    """Phone and photogrammetry apps export GLB with Draco (KHR_draco_mesh_compression):
    read through trimesh and DracoPy, each vertex within Draco's 14-bit quantisation of
    the leg's extent (~0.06 mm) of the mesh's."""
    data = trimesh.Scene(leg_mesh).export(file_type="glb", extension_draco=True)
    assert b"KHR_draco_mesh_compression" in data
    scan = load_scan(data, file_type="glb", max_points=10**6, max_faces=10**6)
    assert scan.is_mesh and len(scan.faces) == len(leg_mesh.faces)
    offset, _ = cKDTree(leg_mesh.vertices).query(scan.points_mm)
    assert offset.max() < np.ptp(leg_mesh.vertices, axis=0).max() / 2**14


def test_a_glb_compressed_in_a_way_the_reader_cannot_read_is_refused_by_name(leg_mesh):
    """A meshopt-compressed GLB's buffers hold zeros where a reader ignoring the
    extension looks: refused with the extension's name, not read as zeros."""
    data = trimesh.Scene(leg_mesh).export(file_type="glb")
    length = struct.unpack_from("<I", data, 12)[0]
    document = json.loads(data[20:20 + length])
    document["extensionsUsed"] = document["extensionsRequired"] = ["EXT_meshopt_compression"]
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    rest = data[20 + length:]
    glb = b"glTF" + struct.pack("<II", 2, 20 + len(text) + len(rest)) + struct.pack("<II", len(text), 0x4E4F534A) + text + rest
    with pytest.raises(FitFailure) as info:
        load_scan(glb, file_type="glb")
    assert info.value.reason is FailureReason.UNSUPPORTED_FORMAT and "EXT_meshopt_compression" in info.value.detail
