"""The robustness corpus: seeded, deterministic synthetic scans with their truth.

``corpus_specs(n, seed)`` draws ``n`` case specifications with the shares of
:data:`KINDS`; ``build_case(spec)`` makes the scan file (bytes) and its truth.
Nothing generated is committed: the same seed gives the same bytes.

Every case is one leg of an ANSUR II subject (MakeHuman shape, see
:mod:`benchmarks.corpus.makehuman`), moved by a random rigid motion, written in mm,
cm or m, sometimes mirrored (a left leg then looks like a right one), with one
degradation.  ``expect`` is ``"fit"`` when the ankle minimum B and the knee waist D lie
in the scan, else the failure reason a correct service gives.
"""

from __future__ import annotations

import dataclasses
import io
from dataclasses import dataclass, field

import numpy as np
import trimesh

from benchmarks.corpus import degrade
from benchmarks.corpus.makehuman import ansur_subjects, leg_submesh, sized_legs
from benchmarks.corpus.truth import LegTruth, measure_truth

#: degradation -> (share of the corpus, what a correct service answers)
KINDS: dict[str, tuple[float, str]] = {
    "mesh_clean": (0.03, "fit"),
    "knee_high": (0.07, "fit"),             # foot to 15-45 mm above D (a knee-high stocking scan)
    "knee_high_cloud": (0.04, "fit"),
    "ankle_to_thigh": (0.05, "fit"),        # starts at or up to 10 mm below B
    "ankle_to_thigh_cloud": (0.03, "fit"),
    "midfoot_midthigh": (0.05, "fit"),
    "holes": (0.06, "fit"),                 # 3-6 holes up to 40 mm across on the calf
    "noise": (0.04, "fit"),                 # 0.3-1 mm normal noise on the vertices
    "cloud": (0.05, "fit"),
    "cloud_noise": (0.05, "fit"),           # up to 1 mm per coordinate
    "cloud_outliers": (0.05, "fit"),        # 2% stray, floor and ghost points
    "cloud_uneven": (0.05, "fit"),          # one side 4x sparser
    "cloud_holes": (0.05, "fit"),
    "floor": (0.04, "fit"),                 # floor grid or scanner platform under the foot
    "floor_cloud": (0.04, "fit"),
    "two_legs": (0.05, "fit"),              # feet to hips, side given
    "two_legs_no_side": (0.03, "several_legs"),
    "fragment": (0.04, "fit"),              # a piece of the other leg and spikes
    "seated": (0.05, "fit"),                # knee bent 30-100 degrees, foot to hip
    "plantar": (0.04, "fit"),               # foot pointed 20-45 degrees
    # a scanner's mesh exported as its vertices only (a PLY without faces): the ring
    # structure of a tessellation, 1.5-2 mm apart (three Loop subdivisions), 0-0.5 mm
    # noise, holes on half of them
    "vertex_cloud": (0.04, "fit"),
    # a coarse body: both legs feet to hips as a mesh of 2-4k vertices (the
    # unsubdivided model, edges p95 ~35 mm, as registered body meshes are), side given;
    # and the same legs' vertices after one subdivision (10-15k points) as a cloud
    "coarse_mesh": (0.03, "fit"),
    "body_vertices": (0.03, "fit"),
    # 3-10k vertices over one lower leg (foot to above the knee), as a cloud
    "sparse_leg_vertices": (0.03, "fit"),
    "cut_above_ankle": (0.025, "no_ankle"),  # starts 40-80 mm above B
    "cut_below_knee": (0.025, "no_knee"),    # ends 30-60 mm below D
}


@dataclass(frozen=True)
class CaseSpec:
    """``seed`` draws the leg and its degradation; with ``leg_seed`` the leg (its size,
    which leg of the body) is drawn from that seed instead, so that specs sharing a
    ``leg_seed`` and ``subject_index`` are re-scans of one leg (benchmarks/repeatability.py)."""

    case_id: str
    kind: str
    seed: int
    subject_index: int
    leg_seed: int | None = None


@dataclass
class Case:
    """A generated scan and what a correct fit of it gives.

    data, file_type, units (the units option to pass, None to let the service detect),
    side (the side option to pass); truth (generating coordinates) and ``to_scan``
    (4x4, generating mm -> scan file units, including any mirror and scale);
    ``true_side`` of the leg as scanned; ``foot_in_scan``.
    """

    spec: CaseSpec
    data: bytes
    file_type: str
    units: str | None
    side: str | None
    expect: str
    truth: LegTruth
    to_scan: np.ndarray
    true_side: str
    foot_in_scan: bool
    is_cloud: bool
    notes: dict = field(default_factory=dict)


