"""MakeHuman legs (CC0) blended to the size of ANSUR II subjects, and posed.

The blend is MakeHuman's macro system as its data README describes it (a plain linear
sum of sparse morph targets, weights from the gender / age / muscle / weight / height
sliders), re-implemented here from that description.  A subject's ankle and calf
girths are matched by the two local sliders ``measure-ankle-circ`` and
``measure-calf-circ`` (about 57 and 95 mm per unit, nearly independent): one secant
step from a first blend measured with :func:`benchmarks.corpus.truth.quick_girths`.

Units: MakeHuman's decimetres in, millimetres out.  MakeHuman axes: Y up, +Z anterior,
+X the character's left.  Arrays: vertices (n, 3) float64, faces (f, 3) int64.
"""

from __future__ import annotations

import csv
import itertools
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parents[2]
MAKEHUMAN_NPZ = ROOT / "tests" / "data" / "makehuman" / "makehuman_legs_adult.npz"
ANSUR_CSV = ROOT / "tests" / "data" / "ansur2" / "ansur2_lower_leg.csv"
DM = 100.0  # mm per decimetre

#: girth change per unit of the measure sliders (data README, calibration table), mm
ANKLE_MM_PER_UNIT = 57.0
CALF_MM_PER_UNIT = 95.0


@lru_cache(maxsize=1)
def makehuman() -> dict:
    """The vendored MakeHuman leg package (adult targets only), as a dict of arrays."""
    with np.load(MAKEHUMAN_NPZ) as z:
        return {k: z[k] for k in z.files}


@lru_cache(maxsize=1)
def ansur_subjects() -> list[dict]:
    """ANSUR II rows (6,068 subjects) with the lower-leg columns as numbers (mm)."""
    with open(ANSUR_CSV, newline="") as handle:
        rows = list(csv.DictReader(handle))
    numeric = [k for k in rows[0] if k not in ("Gender",)]
    return [{**{k: float(r[k]) for k in numeric}, "Gender": r["Gender"]} for r in rows]


@dataclass(frozen=True)
class Sliders:
    """MakeHuman slider values: macro in [0, 1], local in [-1, 1] (name -> value)."""

    gender: float = 0.5
    age: float = 0.5
    muscle: float = 0.5
    weight: float = 0.5
    height: float = 0.5
    african: float = 1 / 3
    asian: float = 1 / 3
    local: tuple = ()


def _tri(v: float, lo: str, mid: str, hi: str) -> dict:
    a, c = max(0.0, 1 - 2 * v), max(0.0, 2 * v - 1)
    return {lo: a, mid: 1 - a - c, hi: c}


def blend(s: Sliders) -> np.ndarray:
    """(3370, 3) vertices in dm: skin rows then the joint-helper cubes (adults: age >= 0.5)."""
    z = makehuman()
    vertices = z["base_vertices"].astype(np.float64).copy()

    def add(key: str, w: float) -> None:
        if abs(w) > 1e-6 and key in z and len(z[key]):
            t = z[key]
            vertices[t["idx"]] += w * t["delta"].astype(np.float64)

    if s.age < 0.5:
        raise ValueError("the vendored package holds adult targets only (age >= 0.5)")
    old = 2 * s.age - 1
    genders = {"female": 1 - s.gender, "male": s.gender}
    ages = {"young": 1 - old, "old": old}
    muscles = _tri(s.muscle, "minmuscle", "averagemuscle", "maxmuscle")
    weights = _tri(s.weight, "minweight", "averageweight", "maxweight")
    hx, hn = max(0.0, 2 * s.height - 1), max(0.0, 1 - 2 * s.height)
    races = {"african": s.african, "asian": s.asian, "caucasian": 1 - s.african - s.asian}
    for g, a in itertools.product(genders, ages):
        for r in races:
            add(f"macrodetails/{r}-{g}-{a}.target", races[r] * genders[g] * ages[a])
        for m, w in itertools.product(muscles, weights):
            b = genders[g] * ages[a] * muscles[m] * weights[w]
            add(f"macrodetails/universal-{g}-{a}-{m}-{w}.target", b)
            add(f"macrodetails/height/{g}-{a}-{m}-{w}-maxheight.target", b * hx)
            add(f"macrodetails/height/{g}-{a}-{m}-{w}-minheight.target", b * hn)
    for name, v in s.local:
        if name.startswith("armslegs/foot-trans"):
            for leg in ("l", "r"):
                add(f"armslegs/{leg}-foot-trans-{'in' if v > 0 else 'out'}.target", abs(v))
            continue
        add(f"{name}-{'incr' if v > 0 else 'decr'}.target", abs(v))
    return vertices


def joints_mm(vertices_dm: np.ndarray) -> dict[str, np.ndarray]:
    """Joint centres (mm) from the helper cubes: name -> (3,)."""
    z = makehuman()
    return {str(n): vertices_dm[idx].mean(axis=0) * DM for n, idx in zip(z["joint_names"], z["joint_vertex_index"])}


def _smoothstep(t: np.ndarray) -> np.ndarray:
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3 - 2 * t)


