"""A corpus of malformed and hostile scans, made at test time from the vendored real leg.

Each case says what a correct service answers, from what the file is (not from what the
service happens to do): the problem codes that name its defect, or ``FITS`` where the
file, odd as it is, holds a readable leg (a binary STL whose header starts with
"solid", a cloud saved as OBJ vertices, a patient's name in Latin-1).
"""

from __future__ import annotations

import base64
import io
import json
import struct
from dataclasses import dataclass, field

import numpy as np
import trimesh

from tests.conftest import REAL

FITS = "fits"
READ_ERRORS = ("unreadable_file", "truncated_file")


@dataclass(frozen=True)
class MalformedScan:
    name: str
    data: bytes
    media_type: str
    filename: str | bytes = "scan.bin"
    params: dict = field(default_factory=dict)
    #: the problem codes (upload 4xx or failed job) that are right, or (FITS,)
    expect: tuple = ()


def _leg() -> trimesh.Trimesh:
    return trimesh.load(REAL / "bodyparts3d_right_leg.stl")


def _binary_stl(triangles: np.ndarray, header: bytes = b"calf-nurbs test", count: int | None = None) -> bytes:
    """A binary STL of (f, 3, 3) float triangles; ``count`` overrides the stated count."""
    f = len(triangles)
    records = np.zeros(f, dtype=[("normal", "<f4", 3), ("vertices", "<f4", (3, 3)), ("attr", "<u2")])
    records["vertices"] = triangles
    return header.ljust(80, b" ")[:80] + struct.pack("<I", f if count is None else count) + records.tobytes()


def _rows(array: np.ndarray, fmt: str) -> bytes:
    """Rows of ``array`` as text lines of ``fmt`` (np.savetxt: one call, no loop)."""
    buffer = io.BytesIO()
    if len(array):
        np.savetxt(buffer, array, fmt=fmt)
    return buffer.getvalue()


