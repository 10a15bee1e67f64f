"""Reading scans into millimetre point sets (paper section 2.1, data acquisition).

Supported: STL (binary and ASCII), PLY (mesh or points only), OBJ, OFF, GLB/glTF
(through trimesh), and plain XYZ / CSV / TXT point clouds (x y z first in each row, in the
dialects :mod:`app.geometry.scan.text_cloud` tells apart: separators, decimal commas,
extra columns, headers, PTS point counts).

Units: everything inside the service is millimetres.  The unit of a file is taken from
the caller (``units=``) or detected from the largest bounding-box extent ``L``: a
human lower leg is at least 120 mm long and a whole body at most 2.5 m, so the first of
``mm`` (120 <= L <= 2500), ``m`` (0.12 <= L <= 2.5) and ``cm`` (12 <= L <= 250) that puts
``L`` in 120..2500 mm wins.  The one real ambiguity (a 1.2-2.5 m body in cm reads like a
120-250 mm calf piece in mm) resolves to mm; pass ``units="cm"`` for such files.
"""

from __future__ import annotations

import io
import os
from dataclasses import dataclass

import numpy as np
import trimesh

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.scan.gltf_count import MAX_MESH_INSTANCES, gltf_json, gltf_scene_size
from app.geometry.scan.integrity import binary_stl_count, check_ply_integrity, check_stl_integrity
from app.geometry.scan.text_cloud import read_text_cloud

#: the formats read as text point clouds (app.geometry.scan.text_cloud; pts: Leica's
#: text cloud, asc: the ASCII cloud Geomagic and CloudCompare export)
TEXT_CLOUD_FORMATS = ("xyz", "csv", "txt", "pts", "asc")
#: file extensions (lower case, no dot) the reader accepts: trimesh's meshes, then the text clouds
SUPPORTED_FORMATS = ("stl", "ply", "obj", "off", "glb", "gltf") + TEXT_CLOUD_FORMATS

#: millimetres per unit
UNIT_SCALE_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}

#: plausible extent of a leg or body scan, mm
MIN_EXTENT_MM = 120.0
MAX_EXTENT_MM = 2500.0

#: no coordinate of a scan lies further from its origin (file units: 10 km in mm); past
#: it sums of squares overflow (1e308) and the numbers cannot be a leg's
MAX_COORDINATE = 1e7

#: fewer points than this cannot carry 200 sections x 72 angles of skin
MIN_POINTS = 500


@dataclass(frozen=True)
class Scan:
    """A scan in millimetres, still in the scan's own axes.

    Attributes
    ----------
    points_mm : (n, 3) float64
        Vertex (or point-cloud) coordinates, millimetres.
    faces : (f, 3) int64 or None
        Triangles indexing ``points_mm``; ``None`` for a point cloud.
    units : str
        Unit of the file: ``"mm"``, ``"cm"`` or ``"m"``.
    units_detected : bool
        True when ``units`` was inferred from the extent rather than given.
    source_format : str
        The format the file was read as.
    """

    points_mm: np.ndarray
    faces: np.ndarray | None
    units: str
    units_detected: bool
    source_format: str

    @property
    def mm_per_unit(self) -> float:
        return UNIT_SCALE_MM[self.units]

    @property
    def is_mesh(self) -> bool:
        return self.faces is not None and len(self.faces) > 0


def detect_units(extent: float) -> str:
    """Unit of a scan whose largest bounding-box extent is ``extent`` (file units).

    See the module docstring for the rule.  Raises ``FitFailure(IMPLAUSIBLE_SIZE)`` when
    no unit makes the scan the size of a leg or a body.
    """
    for unit in ("mm", "m", "cm"):
        length_mm = extent * UNIT_SCALE_MM[unit]
        if MIN_EXTENT_MM <= length_mm <= MAX_EXTENT_MM:
            return unit
    raise FitFailure(
        FailureReason.IMPLAUSIBLE_SIZE,
        f"the scan's largest extent is {extent:g} file units, which is not the size of a "
        "lower leg, a leg or a body in mm, cm or m; pass the units explicitly",
    )