def corpus_specs(n: int, seed: int = 7) -> list[CaseSpec]:
    """``n`` specs, each kind getting round(share * n) (at least 1), subjects drawn
    from all 6,068 ANSUR II rows."""
    rng = np.random.default_rng(seed)
    total = sum(share for share, _ in KINDS.values())
    specs = []
    n_subjects = len(ansur_subjects())
    for kind, (share, _) in KINDS.items():
        for i in range(max(1, round(share / total * n))):
            specs.append(CaseSpec(f"{kind}-{i:02d}", kind, int(rng.integers(2**31)), int(rng.integers(n_subjects))))
    return specs


def leg_rescans(legs: int, seed: int, kinds: tuple[str, ...]):
    """(leg index, spec) for ``legs`` generated legs drawn from ``seed``, each scanned as
    every one of ``kinds`` in turn: re-scans of one leg (its subject and ``leg_seed``
    shared, each scan's own pose, units and degradation).  The draws, in order: a leg's
    subject and leg seed, then one seed per kind (benchmarks/chart_accuracy.py,
    bench_thigh_design.py and sole.py read their legs this way)."""
    rng = np.random.default_rng(seed)
    n_subjects = len(ansur_subjects())
    for leg in range(legs):
        subject, leg_seed = int(rng.integers(n_subjects)), int(rng.integers(2**31))
        for kind in kinds:
            yield leg, CaseSpec(f"leg{leg:02d}-{kind}", kind, int(rng.integers(2**31)), subject, leg_seed)


def _write(mesh: trimesh.Trimesh | None, cloud: np.ndarray | None, rng: np.random.Generator) -> tuple[bytes, str]:
    if cloud is not None:
        if rng.random() < 0.5:
            text = io.StringIO()
            np.savetxt(text, cloud, fmt="%.4f", delimiter=" ")
            return text.getvalue().encode(), "xyz"
        return trimesh.PointCloud(cloud).export(file_type="ply"), "ply"
    fmt = str(rng.choice(["stl", "stl", "ply", "obj"]))
    data = mesh.export(file_type=fmt)
    return (data.encode() if isinstance(data, str) else data), fmt


def _cut_reach(girth_mm: float, axis: np.ndarray, normal: np.ndarray) -> float:
    """How far a cut of ``normal`` (3,), tilted off the leg's ``axis`` (3,), lies above or
    below its height on the axis at the edge of a section of ``girth_mm`` (mm: its
    radius, girth / 2 pi, times the tilt's tangent)."""
    tilt = float(np.arccos(np.clip(normal @ axis, -1.0, 1.0)))
    return float(girth_mm / (2 * np.pi) * np.tan(tilt))


def _knee_cut_notes(truth: LegTruth, axis: np.ndarray, normal: np.ndarray) -> dict:
    """A cut above the knee waist: how far it dips below its height on the axis across
    D's section, and how far above D the leg's girth rises by a tape's resolution
    (benchmarks/robustness.py: a scan that keeps less than that above D may be refused
    no_knee)."""
    return {"cut_drop_at_knee_mm": _cut_reach(truth.girths_mm["D"], axis, normal), "knee_rise_mm": truth.knee_rise_mm}


