"""Graduated compression stocking design on the NURBS calf (paper section 4, Laplace's law).

Model
-----
At height h the stretched fabric follows the *convex hull* of the leg's cross-section (it
bridges concavities).  Its length is the hull perimeter L(h).  With tension per unit width
T(h) = K * eps(h), eps = L / L0 - 1 (L0: the relaxed knitted circumference), the local
pressure on the skin is P = T * kappa, kappa the curvature of the contour where the
fabric touches it and 0 where it bridges.  Because the hull of a smooth closed curve turns
by exactly 2*pi along its contact arcs, the mean pressure around the contour is
2*pi*T / L.  kappa comes from the NURBS surface's own derivatives (The NURBS Book eq.
4.20 via :func:`app.geometry.nurbs.evaluate_derivatives`): for the ring C(u) = S(u, v_h)
in the calf's horizontal plane, kappa = (x' y'' - y' x'') / |C'|^3.

Units: lengths mm, tension N/cm (per cm of fabric width; K in N/cm per unit strain),
pressure Pa internally and reported in mmHg (1 mmHg = 133.322 Pa) and kPa.
T [N/cm] * kappa [1/mm] = 1e5 * T * kappa Pa.

Design
------
Targets: a compression class at B (:data:`COMPRESSION_CLASSES`) graded down the leg by
:data:`GRADIENT`, or explicit pressures at B, B1, C, D; in between, linear in height.
For every height from B to D (every ``step_mm`` and at the landmarks) the tension that
gives the target mean pressure is T = P * L / (2*pi), the strain comes from the fabric
(linear K, or a measured tension-strain table interpolated by PCHIP, monotone), and
L0 = L / (1 + eps) is the knitting specification, rounded to ``resolution_mm``.  The
prediction is then recomputed from the rounded L0, as the knitted stocking would give.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage
from scipy.interpolate import PchipInterpolator
from scipy.spatial import ConvexHull

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.nurbs import NurbsSurface, evaluate_derivatives, evaluate_grid

PA_PER_MMHG = 133.322
#: tension [N/cm] x curvature [1/mm] -> pressure [Pa]
PA_PER_N_PER_CM_PER_MM = 1e5
#: a ring sample is in contact with the fabric when within this distance of the hull, mm
CONTACT_TOLERANCE_MM = 0.05
LANDMARKS = ("B", "B1", "C", "D")

#: Compression classes: mean pressure at B (the ankle), mmHg.  None: no upper bound.
COMPRESSION_CLASSES = {
    "RAL": {
        "source": "RAL-GZ 387/1 (Germany, 2008): pressure at B",
        "classes": {"I": (18.0, 21.0), "II": (23.0, 32.0), "III": (34.0, 46.0), "IV": (49.0, None)},
    },
    "BS": {
        "source": "BS 6612:1985 (United Kingdom): pressure at the ankle",
        "classes": {"1": (14.0, 17.0), "2": (18.0, 24.0), "3": (25.0, 35.0)},
    },
    "AFNOR": {
        "source": "NF G30-102 (France): pressure at the ankle",
        "classes": {"1": (10.0, 15.0), "2": (15.1, 20.0), "3": (20.1, 36.0), "4": (36.1, None)},
    },
}
#: design target inside a class: the middle of the range; open-ended classes 10% above the bound
OPEN_CLASS_MARGIN = 1.10

#: Pressure gradient down the leg as fractions of the pressure at B.  ONE table, with the
#: standing of each row: only the D row is normative (RAL-GZ 387: at most 70% at D); the
#: B1 and C rows are the values commonly cited in the compression literature and by
#: manufacturers, not a requirement of RAL-GZ 387 - they are marked as such.
GRADIENT = {
    "B1": {"range": (0.70, 1.00), "target": 0.85, "normative": False,
           "source": "commonly cited (not normative in RAL-GZ 387): B1 70-100% of B"},
    "C": {"range": (0.50, 0.80), "target": 0.65, "normative": False,
          "source": "commonly cited (not normative in RAL-GZ 387): C 50-80% of B"},
    "D": {"range": (0.0, 0.70), "target": 0.50, "normative": True,
          "source": "RAL-GZ 387: at D at most 70% of the pressure at B"},
}

#: Default limit for local pressure hot spots, mmHg.  Partsch et al. (Dermatol Surg 2008;
#: 34:600-609, the consensus on compression pressures) call sub-bandage pressures above
#: 60 mmHg "very strong"; local pressure over tendons and bony prominences beyond that is
#: where the skin-damage risk the paper warns about begins.  Configurable per design.
DEFAULT_HOT_SPOT_MMHG = 60.0
#: strain a plain linear fabric may be asked for (100%); beyond it the design is refused
DEFAULT_MAX_STRAIN = 1.0


def _design_failure(reason: FailureReason, detail: str) -> FitFailure:
    return FitFailure(reason, detail)


# --------------------------------------------------------------------- fabric


@dataclass(frozen=True)
class Fabric:
    """Tension per unit width as a function of strain.

    Either ``stiffness_n_per_cm`` (linear: T = K * eps up to ``max_strain``) or a
    measured table ``strains`` / ``tensions_n_per_cm`` (strictly increasing, starting at
    0 tension at 0 strain is not required), interpolated by PCHIP, valid up to its last
    strain.
    """

    stiffness_n_per_cm: float | None = None
    strains: tuple = ()
    tensions_n_per_cm: tuple = ()
    max_strain: float = DEFAULT_MAX_STRAIN

    @staticmethod
    def linear(stiffness_n_per_cm: float, max_strain: float = DEFAULT_MAX_STRAIN) -> "Fabric":
        fabric = Fabric(stiffness_n_per_cm=float(stiffness_n_per_cm), max_strain=float(max_strain))
        fabric.validate()
        return fabric

    @staticmethod
    def table(strains, tensions_n_per_cm) -> "Fabric":
        strains = tuple(float(s) for s in strains)
        tensions = tuple(float(t) for t in tensions_n_per_cm)
        fabric = Fabric(strains=strains, tensions_n_per_cm=tensions, max_strain=max(strains) if strains else 0.0)
        fabric.validate()
        return fabric

    def validate(self) -> None:
        if self.stiffness_n_per_cm is not None:
            k = self.stiffness_n_per_cm
            if not np.isfinite(k) or k <= 0:
                raise _design_failure(FailureReason.INVALID_FABRIC, f"stiffness must be a positive number of N/cm, not {k}")
            if k > 1000:
                raise _design_failure(FailureReason.INVALID_FABRIC, f"a stiffness of {k:g} N/cm per unit strain is not a knitted fabric (expected 0.1-100)")
            if not (0 < self.max_strain <= 5):
                raise _design_failure(FailureReason.INVALID_FABRIC, f"max_strain must be in (0, 5], not {self.max_strain}")
            return
        s, t = np.array(self.strains), np.array(self.tensions_n_per_cm)
        if len(s) < 2 or len(s) != len(t):
            raise _design_failure(FailureReason.INVALID_FABRIC, "a tension-strain table needs at least 2 rows of (strain, tension)")
        if not (np.isfinite(s).all() and np.isfinite(t).all()):
            raise _design_failure(FailureReason.INVALID_FABRIC, "the tension-strain table has non-finite values")
        if (s < 0).any() or (t < 0).any():
            raise _design_failure(FailureReason.INVALID_FABRIC, "strains and tensions must not be negative")
        if np.any(np.diff(s) <= 0) or np.any(np.diff(t) <= 0):
            raise _design_failure(FailureReason.INVALID_FABRIC, "the tension-strain table must be strictly increasing in strain and in tension")
        if s[-1] > 5 or t[-1] > 1000:
            raise _design_failure(FailureReason.INVALID_FABRIC, "the table reaches beyond 500% strain or 1000 N/cm: not a knitted fabric")

    def tension(self, strain: np.ndarray) -> np.ndarray:
        """T(eps), N/cm."""
        strain = np.asarray(strain, dtype=float)
        if self.stiffness_n_per_cm is not None:
            return self.stiffness_n_per_cm * strain
        return PchipInterpolator(self.strains, self.tensions_n_per_cm, extrapolate=True)(strain)

    def strain_for(self, tension: np.ndarray) -> np.ndarray:
        """eps(T), the inverse (monotone, so well defined); NaN beyond the fabric's range."""
        tension = np.asarray(tension, dtype=float)
        if self.stiffness_n_per_cm is not None:
            strain = tension / self.stiffness_n_per_cm
            return np.where(strain <= self.max_strain + 1e-12, strain, np.nan)
        # invert the forward PCHIP itself (monotone): sample it densely and interpolate
        grid = np.linspace(self.strains[0], self.strains[-1], 4001)
        forward = self.tension(grid)
        strain = np.interp(tension, forward, grid, left=np.nan, right=np.nan)
        below = tension < self.tensions_n_per_cm[0]
        if below.any():  # below the first row: linear towards zero strain
            strain = np.where(below, tension / self.tensions_n_per_cm[0] * self.strains[0], strain)
        return strain

    def as_dict(self) -> dict:
        if self.stiffness_n_per_cm is not None:
            return {"stiffness_n_per_cm": self.stiffness_n_per_cm, "max_strain": self.max_strain}
        return {"table": [[s, t] for s, t in zip(self.strains, self.tensions_n_per_cm)]}