def _format_of(name: str | None, file_type: str | None) -> str:
    fmt = (file_type or "").lower().lstrip(".")
    if not fmt and name:
        fmt = os.path.splitext(name)[1].lower().lstrip(".")
    if fmt == "stl_ascii":
        fmt = "stl"
    if fmt not in SUPPORTED_FORMATS:
        raise FitFailure(
            FailureReason.UNSUPPORTED_FORMAT,
            f"unsupported scan format {fmt or '(none)'!r}; use one of "
            + ", ".join(SUPPORTED_FORMATS),
        )
    return fmt


def merge_duplicate_vertices(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge bit-identical vertices (STL stores every corner separately).

    vertices (n, 3), faces (f, 3) -> unique vertices (u, 3) and re-indexed faces.  A
    64-bit hash of the coordinates is made unique with numpy; the result is checked
    exactly and trimesh's own merge is used if two different points ever collide.
    """
    bits = np.ascontiguousarray(vertices, dtype=np.float64).view(np.uint64)
    key = bits[:, 0] * np.uint64(0x9E3779B97F4A7C15) ^ bits[:, 1] * np.uint64(0xC2B2AE3D27D4EB4F) ^ bits[:, 2]
    # group equal keys: a stable sort, then a new group wherever the key changes
    order = np.argsort(key, kind="stable")
    ordered = key[order]
    starts = np.concatenate([[True], ordered[1:] != ordered[:-1]])
    group = np.cumsum(starts) - 1
    inverse = np.empty(len(key), dtype=np.int64)
    inverse[order] = group
    first = order[starts]  # the first corner of each group (stable sort)
    unique = vertices[first]
    if not np.array_equal(unique[inverse], vertices):  # hash collision: be exact
        mesh = trimesh.Trimesh(vertices, faces, process=False)
        mesh.merge_vertices(merge_tex=True, merge_norm=True)
        return np.asarray(mesh.vertices), np.asarray(mesh.faces, dtype=np.int64)
    return unique, inverse.reshape(-1)[faces]


def _check_size(what: str, count: int, limit: int) -> None:
    if count > limit:
        raise FitFailure(
            FailureReason.SCAN_TOO_LARGE,
            f"the scan has {count} {what}; this service accepts at most {limit}. A calf needs far fewer: "
            "decimate the mesh or subsample the cloud (1-2 mm spacing is plenty) and upload it again",
        )


def _ascii_text(data: bytes, fmt: str) -> bytes:
    """Text formats (ASCII STL, OBJ, OFF) with bytes beyond ASCII - a solid or group
    name in Latin-1, UTF-8 or another code page - get those bytes replaced by '?'.
    Only names and comments can hold them (numbers and keywords are ASCII), so the
    geometry is unchanged, and no guess at the code page is needed."""
    if fmt not in ("stl", "obj", "off") or data.isascii() or (fmt == "stl" and binary_stl_count(data) is not None):
        return data
    array = np.frombuffer(data, dtype=np.uint8).copy()
    array[array >= 0x80] = 0x3F
    return array.tobytes()


def _read_with_trimesh(data: bytes, fmt: str) -> tuple[np.ndarray, np.ndarray | None]:
    trimesh_type = "stl" if fmt == "stl" else fmt
    data = _ascii_text(data, fmt)
    try:
        # no trimesh processing: exact duplicate corners are merged below (3x faster);
        # nothing else is needed by the slicer, which takes any triangle soup
        geometry = trimesh.load(io.BytesIO(data), file_type=trimesh_type, process=False)
    except Exception as exc:  # trimesh raises many kinds for corrupt files
        # (the library's own message names its internals, not the file's fault)
        raise FitFailure(
            FailureReason.UNREADABLE_FILE,
            f"the file could not be read as {fmt.upper()}: it is corrupt, or not {fmt.upper()}",
        ) from exc
    if isinstance(geometry, trimesh.Scene):
        meshes = [g for g in geometry.dump() if isinstance(g, trimesh.Trimesh)]
        clouds = [g for g in geometry.dump() if isinstance(g, trimesh.PointCloud)]
        if meshes:
            geometry = trimesh.util.concatenate(meshes)
        elif clouds:
            geometry = trimesh.PointCloud(np.vstack([c.vertices for c in clouds]))
        else:
            raise FitFailure(FailureReason.EMPTY_SCAN, "the file holds no mesh or points")
    if isinstance(geometry, trimesh.Trimesh):
        faces = np.asarray(geometry.faces, dtype=np.int64)
        vertices = np.asarray(geometry.vertices, dtype=np.float64)
        if vertices.ndim != 2 or vertices.shape[1] != 3:
            raise FitFailure(FailureReason.UNREADABLE_FILE, f"the mesh's vertices have "
                             f"{vertices.shape[-1] if vertices.ndim == 2 else 'no'} coordinates; a 3D scan's have three (x y z)")
        if not len(faces):
            return vertices, None
        if not np.isfinite(vertices).all():
            return vertices, faces  # rejected with a reason by the caller
        if faces.min() < 0 or faces.max() >= len(vertices):
            raise FitFailure(FailureReason.UNREADABLE_FILE, "the mesh has faces pointing at missing vertices")
        vertices, faces = merge_duplicate_vertices(vertices, faces)
        used = np.bincount(faces.ravel(), minlength=len(vertices)) > 0
        if not used.all():  # drop vertices no face uses
            remap = np.cumsum(used) - 1
            vertices, faces = vertices[used], remap[faces]
        return vertices, faces
    if isinstance(geometry, trimesh.PointCloud):
        return np.asarray(geometry.vertices, dtype=np.float64), None
    raise FitFailure(
        FailureReason.UNREADABLE_FILE, f"the file holds a {type(geometry).__name__}, not a scan"
    )


#: glTF extensions that compress a mesh's buffers in a way the reader cannot undo: a
#: reader that ignores them reads the uncompressed fallback, which a compressed file may
#: leave empty (zeros), so a file that requires one is refused by name.  (Draco,
#: KHR_draco_mesh_compression, is read: trimesh decodes it with DracoPy.)
UNREADABLE_GLTF_EXTENSIONS = ("EXT_meshopt_compression", "KHR_meshopt_compression")


def _check_gltf_extensions(document: dict, fmt: str) -> None:
    """FitFailure (unsupported_format) when the glTF JSON ``document`` requires an
    extension the reader cannot read (:data:`UNREADABLE_GLTF_EXTENSIONS`), by name."""
    required = document.get("extensionsRequired", [])
    names = [name for name in required if name in UNREADABLE_GLTF_EXTENSIONS] if isinstance(required, list) else []
    if names:
        raise FitFailure(
            FailureReason.UNSUPPORTED_FORMAT,
            f"the {fmt.upper()} is compressed with {', '.join(names)}, which this service cannot read: export it "
            "uncompressed or with Draco compression (KHR_draco_mesh_compression), or as PLY or STL")


def load_scan(
    source: str | os.PathLike | bytes,
    *,
    file_type: str | None = None,
    units: str | None = None,
    max_points: int | None = None,
    max_faces: int | None = None,
) -> Scan:
    """Read a scan file (path or bytes) into a :class:`Scan` in millimetres.

    Parameters
    ----------
    source : path or bytes
        The file.  With bytes, ``file_type`` names the format.
    file_type : str, optional
        Format (extension without the dot); taken from the path when omitted.
    units : {"mm", "cm", "m", "in"}, optional
        Unit of the coordinates; detected from the extent when omitted (mm, m or cm:
        inches are never guessed from the extent; :mod:`app.geometry.placement.leg_size` names
        them when the calf reads too thin).

    Raises
    ------
    FitFailure
        ``unsupported_format``, ``unreadable_file``, ``truncated_file``, ``empty_scan``,
        ``non_finite_coordinates``, ``too_few_points`` or ``implausible_size``.
    """
    name = None
    if isinstance(source, (bytes, bytearray, memoryview)):
        data = bytes(source)
    else:
        name = os.fspath(source)
        try:
            with open(name, "rb") as handle:
                data = handle.read()
        except OSError as exc:
            raise FitFailure(FailureReason.UNREADABLE_FILE, "the scan file cannot be opened (missing or unreadable)") from exc
    fmt = _format_of(name, file_type)
    if units is not None and units not in UNIT_SCALE_MM:
        raise FitFailure(
            FailureReason.INVALID_OPTION, f"units must be one of mm, cm, m, in, not {units!r}"
        )
    if not data.strip():
        raise FitFailure(FailureReason.EMPTY_SCAN, "the file is empty")

    announced = binary_stl_count(data) if fmt == "stl" else None
    if max_faces is not None and announced is not None:
        # a binary STL says how many triangles it holds before any is read
        _check_size("triangles", announced, max_faces)
    document = gltf_json(data, fmt) if fmt in ("glb", "gltf") else None
    if document is not None:
        _check_gltf_extensions(document, fmt)
    if document is not None and (max_points is not None or max_faces is not None):
        # a scene instancing one mesh N times is counted from its JSON before trimesh
        # expands it (app.geometry.scan.gltf_count)
        size = gltf_scene_size(document)
        if size.max_instances > MAX_MESH_INSTANCES:
            raise FitFailure(FailureReason.SCAN_TOO_LARGE, f"the file's scene shows one mesh {size.max_instances} times "
                             f"({size.triangles} triangles once expanded); a scan holds each of its meshes once "
                             f"(at most {MAX_MESH_INSTANCES}): export the scan itself, not a scene of copies")
        if max_faces is not None:
            _check_size("triangles (every instance of the scene counted)", size.triangles, max_faces)
        if max_points is not None:
            _check_size("points (every instance of the scene counted)", size.points, max_points)
    if fmt in TEXT_CLOUD_FORMATS:
        points, faces = read_text_cloud(data), None
    else:
        if fmt == "stl":
            check_stl_integrity(data)
        if fmt == "ply":
            check_ply_integrity(data)
        points, faces = _read_with_trimesh(data, fmt)
    if max_points is not None:
        _check_size("points", len(points), max_points)
    if max_faces is not None and faces is not None:
        _check_size("triangles", len(faces), max_faces)

    if points.size == 0:
        raise FitFailure(FailureReason.EMPTY_SCAN, "the scan has no points")
    if points.ndim != 2 or points.shape[1] != 3:
        raise FitFailure(FailureReason.UNREADABLE_FILE,
                         f"the scan's vertices have {points.shape[-1] if points.ndim == 2 else 'no'} coordinates; "
                         "a 3D scan's have three (x y z)")
    if not np.isfinite(points).all():
        bad = int((~np.isfinite(points)).any(axis=1).sum())
        raise FitFailure(
            FailureReason.NON_FINITE_COORDINATES,
            f"{bad} of {len(points)} points have NaN or infinite coordinates",
        )
    if len(points) < MIN_POINTS:
        raise FitFailure(
            FailureReason.TOO_FEW_POINTS,
            f"the scan has {len(points)} points; at least {MIN_POINTS} are needed",
        )
    reach = float(np.abs(points).max())
    if reach > MAX_COORDINATE:
        raise FitFailure(
            FailureReason.IMPLAUSIBLE_SIZE,
            f"the scan's coordinates reach {reach:.3g} file units from its origin; a scan's lie within "
            f"{MAX_COORDINATE:.0e} (10 km in mm): the numbers are not coordinates of a leg")
    extent = float(np.ptp(points, axis=0).max())
    detected = units is None
    unit = detect_units(extent) if units is None else units
    length_mm = extent * UNIT_SCALE_MM[unit]
    if not (MIN_EXTENT_MM <= length_mm <= MAX_EXTENT_MM):
        raise FitFailure(
            FailureReason.IMPLAUSIBLE_SIZE,
            f"in {unit} the scan is {length_mm:.0f} mm long; a leg or body scan is "
            f"{MIN_EXTENT_MM:.0f}-{MAX_EXTENT_MM:.0f} mm",
        )
    return Scan(
        points_mm=points * UNIT_SCALE_MM[unit],
        faces=faces,
        units=unit,
        units_detected=detected,
        source_format=fmt,
    )