def rotate_below(vertices_mm: np.ndarray, mask: np.ndarray, centre: np.ndarray, angle_deg: float, blend_mm: float) -> np.ndarray:
    """Bend the masked vertices about the lateral (x) axis through ``centre``.

    A one-joint linear blend: vertices more than ``blend_mm`` below the joint turn by the
    full angle, those more than ``blend_mm`` above stay, a smoothstep in between (so
    the skin does not tear).  Positive angles move what lies below the joint backwards
    (-z, knee flexion) or, for a foot, the toes down (plantar flexion).
    vertices_mm (n, 3), mask (n,) bool -> (n, 3).
    """
    rel = vertices_mm - centre
    w = _smoothstep((-rel[:, 1] + blend_mm) / (2 * blend_mm)) * mask
    theta = np.radians(angle_deg) * w
    c, s = np.cos(theta), np.sin(theta)
    out = vertices_mm.copy()
    out[:, 1] = centre[1] + c * rel[:, 1] - s * rel[:, 2]
    out[:, 2] = centre[2] + s * rel[:, 1] + c * rel[:, 2]
    return out


@dataclass(frozen=True)
class GeneratedLegs:
    """Both MakeHuman legs (joined at the crotch, open at the top) of one subject, mm.

    vertices (n, 3), faces (f, 3) after two Loop subdivisions (mean edge ~3.5 mm);
    ``joints`` name -> (3,) mm after posing; ``subject`` the ANSUR row used.
    """

    vertices: np.ndarray
    faces: np.ndarray
    joints: dict
    subject: dict
    sliders: Sliders


def subject_sliders(subject: dict, rng: np.random.Generator) -> Sliders:
    """Macro sliders for an ANSUR subject, with shape variety drawn from ``rng``.

    gender from the record; height from stature (z-score within the sex, 2.5 sd to the
    slider's ends); weight from BMI (18 -> 0, 34 -> 1); age from years; muscle and the
    lower-leg fat/muscle local sliders at random (legs of equal girth differ in shape).
    """
    male = subject["Gender"] == "Male"
    mean, sd = (1756.2, 68.6) if male else (1628.5, 64.2)
    height = float(np.clip(0.5 + (subject["stature"] - mean) / (5 * sd), 0.05, 0.95))
    bmi = subject["weightkg"] / 10.0 / (subject["stature"] / 1000.0) ** 2
    age = float(np.clip(0.5 + (subject["Age"] - 25) / 130.0, 0.5, 0.75))
    local = (
        ("armslegs/l-lowerleg-fat", float(rng.uniform(-0.4, 0.4))),
        ("armslegs/l-lowerleg-muscle", float(rng.uniform(-0.4, 0.4))),
    )
    local = local + tuple((n.replace("/l-", "/r-"), v) for n, v in local)
    return Sliders(
        gender=1.0 if male else 0.0,
        age=age,
        muscle=float(rng.uniform(0.25, 0.75)),
        weight=float(np.clip((bmi - 18.0) / 16.0, 0.0, 1.0)),
        height=height,
        african=0.0, asian=0.0,
        local=local,
    )


def height_for_shank(sliders: Sliders, shank_mm: float) -> float:
    """The height slider that gives ``sliders``' body a shank (ankle joint to knee joint)
    of ``shank_mm``.

    MakeHuman's height slider scales the whole body, and from stature alone it makes
    tall subjects' shanks far longer than ANSUR II's (530 mm for a 1836 mm man whose
    tibiale-to-lateral-malleolus length is 418 mm; ANSUR II's longest is 499 mm).  The
    lower leg is what is scanned, so its length is matched: the vertices are linear in
    the slider on each side of 0.5, so the shank length is sampled every 0.05 and
    inverted by interpolation (clipped to the slider's range).  Tibiale height minus
    lateral malleolus height is taken as the joint-to-joint length (both landmarks lie
    within ~1 cm of the joint centres).
    """
    grid = np.linspace(0.0, 1.0, 21)
    lengths = []
    for h in grid:
        joints = joints_mm(blend(Sliders(**{**sliders.__dict__, "height": float(h)})))
        lengths.append(float(np.linalg.norm(joints["l-knee"] - joints["l-ankle"])))
    return float(np.interp(shank_mm, np.maximum.accumulate(lengths), grid))