def _ascii_ply(vertices: np.ndarray, faces: np.ndarray, stated_vertices: int | None = None) -> bytes:
    head = (f"ply\nformat ascii 1.0\nelement vertex {len(vertices) if stated_vertices is None else stated_vertices}\n"
            "property float x\nproperty float y\nproperty float z\n"
            f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    # (a face list, or an empty line where there is none)
    return head.encode() + _rows(vertices, "%.4f") + (_rows(faces, "3 %d %d %d") if len(faces) else b"\n")


def _obj(vertices: np.ndarray, faces: np.ndarray | None, index_base: int = 1) -> bytes:
    text = _rows(vertices, "v %.4f %.4f %.4f")
    return text if faces is None else text + _rows(np.asarray(faces) + index_base, "f %d %d %d")


def _xyz(points: np.ndarray) -> bytes:
    return _rows(points, "%.3f")


def _gltf(uri: str, count: int = 3) -> bytes:
    """A glTF JSON with one triangle mesh whose buffer lives at ``uri``."""
    document = {
        "asset": {"version": "2.0"},
        "buffers": [{"uri": uri, "byteLength": 36}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": count, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 1]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}], "scene": 0,
    }
    return json.dumps(document).encode()


def malformed_scans() -> list[MalformedScan]:
    leg = _leg()
    v, f = np.asarray(leg.vertices, dtype=np.float64), np.asarray(leg.faces)
    triangles = v[f]
    good_stl = _binary_stl(triangles)
    rng = np.random.default_rng(11)
    cases: list[MalformedScan] = []

    def add(name, data, media, expect, filename="scan.bin", **params):
        cases.append(MalformedScan(name, data, media, filename, params, tuple(expect)))

    # --- STL: truncated, lying headers, numbers that are not numbers
    add("stl truncated to a third", good_stl[: len(good_stl) // 3], "model/stl", ("truncated_file",))
    add("stl count says a million more", _binary_stl(triangles, count=len(triangles) + 1_000_000), "model/stl", ("truncated_file",))
    add("stl count says 2^32-1", _binary_stl(triangles[:10], count=0xFFFFFFFF), "model/stl", ("truncated_file", "scan_too_large"))
    add("stl count says fewer than it holds", _binary_stl(triangles, count=20), "model/stl", ("truncated_file", "unreadable_file", "too_few_points"))
    add("stl header only", _binary_stl(triangles[:0]), "model/stl", ("empty_scan", "truncated_file"))
    add("stl binary whose header says solid", _binary_stl(triangles, header=b"solid leg exported by a scanner"), "model/stl", (FITS,))
    ascii_stl = trimesh.Trimesh(v, f).export(file_type="stl_ascii").encode()
    add("ascii stl cut mid-facet", ascii_stl[: len(ascii_stl) // 2], "model/stl", READ_ERRORS + ("not_a_leg", "no_knee", "no_ankle", "no_calf"))
    add("ascii stl with words for numbers", ascii_stl.replace(b"vertex ", b"vertex one two three ", 5), "model/stl", READ_ERRORS)
    with_nan = triangles.copy()
    with_nan[5, 1, 2] = np.nan
    add("stl with a NaN vertex", _binary_stl(with_nan), "model/stl", ("non_finite_coordinates",))
    with_inf = triangles.copy()
    with_inf[7, 0, 0] = np.inf
    add("stl with an infinite vertex", _binary_stl(with_inf), "model/stl", ("non_finite_coordinates",))
    add("stl of zero-area faces only", _binary_stl(np.repeat(triangles[:, :1], 3, axis=1)), "model/stl",
        ("empty_scan", "too_few_points", "not_a_leg", "implausible_size"))
    degenerate = np.concatenate([triangles, np.repeat(triangles[:2000, :1], 3, axis=1)])
    add("leg with 2000 zero-area faces added", _binary_stl(degenerate), "model/stl", (FITS,))
    # --- PLY
    add("ply face index out of range", _ascii_ply(v[:100], np.array([[0, 1, 99_999_999]])), "application/x-ply", READ_ERRORS)
    add("ply negative face index", _ascii_ply(v[:100], np.array([[0, 1, -5]])), "application/x-ply", READ_ERRORS)
    add("ply states 1000 vertices, holds 10", _ascii_ply(v[:10], np.zeros((0, 3), int), stated_vertices=1000), "application/x-ply", READ_ERRORS)
    add("ply states 2^31 vertices", _ascii_ply(v[:10], np.zeros((0, 3), int), stated_vertices=2**31), "application/x-ply",
        READ_ERRORS + ("scan_too_large",))
    binary_ply = leg.export(file_type="ply")
    add("binary ply truncated", binary_ply[: len(binary_ply) // 2], "application/x-ply", READ_ERRORS)
    nan_cloud = v.copy()
    nan_cloud[3] = np.nan
    add("ply with a NaN vertex", trimesh.Trimesh(nan_cloud, f, process=False).export(file_type="ply"), "application/x-ply", ("non_finite_coordinates",))
    add("ply that is not ply", b"ply\nformat nonsense 9\n" * 20, "application/x-ply", READ_ERRORS)
    # --- OBJ and OFF
    add("obj face index out of range", _obj(v[:50], np.array([[0, 1, 99_999_998]])), "model/obj", READ_ERRORS + ("too_few_points", "empty_scan"))
    add("obj face index 0 (obj counts from 1)", _obj(v[:50], np.array([[0, 1, 2]]), index_base=0), "model/obj", READ_ERRORS + ("too_few_points", "empty_scan"))
    add("obj with words for coordinates", b"v one two three\nv 1 2 3\nf 1 2 3\n", "model/obj", READ_ERRORS + ("too_few_points", "empty_scan"))
    add("obj of vertices only (a cloud)", _obj(trimesh.sample.sample_surface(leg, 40_000, seed=2)[0], None), "model/obj", (FITS,))
    add("off with wrong counts", b"OFF\n100 50 0\n0 0 0\n1 1 1\n", "model/x-off", READ_ERRORS + ("too_few_points", "empty_scan"))
    add("off face index out of range", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", "model/x-off", READ_ERRORS + ("too_few_points",))
    # --- glTF: buffers must not be read from anywhere but the file itself
    add("gltf buffer at file:///etc/passwd", _gltf("file:///etc/passwd"), "model/gltf+json", READ_ERRORS)
    add("gltf buffer at ../../ outside", _gltf("../../../../etc/passwd"), "model/gltf+json", READ_ERRORS)
    add("gltf buffer on the network", _gltf("http://127.0.0.1:9/leg.bin"), "model/gltf+json", READ_ERRORS)
    add("gltf accessor past its buffer", _gltf("data:application/octet-stream;base64," + base64.b64encode(bytes(36)).decode(), count=1000),
        "model/gltf+json", READ_ERRORS + ("too_few_points",))
    add("gltf that is not json", b"{\"asset\": {\"version\": \"2.0\"", "model/gltf+json", READ_ERRORS)
    glb = leg.export(file_type="glb")
    add("glb truncated", glb[: len(glb) // 2], "model/gltf-binary", READ_ERRORS)
    add("glb with a wrong magic", b"glTX" + glb[4:], "model/gltf-binary", READ_ERRORS)
    add("glb whose json chunk is not json", glb[:20] + b"!" * 16 + glb[36:], "model/gltf-binary", READ_ERRORS)
    # --- point clouds
    add("xyz with text lines", b"# scanner export\n1 2 3\nhello world\n4 5 6\n", "text/x-xyz", READ_ERRORS + ("too_few_points",))
    add("xyz of three points", _xyz(v[:3]), "text/x-xyz", ("too_few_points",))
    add("xyz with NaN", _xyz(v[:500]).replace(b"\n", b"\nnan nan nan\n", 1), "text/x-xyz", ("non_finite_coordinates",) + READ_ERRORS)
    add("csv of two columns", b"x,y\n1,2\n3,4\n5,6\n", "text/csv", READ_ERRORS + ("too_few_points",))
    big = rng.normal(0.0, 200.0, size=(2_000_000, 3)).astype("<f4")
    big_ply = (b"ply\nformat binary_little_endian 1.0\nelement vertex 2000000\nproperty float x\nproperty float y\n"
               b"property float z\nend_header\n" + big.tobytes())
    add("2M-point cloud over the point limit", big_ply, "application/x-ply", ("scan_too_large",))
    # --- not legs, two legs, units
    add("a sphere", trimesh.creation.icosphere(4, radius=150.0).export(file_type="stl"), "model/stl", ("not_a_leg", "implausible_size"))
    add("a cylinder without ankle or knee", trimesh.creation.cylinder(radius=55.0, height=450.0, sections=72).subdivide_to_size(10).export(file_type="stl"),
        "model/stl", ("not_a_leg", "no_calf", "no_ankle", "no_knee"))
    add("a flat plate", trimesh.creation.box(extents=(600.0, 600.0, 2.0)).subdivide_to_size(20).export(file_type="stl"), "model/stl",
        ("not_a_leg", "implausible_size", "empty_scan"))
    add("a torus", trimesh.creation.torus(200.0, 60.0).export(file_type="stl"), "model/stl", ("not_a_leg", "no_calf", "no_ankle", "no_knee"))
    # the right leg and its mirror image about the body's midline (x = 0 in BodyParts3D),
    # moved 20 mm in so that the thighs run into each other
    mirrored = v * np.array([-1.0, 1.0, 1.0]) - np.array([20.0, 0.0, 0.0])
    pair = trimesh.util.concatenate([trimesh.Trimesh(v, f), trimesh.Trimesh(mirrored, f[:, ::-1])])
    add("two legs fused at the thighs, no side", pair.export(file_type="stl"), "model/stl", ("several_legs",))
    add("a leg in metres declared as mm", trimesh.Trimesh(v / 1000.0, f).export(file_type="stl"), "model/stl", ("implausible_size",), units="mm")
    add("a leg in mm declared as metres", good_stl, "model/stl", ("implausible_size",), units="m")
    add("a leg in cm, units left to detection", trimesh.Trimesh(v / 10.0, f).export(file_type="stl"), "model/stl", (FITS,))
    # --- names as clinics' systems write them
    add("Latin-1 file name", good_stl, "model/stl", (FITS,), filename="Müller_Jürgen_links.stl".encode("latin-1"))
    add("file name that climbs out of the store", good_stl, "model/stl", (FITS,), filename="../../../../etc/cron.d/leg.stl")
    add("a 5000-character file name", good_stl, "model/stl", (FITS,), filename="leg_" + "x" * 5000 + ".stl")
    add("a 20000-character file name", good_stl, "model/stl", ("header_too_long",), filename="leg_" + "y" * 20000 + ".stl")
    return cases