# --------------------------------------------------------------- cross-sections


@dataclass(frozen=True)
class Rings:
    """Horizontal rings of the surface at k heights, n samples each (calf frame, mm).

    points (k, n, 2); curvature (k, n) 1/mm (positive where convex); arc (k, n) the arc
    length each sample stands for; contact (k, n) bool, on the hull; hull_perimeter (k,);
    perimeter (k,); centroid (k, 2); angle (k, n) direction of each sample from the
    centroid, radians.
    """

    heights_mm: np.ndarray
    u: np.ndarray
    v: np.ndarray
    points: np.ndarray
    z: np.ndarray
    curvature: np.ndarray
    arc: np.ndarray
    contact: np.ndarray
    hull_perimeter: np.ndarray
    perimeter: np.ndarray
    centroid: np.ndarray
    angle: np.ndarray


def heights_to_v(surface: NurbsSurface, heights: np.ndarray, samples: int = 2001) -> np.ndarray:
    """v parameters whose rings lie at the given calf-frame heights (mean z of the ring)."""
    v0, v1 = surface.domain_v
    u0, u1 = surface.domain_u
    v = np.linspace(v0, v1, samples)
    u = u0 + (u1 - u0) * np.arange(8) / 8
    z = evaluate_grid(surface, u, v)[..., 2].mean(axis=0)
    if np.any(np.diff(z) <= 0):
        raise _design_failure(FailureReason.INVALID_RECORD, "the surface's rings do not rise monotonically along v")
    heights = np.asarray(heights, dtype=float)
    if heights.min() < z[0] - 1e-6 or heights.max() > z[-1] + 1e-6:
        raise _design_failure(FailureReason.INVALID_TARGET, f"heights must lie between {z[0]:.1f} and {z[-1]:.1f} mm")
    return np.interp(heights, z, v)