def sized_legs(subject: dict, rng: np.random.Generator, knee_flexion_deg: float = 0.0,
               plantar_flexion_deg: float = 0.0, subdivisions: int = 2) -> GeneratedLegs:
    """Both legs of ``subject``: blended, shank length and girths matched, posed,
    subdivided (mm)."""
    from benchmarks.corpus.truth import quick_girths

    base = subject_sliders(subject, rng)
    base = Sliders(**{**base.__dict__, "height": height_for_shank(base, subject["tibialheight"] - subject["lateralmalleolusheight"])})
    first = blend(base)
    girth_b, girth_c = quick_girths(first)
    ankle = float(np.clip((subject["anklecircumference"] - girth_b) / ANKLE_MM_PER_UNIT, -1.0, 1.0))
    calf = float(np.clip((subject["calfcircumference"] - girth_c) / CALF_MM_PER_UNIT, -0.6, 1.0))
    sliders = Sliders(**{**base.__dict__, "local": base.local + (
        ("measure/measure-ankle-circ", ankle), ("measure/measure-calf-circ", calf))})
    vertices_dm = blend(sliders)
    z = makehuman()
    n_skin = int(z["n_skin"])
    joints = joints_mm(vertices_dm)
    skin = vertices_dm[:n_skin] * DM
    for prefix, sign in (("l", 1.0), ("r", -1.0)):
        leg = skin[:, 0] * sign > 0
        if knee_flexion_deg:
            knee = joints[f"{prefix}-knee"]
            skin = rotate_below(skin, leg, knee, knee_flexion_deg, 45.0)
            for name in (f"{prefix}-ankle", f"{prefix}-foot-1", f"{prefix}-foot-2"):
                joints[name] = rotate_below(joints[name][None], np.ones(1, bool), knee, knee_flexion_deg, 45.0)[0]
        if plantar_flexion_deg:
            # the foot turns about the ankle joint: the blend runs along the shank (local y)
            skin = _plantar_flex(skin, leg, joints, prefix, plantar_flexion_deg)
    faces = z["faces"].astype(np.int64)
    vertices, faces = trimesh.remesh.subdivide_loop(skin, faces, iterations=subdivisions)
    return GeneratedLegs(np.asarray(vertices), np.asarray(faces, dtype=np.int64), joints, subject, sliders)


#: an adducted leg turns by the full angle this far below its hip joint and not at all
#: at the joint, a smoothstep between: the crotch, 30-50 mm below the joints, barely moves
ADDUCTION_BLEND_MM = 150.0


def adduct(vertices_mm: np.ndarray, mask: np.ndarray, hip: np.ndarray, angle_deg: float,
           blend_mm: float = ADDUCTION_BLEND_MM) -> np.ndarray:
    """Turn the masked vertices about the anterior (z) axis through the hip joint ``hip``
    (3,): those ``blend_mm`` or more below the joint by ``angle_deg`` (positive moves
    what lies below towards +x), those at or above it not at all.  A one-joint linear
    blend, as :func:`rotate_below` bends the knee.  vertices_mm (n, 3), mask (n,) bool
    -> (n, 3)."""
    rel = vertices_mm - hip
    theta = np.radians(angle_deg) * _smoothstep(-rel[:, 1] / blend_mm) * mask
    c, s = np.cos(theta), np.sin(theta)
    out = vertices_mm.copy()
    out[:, 0] = hip[0] + c * rel[:, 0] - s * rel[:, 1]
    out[:, 1] = hip[1] + s * rel[:, 0] + c * rel[:, 1]
    return out


def adduct_legs(legs: GeneratedLegs, angle_deg: float) -> GeneratedLegs:
    """Both legs turned towards each other by ``angle_deg`` about their hip joints
    (:func:`adduct`; the joints below go with them).  MakeHuman stands with its ankles
    ~330 mm apart; a patient at a scanner often stands with the feet together, and at
    some angle (about 10 degrees) the knees or ankles meet.  Past it the generator's
    skins pass into each other where a body's would press flat."""
    vertices, joints = legs.vertices, dict(legs.joints)
    for prefix, sign in (("l", 1.0), ("r", -1.0)):
        hip = joints[f"{prefix}-upper-leg"]
        vertices = adduct(vertices, vertices[:, 0] * sign > 0, hip, -sign * angle_deg)
        for name in (f"{prefix}-knee", f"{prefix}-ankle", f"{prefix}-foot-1", f"{prefix}-foot-2"):
            joints[name] = adduct(joints[name][None], np.ones(1, bool), hip, -sign * angle_deg)[0]
    return GeneratedLegs(vertices, legs.faces, joints, legs.subject, legs.sliders)


def _plantar_flex(skin: np.ndarray, leg: np.ndarray, joints: dict, prefix: str, angle_deg: float) -> np.ndarray:
    """Turn the foot (toes down) about the ankle joint, blended 25 mm along the shank."""
    ankle, knee = joints[f"{prefix}-ankle"], joints[f"{prefix}-knee"]
    up = (knee - ankle) / np.linalg.norm(knee - ankle)
    lateral = np.array([1.0, 0.0, 0.0])
    forward = np.cross(lateral, up)
    forward /= np.linalg.norm(forward)
    lateral = np.cross(up, forward)
    basis = np.stack([lateral, up, forward])  # local x, y (up the shank), z (anterior)
    local = (skin - ankle) @ basis.T
    bent = rotate_below(local, leg, np.zeros(3), angle_deg, 25.0)
    return bent @ basis + ankle


def leg_submesh(vertices: np.ndarray, faces: np.ndarray, side_sign: float) -> trimesh.Trimesh:
    """One leg (+1 the character's left, x > 0; -1 the right) cut from both legs."""
    keep = vertices[:, 0] * side_sign > 0
    f = faces[keep[faces].all(axis=1)]
    mesh = trimesh.Trimesh(vertices, f, process=False)
    mesh.remove_unreferenced_vertices()
    return mesh