def build_case(spec: CaseSpec) -> Case:
    """Generate the scan of ``spec`` (deterministic in ``spec.seed``)."""
    rng = np.random.default_rng(spec.seed)
    kind = spec.kind
    subject = ansur_subjects()[spec.subject_index]
    knee_flexion = float(rng.uniform(30.0, 100.0)) if kind == "seated" else 0.0
    plantar = float(rng.uniform(20.0, 45.0)) if kind == "plantar" else 0.0
    leg_rng = rng if spec.leg_seed is None else np.random.default_rng(spec.leg_seed)
    # the tessellation a kind is scanned at: Loop subdivisions of the MakeHuman mesh
    # (0: edges p50 8 mm, p95 34 mm; 1: 4 / 17 mm; 2: ~3.5 mm mean; 3: ~1.7 mm)
    subdivisions = {"vertex_cloud": 3, "coarse_mesh": 0, "body_vertices": 1, "sparse_leg_vertices": 1}.get(kind, 2)
    legs = sized_legs(subject, leg_rng, knee_flexion, plantar, subdivisions=subdivisions)
    skin = legs  # the surface the truth is measured on
    if subdivisions == 1:
        # a body scanner's vertices lie on the skin, but a coarse Loop level's lie off the
        # finer levels' surface - outside it where the skin is convex, by 0.2 mm median,
        # 0.6 p95 and 1.5 max on subject 2000 (a tape girth ~1-4 mm long): each is moved
        # to where the reference level (2, every other kind's) puts it, its even vertex
        # (Loop subdivision keeps the coarse vertices first), so the sparse cloud samples
        # the same skin as the other re-scans of the leg and its truth is measured on it
        fine_vertices, fine_faces = trimesh.remesh.subdivide_loop(legs.vertices, legs.faces, iterations=1)
        skin = dataclasses.replace(legs, vertices=np.asarray(fine_vertices), faces=np.asarray(fine_faces, dtype=np.int64))
        legs = dataclasses.replace(legs, vertices=skin.vertices[: len(legs.vertices)])
    sign = float(leg_rng.choice([1.0, -1.0]))  # +1 MakeHuman's left leg (x > 0)
    prefix = "l" if sign > 0 else "r"
    leg = leg_submesh(legs.vertices, legs.faces, sign)
    ankle, knee = legs.joints[f"{prefix}-ankle"], legs.joints[f"{prefix}-knee"]
    truth = measure_truth(leg if skin is legs else leg_submesh(skin.vertices, skin.faces, sign), ankle, knee)
    axis = truth.axis
    b, d = truth.points_mm["B"], truth.points_mm["D"]
    sole_y = float(leg.vertices[:, 1].min())
    notes: dict = {"subject": int(subject["subjectid"]), "knee_flexion_deg": knee_flexion, "plantar_deg": plantar}
    foot = True
    mesh: trimesh.Trimesh = leg
    if kind in ("knee_high", "knee_high_cloud", "cut_below_knee"):
        reach = rng.uniform(15.0, 45.0) if kind != "cut_below_knee" else -rng.uniform(30.0, 60.0)
        notes["top_above_D_mm"] = float(reach)
        normal = degrade.tilted(axis, 8.0, rng)
        notes.update(_knee_cut_notes(truth, axis, normal))
        mesh = degrade.crop(mesh, d + reach * axis, -normal)
    if kind in ("ankle_to_thigh", "ankle_to_thigh_cloud", "cut_above_ankle"):
        start = -rng.uniform(0.0, 10.0) if kind != "cut_above_ankle" else rng.uniform(40.0, 80.0)
        notes["bottom_above_B_mm"] = float(start)
        normal = degrade.tilted(axis, 8.0, rng)
        # how far the tilted cut rises above its height on the axis across the ankle's
        # section (its radius from B's girth): B's band lies whole in the scan only below that
        notes["cut_rise_at_ankle_mm"] = _cut_reach(truth.girths_mm["B"], axis, normal)
        mesh = degrade.crop(mesh, b + start * axis, normal)
        foot = False
    if kind == "midfoot_midthigh":
        up = np.array([0.0, 1.0, 0.0])
        mesh = degrade.crop(mesh, np.array([0.0, sole_y + rng.uniform(30.0, 50.0), 0.0]), up)
        thigh_top = float(leg.vertices[:, 1].max())
        mesh = degrade.crop(mesh, np.array([0.0, 0.5 * (thigh_top + knee[1]), 0.0]), -up)
    if kind in ("holes", "cloud_holes"):
        centres, radii = degrade.holes_on_calf(mesh, b, d, int(rng.integers(3, 7)), rng)
        notes["holes_mm"] = (2 * radii).round(1).tolist()
        if kind == "holes":
            mesh = degrade.punch_holes(mesh, centres, radii)
    if kind == "noise":
        notes["noise_mm"] = float(rng.uniform(0.3, 1.0))
        mesh = degrade.vertex_noise(mesh, notes["noise_mm"], rng)
    if kind in ("two_legs", "two_legs_no_side", "coarse_mesh", "body_vertices"):
        mesh = trimesh.Trimesh(legs.vertices, legs.faces, process=False)
    if kind == "fragment":
        other = leg_submesh(legs.vertices, legs.faces, -sign)
        piece = degrade.crop(degrade.crop(other, b + 60.0 * axis, axis), d - 40.0 * axis, -axis)
        mesh = trimesh.util.concatenate([degrade.spikes(mesh, 6, rng), piece])
    if kind == "seated":  # the scan holds the whole bent leg, foot to hip
        pass
    if kind in ("floor", "floor_cloud"):
        as_box = bool(rng.random() < 0.5)
        notes["floor"] = "platform" if as_box else "floor"
        ground = degrade.floor_plane(leg.vertices.mean(axis=0), sole_y - rng.uniform(0.0, 2.0), 700.0, rng, as_box)
        if kind == "floor":
            mesh = trimesh.util.concatenate([mesh, ground])

    cloud = None
    if kind == "sparse_leg_vertices":  # foot to 15-45 mm above D, like a knee-high scan
        reach = rng.uniform(15.0, 45.0)
        notes["top_above_D_mm"] = float(reach)
        normal = degrade.tilted(axis, 8.0, rng)
        notes.update(_knee_cut_notes(truth, axis, normal))
        mesh = degrade.crop(mesh, d + reach * axis, -normal)
    if kind in ("vertex_cloud", "body_vertices", "sparse_leg_vertices"):
        cloud = np.asarray(mesh.vertices, dtype=np.float64)
        if kind == "vertex_cloud":
            notes["noise_mm"] = float(rng.uniform(0.0, 0.5))
            cloud = degrade.cloud_noise(cloud, notes["noise_mm"], rng)
            if rng.random() < 0.5:
                centres, radii = degrade.holes_on_calf(mesh, b, d, int(rng.integers(3, 7)), rng)
                notes["holes_mm"] = (2 * radii).round(1).tolist()
                cloud = degrade.cloud_holes(cloud, centres, radii)
        notes["n_points"] = int(len(cloud))
    elif kind.startswith("cloud") or kind.endswith("_cloud"):
        area = mesh.area
        cloud = degrade.sample_cloud(mesh, int(np.clip(area * rng.uniform(0.25, 0.5), 40_000, 120_000)), rng)
        if kind == "cloud_noise":
            notes["noise_mm"] = float(rng.uniform(0.3, 1.0))
            cloud = degrade.cloud_noise(cloud, notes["noise_mm"], rng)
        if kind == "cloud_outliers":
            cloud = degrade.outliers(cloud, 0.02, sole_y, rng)
            cloud = degrade.cloud_spikes(cloud, 5, rng)
        if kind == "cloud_uneven":
            cloud = degrade.uneven_density(cloud, axis, rng)
        if kind == "cloud_holes":
            cloud = degrade.cloud_holes(cloud, centres, radii)
        if kind == "floor_cloud":
            cloud = np.vstack([cloud, degrade.sample_cloud(ground, int(0.3 * len(cloud)), rng)])

    # the scan's own coordinates: mirror, rigid motion, units
    mirror = bool(rng.random() < 0.2)
    motion = degrade.rigid_motion(rng)
    if mirror:
        motion = motion @ np.diag([-1.0, 1.0, 1.0, 1.0])
    units = str(rng.choice(["mm", "mm", "mm", "m", "m", "cm"]))
    scale = {"mm": 1.0, "cm": 0.1, "m": 0.001}[units]
    to_scan = np.diag([scale, scale, scale, 1.0]) @ motion
    if cloud is not None:
        cloud = trimesh.transform_points(cloud, to_scan)
    else:
        mesh = mesh.copy()
        mesh.apply_transform(to_scan)  # trimesh flips the winding of a mirrored mesh
    data, file_type = _write(mesh, cloud, rng)
    true_side = ("left" if sign > 0 else "right") if not mirror else ("right" if sign > 0 else "left")
    expect = KINDS[kind][1]
    if kind == "seated" and truth.knee_hidden:
        # at this flexion the thigh covers the knee waist: no tape can be laid there, and
        # the right answer is the refusal that says so
        expect = "no_knee"
    notes["knee_hidden"] = truth.knee_hidden
    side = None
    if kind in ("two_legs", "coarse_mesh", "body_vertices"):
        side = true_side
    elif kind not in ("two_legs_no_side",) and rng.random() < 0.3:
        side = true_side
    notes.update(mirrored=mirror, units=units)
    return Case(spec, data, file_type, units if units == "cm" else None, side, expect, truth, to_scan,
                true_side, foot, cloud is not None, notes)