def surface_rings(surface: NurbsSurface, heights: np.ndarray, n_around: int = 360) -> Rings:
    """Rings, curvature from the surface derivatives, and fabric contact (convex hull)."""
    heights = np.asarray(heights, dtype=float)
    v_of_h = heights_to_v(surface, heights)
    u0, u1 = surface.domain_u
    u = u0 + (u1 - u0) * np.arange(n_around) / n_around
    k = len(heights)
    uu = np.tile(u, k)
    vv = np.repeat(v_of_h, n_around)
    s, su, _, suu, _, _ = evaluate_derivatives(surface, uu, vv)
    points = s[:, :2].reshape(k, n_around, 2)
    z = s[:, 2].reshape(k, n_around)
    dx, dy = su[:, 0], su[:, 1]
    ddx, ddy = suu[:, 0], suu[:, 1]
    speed = np.hypot(dx, dy)
    curvature = ((dx * ddy - dy * ddx) / speed**3).reshape(k, n_around)
    # arc length per sample: |C'| du
    arc = (speed * (u1 - u0) / n_around).reshape(k, n_around)
    contact = np.zeros((k, n_around), dtype=bool)
    hull_perimeter = np.zeros(k)
    for i in range(k):  # one hull per ring (k ~ 60); everything inside is vectorized
        ring = points[i]
        hull = ConvexHull(ring)
        hull_perimeter[i] = hull.area  # in 2-D, "area" is the perimeter
        contact[i] = _contact(ring, np.sort(hull.vertices))
    nxt = np.roll(points, -1, axis=1)
    perimeter = np.linalg.norm(nxt - points, axis=2).sum(axis=1)
    centroid = points.mean(axis=1)
    rel = points - centroid[:, None, :]
    angle = np.mod(np.arctan2(rel[..., 1], rel[..., 0]), 2 * np.pi)
    return Rings(heights, u, v_of_h, points, z, curvature, arc, contact, hull_perimeter, perimeter, centroid, angle)


def _contact(ring: np.ndarray, hull_vertices: np.ndarray) -> np.ndarray:
    """(n,) bool: ring samples within CONTACT_TOLERANCE_MM of the hull boundary.

    Each sample lies under the hull edge between the hull vertices before and after it
    (in ring order); its distance to that edge's line tells whether the fabric touches.
    """
    n = len(ring)
    index = np.arange(n)
    slot = np.searchsorted(hull_vertices, index, side="right") - 1  # previous hull vertex
    a = hull_vertices[slot % len(hull_vertices)]
    b = hull_vertices[(slot + 1) % len(hull_vertices)]
    pa, pb = ring[a], ring[b]
    edge = pb - pa
    length = np.linalg.norm(edge, axis=1)
    rel = ring - pa
    distance = np.abs(edge[:, 0] * rel[:, 1] - edge[:, 1] * rel[:, 0]) / np.maximum(length, 1e-12)
    return (distance < CONTACT_TOLERANCE_MM) | np.isin(index, hull_vertices)


def local_pressure_pa(rings: Rings, tension_n_per_cm: np.ndarray) -> np.ndarray:
    """(k, n) Laplace pressure T * kappa on the skin, 0 where the fabric bridges, Pa."""
    kappa = np.where(rings.contact, np.maximum(rings.curvature, 0.0), 0.0)
    return PA_PER_N_PER_CM_PER_MM * np.asarray(tension_n_per_cm)[:, None] * kappa


def mean_pressure_pa(rings: Rings, tension_n_per_cm: np.ndarray) -> np.ndarray:
    """(k,) mean pressure around the hull, 2 pi T / L, Pa."""
    return PA_PER_N_PER_CM_PER_MM * 2 * np.pi * np.asarray(tension_n_per_cm) / rings.hull_perimeter


def sector_means(rings: Rings, pressure: np.ndarray, directions: dict[str, float], half_width_deg: float = 10.0) -> dict:
    """Mean local pressure (arc-length weighted) in a sector around each direction.

    directions: name -> angle (radians, calf frame); returns name -> (k,) Pa.  A sensor
    (e.g. the paper's mannequin measurement) reads an area, not a point: +-10 degrees.
    """
    out = {}
    half = np.deg2rad(half_width_deg)
    for name, theta in directions.items():
        delta = np.abs((rings.angle - theta + np.pi) % (2 * np.pi) - np.pi)
        weight = rings.arc * (delta <= half)
        out[name] = (pressure * weight).sum(axis=1) / np.maximum(weight.sum(axis=1), 1e-12)
    return out


def side_directions(side: str | None) -> tuple[dict[str, float], bool]:
    """Medial/lateral/anterior/posterior angles in the calf frame (x = subject's right,
    y = anterior).  Medial points to the body's midline: -x for a right leg, +x for a
    left leg.  Unknown side: a right leg is assumed (second value True)."""
    assumed = side not in ("left", "right")
    medial = 0.0 if side == "left" else np.pi
    return {"medial": medial, "lateral": (medial + np.pi) % (2 * np.pi), "anterior": np.pi / 2, "posterior": 3 * np.pi / 2}, assumed


def sector_name(angle: float, directions: dict[str, float]) -> str:
    names = list(directions)
    diffs = [abs((angle - directions[n] + np.pi) % (2 * np.pi) - np.pi) for n in names]
    return names[int(np.argmin(diffs))]


# -------------------------------------------------------------------- targets


def normalize_class(standard: str, name: str) -> tuple[str, str, tuple]:
    """('RAL', 'II', (23, 32)) from loose spellings: 'ral', 'ccl2', '2', 'II'."""
    key = standard.strip().upper()
    if key not in COMPRESSION_CLASSES:
        raise _design_failure(FailureReason.INVALID_TARGET, f"standard must be one of {', '.join(COMPRESSION_CLASSES)}, not {standard!r}")
    classes = COMPRESSION_CLASSES[key]["classes"]
    raw = str(name).strip().upper().replace("CCL", "").replace("CLASS", "").strip()
    roman = {"1": "I", "2": "II", "3": "III", "4": "IV"}
    arabic = {v: k for k, v in roman.items()}
    for candidate in (raw, roman.get(raw, ""), arabic.get(raw, "")):
        if candidate in classes:
            return key, candidate, classes[candidate]
    raise _design_failure(
        FailureReason.INVALID_TARGET, f"{key} has classes {', '.join(classes)}; {name!r} is not one of them"
    )


def class_target_mmhg(bounds: tuple) -> float:
    lo, hi = bounds
    return lo * OPEN_CLASS_MARGIN if hi is None else (lo + hi) / 2


def gradient_targets(at_b_mmhg: float) -> dict:
    return {"B": at_b_mmhg, **{name: row["target"] * at_b_mmhg for name, row in GRADIENT.items()}}


def validate_targets(targets: dict) -> dict:
    clean = {}
    for name in LANDMARKS:
        if name not in targets:
            raise _design_failure(FailureReason.INVALID_TARGET, f"explicit targets need B, B1, C and D; {name} is missing")
        value = float(targets[name])
        if not np.isfinite(value) or value <= 0:
            raise _design_failure(FailureReason.INVALID_TARGET, f"the target at {name} must be a positive pressure, not {value}")
        if value > 100:
            raise _design_failure(FailureReason.INVALID_TARGET, f"{value:g} mmHg at {name} is beyond any compression class (max 100)")
        clean[name] = value
    return clean


# --------------------------------------------------------------------- design


@dataclass(frozen=True)
class DesignInputs:
    standard: str = "RAL"
    compression_class: str | None = "II"
    targets_mmhg: dict | None = None  # explicit B, B1, C, D; overrides the class
    fabric: Fabric = field(default_factory=lambda: Fabric.linear(10.0))
    hot_spot_limit_mmhg: float = DEFAULT_HOT_SPOT_MMHG
    step_mm: float = 5.0
    resolution_mm: float = 1.0
    n_around: int = 360


def design_stocking(surface: NurbsSurface, landmarks: dict, side: str | None, inputs: DesignInputs) -> dict:
    """The stocking design (see module docstring); a JSON-ready dictionary.

    surface: the calf record's surface; landmarks: name -> {"height_mm", ...} for B, B1,
    C, D; side: "left" | "right" | None.  Raises FitFailure (INVALID_TARGET,
    INVALID_FABRIC, UNREACHABLE_PRESSURE) with the reason.
    """
    for name in LANDMARKS:
        if name not in landmarks:
            raise _design_failure(FailureReason.INVALID_RECORD, f"the record has no landmark {name}; a design needs B, B1, C and D")
    if not (0.5 <= inputs.step_mm <= 50):
        raise _design_failure(FailureReason.INVALID_TARGET, "step_mm must be 0.5-50 mm")
    if not (0.0 < inputs.resolution_mm <= 10):
        raise _design_failure(FailureReason.INVALID_TARGET, "resolution_mm must be in (0, 10] mm")
    if not (5 <= inputs.hot_spot_limit_mmhg <= 300):
        raise _design_failure(FailureReason.INVALID_TARGET, "the hot-spot limit must be 5-300 mmHg")
    inputs.fabric.validate()

    class_info = None
    if inputs.targets_mmhg is not None:
        targets = validate_targets(inputs.targets_mmhg)
    else:
        standard, cls, bounds = normalize_class(inputs.standard, inputs.compression_class or "")
        targets = gradient_targets(class_target_mmhg(bounds))
        class_info = {"standard": standard, "class": cls, "range_mmHg": list(bounds), "source": COMPRESSION_CLASSES[standard]["source"]}

    landmark_z = {name: float(landmarks[name]["height_mm"]) for name in LANDMARKS}
    z = np.array([landmark_z[n] for n in LANDMARKS])
    if np.any(np.diff(z) <= 0):
        raise _design_failure(FailureReason.INVALID_RECORD, "landmark heights must rise B < B1 < C < D")
    grid = np.arange(z[0], z[-1] + 1e-9, inputs.step_mm)
    heights = np.unique(np.round(np.concatenate([grid, z]), 6))
    heights = np.clip(heights, z[0], z[-1])
    rings = surface_rings(surface, heights, inputs.n_around)
    target_mmhg = np.interp(heights, z, [targets[n] for n in LANDMARKS])
    target_pa = target_mmhg * PA_PER_MMHG
    # mean pressure 2 pi T / L  ->  T = P L / (2 pi)
    tension = target_pa * rings.hull_perimeter / (2 * np.pi * PA_PER_N_PER_CM_PER_MM)
    strain = inputs.fabric.strain_for(tension)
    if not np.isfinite(strain).all():
        worst = int(np.nanargmax(np.where(np.isfinite(strain), -np.inf, tension)))
        raise _design_failure(
            FailureReason.UNREACHABLE_PRESSURE,
            f"at {heights[worst]:.0f} mm the target {target_mmhg[worst]:.1f} mmHg needs a tension of "
            f"{tension[worst]:.2f} N/cm, more than the fabric gives within its strain limit "
            f"({inputs.fabric.max_strain:.0%}): the stocking would have to stretch beyond what the fabric "
            "takes without tearing; choose a stiffer fabric or a lower class",
        )
    relaxed = rings.hull_perimeter / (1.0 + strain)
    relaxed_knit = np.round(relaxed / inputs.resolution_mm) * inputs.resolution_mm
    # prediction from the knitted (rounded) specification
    strain_knit = rings.hull_perimeter / relaxed_knit - 1.0
    tension_knit = inputs.fabric.tension(np.maximum(strain_knit, 0.0))
    local = local_pressure_pa(rings, tension_knit)
    mean = mean_pressure_pa(rings, tension_knit)
    directions, side_assumed = side_directions(side)
    sides = sector_means(rings, local, directions)

    index = {name: int(np.argmin(np.abs(heights - landmark_z[name]))) for name in LANDMARKS}
    per_landmark = {}
    for name in LANDMARKS:
        i = index[name]
        per_landmark[name] = {
            "height_mm": float(heights[i]),
            "target_mmHg": float(target_mmhg[i]),
            "mean_pressure_mmHg": float(mean[i] / PA_PER_MMHG),
            "mean_pressure_kPa": float(mean[i] / 1000),
            "peak_pressure_mmHg": float(local[i].max() / PA_PER_MMHG),
            "stretched_circumference_mm": float(rings.hull_perimeter[i]),
            "skin_circumference_mm": float(rings.perimeter[i]),
            "relaxed_circumference_mm": float(relaxed_knit[i]),
            "strain": float(strain_knit[i]),
            "tension_N_per_cm": float(tension_knit[i]),
            "sides_mmHg": {k: float(v[i] / PA_PER_MMHG) for k, v in sides.items()},
            "sides_kPa": {k: float(v[i] / 1000) for k, v in sides.items()},
        }
    p = {name: per_landmark[name]["mean_pressure_mmHg"] for name in LANDMARKS}
    ratios = {f"{n}/B": p[n] / p["B"] for n in ("B1", "C", "D")}
    checks = _checks(p, ratios, class_info)
    hot_spots = find_hot_spots(rings, local, inputs.hot_spot_limit_mmhg * PA_PER_MMHG, directions)
    spec = [
        {
            "height_mm": float(h),
            "target_mmHg": float(t),
            "stretched_circumference_mm": float(L),
            "tension_N_per_cm": float(T),
            "strain": float(e),
            "relaxed_circumference_mm": float(L0),
            "predicted_mean_mmHg": float(m / PA_PER_MMHG),
        }
        for h, t, L, T, e, L0, m in zip(heights, target_mmhg, rings.hull_perimeter, tension_knit, strain_knit, relaxed_knit, mean)
    ]
    return {
        "units": {"length": "mm", "pressure": "mmHg (kPa where named)", "tension": "N/cm"},
        "class": class_info,
        "targets_mmHg": targets,
        "gradient_table": {k: {**v, "range": list(v["range"])} for k, v in GRADIENT.items()},
        "fabric": inputs.fabric.as_dict(),
        "landmarks": per_landmark,
        "ratios": ratios,
        "checks": checks,
        "passed": all(c["pass"] for c in checks if c["normative"]),
        "hot_spot_limit_mmHg": inputs.hot_spot_limit_mmhg,
        "hot_spots": hot_spots,
        "side": side,
        "side_assumed": side_assumed,
        "knitting_spec": spec,
    }


def _checks(p: dict, ratios: dict, class_info: dict | None) -> list[dict]:
    checks = []
    if class_info is not None:
        lo, hi = class_info["range_mmHg"]
        ok = p["B"] >= lo - 1e-9 and (hi is None or p["B"] <= hi + 1e-9)
        label = f"{lo:g}-{hi:g}" if hi is not None else f">= {lo:g}"
        checks.append({"name": f"B in {class_info['standard']} class {class_info['class']} ({label} mmHg)",
                       "value": p["B"], "pass": bool(ok), "normative": True})
    checks.append({"name": "graded B > B1 > C > D", "value": [p[n] for n in LANDMARKS],
                   "pass": bool(p["B"] > p["B1"] > p["C"] > p["D"]), "normative": True})
    for name, row in GRADIENT.items():
        lo, hi = row["range"]
        value = ratios[f"{name}/B"]
        checks.append({"name": f"{name}/B in {lo:.0%}-{hi:.0%} ({row['source']})", "value": value,
                       "pass": bool(lo - 1e-9 <= value <= hi + 1e-9), "normative": row["normative"]})
    return checks


def find_hot_spots(rings: Rings, local_pa: np.ndarray, limit_pa: float, directions: dict[str, float]) -> list[dict]:
    """Connected regions of the (height x angle) grid where local pressure > limit.

    Regions are labelled with scipy.ndimage; a region crossing the angle seam (the first
    and last columns) is one region: labels touching across it are merged.  Peak,
    height extent and size per region come from ndimage reductions.
    """
    above = local_pa > limit_pa
    labels, count = ndimage.label(above)
    if count == 0:
        return []
    parent = np.arange(count + 1)

    def root(label: int) -> int:
        while parent[label] != label:
            label = parent[label]
        return label

    seam = above[:, 0] & above[:, -1]
    for a, b in zip(labels[seam, 0], labels[seam, -1]):  # rows on the seam only
        ra, rb = root(a), root(b)
        parent[max(ra, rb)] = min(ra, rb)
    merged = np.array([root(label) for label in range(count + 1)])[labels]
    ids = np.unique(merged[merged > 0])
    rows = np.broadcast_to(np.arange(local_pa.shape[0])[:, None], local_pa.shape)
    peaks = ndimage.maximum_position(local_pa, merged, ids)
    lowest = ndimage.minimum(rows, merged, ids)
    highest = ndimage.maximum(rows, merged, ids)
    sizes = ndimage.sum(above, merged, ids)
    spots = []
    for (r, c), lo, hi, size in zip(peaks, lowest, highest, sizes):
        angle = float(rings.angle[r, c])
        spots.append({
            "height_mm": float(rings.heights_mm[r]),
            "from_height_mm": float(rings.heights_mm[int(lo)]),
            "to_height_mm": float(rings.heights_mm[int(hi)]),
            "angle_deg": float(np.degrees(angle)),
            "side": sector_name(angle, directions),
            "peak_mmHg": float(local_pa[r, c] / PA_PER_MMHG),
            "peak_kPa": float(local_pa[r, c] / 1000),
            "samples": int(size),
        })
    return sorted(spots, key=lambda spot: -spot["peak_mmHg"])


def pressure_map(surface: NurbsSurface, design: dict, fabric: Fabric, n_around: int = 360) -> tuple[Rings, np.ndarray]:
    """Local pressure (Pa) on a (heights, n_around) grid, from the design's knitting spec.

    Heights every 2.5 mm from B to D; tension interpolated from the spec in height.
    """
    spec = design["knitting_spec"]
    h_spec = np.array([row["height_mm"] for row in spec])
    t_spec = np.array([row["tension_N_per_cm"] for row in spec])
    heights = np.arange(h_spec[0], h_spec[-1] + 1e-9, 2.5)
    rings = surface_rings(surface, heights, n_around)
    return rings, local_pressure_pa(rings, np.interp(heights, h_spec, t_spec))
