"""Graduated compression stocking design on the NURBS calf (paper section 4, Laplace's law).

The fabric is :mod:`app.geometry.garment.fabric`, the classes and the gradient
:mod:`app.geometry.garment.standards`, the rings and pressures :mod:`app.geometry.garment.pressure`;
this module turns them into a design.

Model
-----
At height h the stretched fabric follows the *convex hull* of the leg's cross-section (it
bridges concavities).  Its length is the hull perimeter L(h).  With tension per unit width
T(h) = K * eps(h), eps = L / L0 - 1 (L0: the relaxed knitted circumference), the local
pressure on the skin is P = T * kappa, kappa the curvature of the contour where the
fabric touches it and 0 where it bridges.  Because the hull of a smooth closed curve turns
by exactly 2*pi along its contact arcs, the mean pressure around the contour is
2*pi*T / L.  kappa comes from the NURBS surface's own derivatives (The NURBS Book eq.
4.20 via :func:`app.geometry.spline.nurbs.evaluate_derivatives`): for the ring C(u) = S(u, v_h)
in the calf's horizontal plane, kappa = (x' y'' - y' x'') / |C'|^3.

Units: lengths mm, tension N/cm (per cm of fabric width; K in N/cm per unit strain),
pressure Pa internally and reported in mmHg (1 mmHg = 133.322 Pa) and kPa.
T [N/cm] * kappa [1/mm] = 1e5 * T * kappa Pa.

Design
------
Targets: a compression class at B (:data:`app.geometry.garment.standards.COMPRESSION_CLASSES`)
graded down the leg by :data:`app.geometry.garment.standards.GRADIENT`, or explicit pressures at
B, B1, C, D; in between, linear in height.
For every height from B to D (every ``step_mm`` and at the landmarks) the tension that
gives the target mean pressure is T = P * L / (2*pi), the strain comes from the fabric
(linear K, or a measured tension-strain table interpolated by PCHIP, monotone), and
L0 = L / (1 + eps) is the knitting specification, rounded to ``resolution_mm``.  The
prediction is then recomputed from the rounded L0, as the knitted stocking would give.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from app.geometry.anatomy.feature_layers import LANDMARK_NAMES
from app.geometry.errors import FailureReason, FitFailure
from app.geometry.garment.fabric import Fabric
from app.geometry.garment.knitting import KnittingSpec, knit_rows
from app.geometry.garment.measuring_points import THIGH_POINTS
from app.geometry.garment.pressure import (
    PA_PER_MMHG,
    HotSpot,
    find_hot_spots,
    local_pressure_pa,
    mean_pressure_pa,
    sector_means,
    side_directions,
    surface_rings,
)
from app.geometry.garment.standards import (
    COMPRESSION_CLASSES,
    GRADIENT,
    DesignCheck,
    class_target_mmhg,
    gradient_targets,
    normalize_class,
    validate_targets,
)
from app.geometry.garment.stocking_ends import MAX_TOP_BAND_MM, TOES, TOP_BAND_WIDTH_MM, FootOutcome, TopBand, foot_part, top_band
from app.geometry.garment.thigh_design import ThighPart, thigh_part
from app.geometry.scan.skin_layers import SkinLayers
from app.geometry.scan.skin_seam import SkinSeam
from app.geometry.spline.nurbs import NurbsSurface
from app.geometry.spline.skin_distance import SkinDistance

#: Default limit for local pressure hot spots, mmHg.  Partsch et al. (Dermatol Surg 2008;
#: 34:600-609, the consensus on compression pressures) call sub-bandage pressures above
#: 60 mmHg "very strong"; local pressure over tendons and bony prominences beyond that is
#: where the skin-damage risk the paper warns about begins.  Configurable per design.
DEFAULT_HOT_SPOT_MMHG = 60.0
#: the one set of design defaults (the HTTP schema, the CLI and the service read these):
#: RAL-GZ 387 class II (23-32 mmHg at B, the class most prescribed for venous disease),
#: a linear fabric of K = 10 N/cm per unit strain, the knitting specification every 5 mm
#: with the relaxed circumferences to 1 mm
DEFAULT_STANDARD = "RAL"
DEFAULT_CLASS = "II"
DEFAULT_STIFFNESS_N_PER_CM = 10.0
DEFAULT_STEP_MM = 5.0
DEFAULT_RESOLUTION_MM = 1.0
#: the toe when a request names none (the API's default since designs had no toe; the order
#: prints it, so a clinic that wants an open toe says so)
DEFAULT_TOE = "closed"
#: knee-high unless asked: every record has a calf, not every scan a thigh
DEFAULT_STOCKING_TYPE = "AD"
STOCKING_TYPES = ("AD", "AG")


@dataclass(frozen=True)
class LandmarkPressure:
    """The design at one landmark: heights mm above the floor frame's z, the target mmHg,
    predicted pressures Pa (``sides_pa`` per direction: medial, lateral, anterior,
    posterior; mmHg = Pa / :data:`PA_PER_MMHG`), circumferences
    mm (stretched = hull of the skin, skin = the section's own perimeter, relaxed = the
    knitted specification), strain (-) and tension N/cm of the knitted stocking."""

    height_mm: float
    target_mmhg: float
    mean_pressure_pa: float
    peak_pressure_pa: float
    stretched_circumference_mm: float
    skin_circumference_mm: float
    relaxed_circumference_mm: float
    strain: float
    tension_n_per_cm: float
    sides_pa: dict[str, float]

    @property
    def mean_pressure_mmhg(self) -> float:
        return self.mean_pressure_pa / PA_PER_MMHG


@dataclass(frozen=True)
class StockingDesign:
    """A graduated compression stocking designed on a calf record (module docstring).

    ``compression_class`` is None for explicit targets, else {"standard", "class",
    "range_mmHg", "source"}; ``targets_mmhg`` B, B1, C, D; ``ratios`` "B1/B", "C/B",
    "D/B" of the predicted mean pressures.  Its JSON form is shaped by the service
    (:func:`app.services.designs.design_document`).
    """

    compression_class: dict | None
    targets_mmhg: dict[str, float]
    fabric: Fabric
    landmarks: dict[str, LandmarkPressure]
    ratios: dict[str, float]
    checks: tuple[DesignCheck, ...]
    hot_spots: tuple[HotSpot, ...]
    hot_spot_limit_mmhg: float
    side: str | None
    side_assumed: bool
    knitting_spec: KnittingSpec  # the graded rows: B to D, and on to G for a thigh-high
    thigh: ThighPart | None = None  # a thigh-high's part above D
    #: the foot's rows from cA and cY, or why not (app.geometry.garment.stocking_ends)
    foot: FootOutcome = FootOutcome(None, "no foot was designed")
    top_band: TopBand | None = None  # the band at the top, replacing the graded rows under it
    #: what this stocking is graded from that the scan leaves uncertain, a sentence each:
    #: a thigh point whose girth is uncertain by more than an order's tolerance (the
    #: chart's uncertainty_mm), the calf surface standing off the scan's skin
    uncertain_inputs: tuple[str, ...] = ()

    @property
    def stocking_type(self) -> str:
        return "AG" if self.thigh is not None else "AD"

    @property
    def passed(self) -> bool:
        """Every normative check passes (hot spots and advisory checks aside)."""
        return all(c.passed for c in self.checks if c.normative)

    @property
    def verdict(self) -> tuple[str, list[str]]:
        """(verdict, reasons): see :func:`design_verdict`."""
        incomplete = [] if self.foot.part is not None else [f"the foot is not in the knitting specification: {self.foot.reason}"]
        return design_verdict(self.checks, self.hot_spots, self.hot_spot_limit_mmhg, incomplete + list(self.uncertain_inputs))


def design_verdict(checks, hot_spots, limit_mmhg: float, incomplete: list[str] | None = None) -> tuple[str, list[str]]:
    """The verdict a clinician reads first: "fail" when a normative check of the standard
    fails; "review" when only an advisory check (the commonly cited, not normative,
    gradient rows) fails, local pressure somewhere exceeds the hot-spot limit or a part of
    the stocking could not be specified from the scan, or only from a girth it leaves
    uncertain (``incomplete``, a sentence each: the foot without cA or cY; a thigh-high's
    cG at a smooth gluteal fold); "pass" only when every check passes, no hot spot is
    found and the stocking is specified from the foot to the top from sure girths.  With the reasons, each a
    sentence naming the check or where the hot spot is (height above B, side, peak)."""
    reasons = [f"{c.name}: fails (normative)" for c in checks if not c.passed and c.normative]
    verdict = "fail" if reasons else "pass"
    advisory = [f"{c.name}: outside (advisory)" for c in checks if not c.passed and not c.normative]
    spots = [f"local pressure {s.peak_mmhg:.1f} mmHg above the {limit_mmhg:g} mmHg limit at {s.height_mm:.0f} mm "
             f"above B ({s.from_height_mm:.0f}-{s.to_height_mm:.0f} mm), {s.side}" for s in hot_spots]
    missing = list(incomplete or [])
    if verdict == "pass" and (advisory or spots or missing):
        verdict = "review"
    return verdict, reasons + advisory + spots + missing


@dataclass(frozen=True)
class DesignInputs:
    standard: str = DEFAULT_STANDARD
    compression_class: str | None = DEFAULT_CLASS
    targets_mmhg: dict | None = None  # explicit B, B1, C, D; overrides the class
    fabric: Fabric = field(default_factory=lambda: Fabric.linear(DEFAULT_STIFFNESS_N_PER_CM))
    hot_spot_limit_mmhg: float = DEFAULT_HOT_SPOT_MMHG
    step_mm: float = DEFAULT_STEP_MM
    resolution_mm: float = DEFAULT_RESOLUTION_MM
    toe: str = DEFAULT_TOE  # "closed" | "open": the stocking's foot (the order carries it)
    stocking_type: str = DEFAULT_STOCKING_TYPE  # "AD" knee-high, "AG" thigh-high (app.geometry.garment.thigh_design)
    #: the top band's width, mm (None: the type's usual, stocking_ends.TOP_BAND_WIDTH_MM; 0: none)
    top_band_mm: float | None = None
    n_around: int = 360


def design_stocking(surface: NurbsSurface, landmarks: dict, side: str | None, inputs: DesignInputs,
                    chart: dict | None = None, fit: dict | None = None) -> StockingDesign:
    """The stocking design (see module docstring).

    surface: the calf record's surface; landmarks: name -> {"height_mm", ...} for B, B1,
    C, D; side: "left" | "right" | None; chart: the record's points off the calf (schema
    version 3), which a thigh-high (``inputs.stocking_type`` "AG") needs: cE, cF, cG and
    the thigh profile; fit: the record's ``fit`` (what the fit noticed), of which the
    design reads four entries, each making it "review": ``surface_to_scan`` (the surface
    -> scan distances, app.geometry.spline.skin_distance.SkinDistance.as_dict: a surface
    standing off the skin over an arc of a ring), ``skin_layers``
    (app.geometry.scan.skin_layers.SkinLayers.as_dict: a cloud holding the skin twice),
    ``skin_seam`` (app.geometry.scan.skin_seam.SkinSeam.as_dict: a cloud whose skin steps
    along a line up the calf, the leg moved between the scan's parts) and,
    for a thigh-high, ``sparse_points_per_mm`` (a cloud too sparse for thin slabs: its
    thigh's points and G may be off).  An entry of another form (an imported record's) is
    no reason.
    Raises FitFailure (INVALID_TARGET, INVALID_FABRIC,
    UNREACHABLE_PRESSURE) with the reason.
    """
    if inputs.stocking_type not in STOCKING_TYPES:
        raise FitFailure(FailureReason.INVALID_TARGET, f"stocking_type must be one of {', '.join(STOCKING_TYPES)}")
    noticed = fit if isinstance(fit, dict) else {}
    thigh_chart = _thigh_chart(chart) if inputs.stocking_type == "AG" else None
    for name in LANDMARK_NAMES:
        if name not in landmarks:
            raise FitFailure(FailureReason.INVALID_RECORD, f"the record has no landmark {name}; a design needs B, B1, C and D")
    if not (0.5 <= inputs.step_mm <= 50):
        raise FitFailure(FailureReason.INVALID_TARGET, "step_mm must be 0.5-50 mm")
    if not (0.0 < inputs.resolution_mm <= 10):
        raise FitFailure(FailureReason.INVALID_TARGET, "resolution_mm must be in (0, 10] mm")
    if not (5 <= inputs.hot_spot_limit_mmhg <= 300):
        raise FitFailure(FailureReason.INVALID_TARGET, "the hot-spot limit must be 5-300 mmHg")
    if inputs.toe not in TOES:
        raise FitFailure(FailureReason.INVALID_TARGET, f"toe must be one of {', '.join(TOES)}")
    band_mm = TOP_BAND_WIDTH_MM[inputs.stocking_type] if inputs.top_band_mm is None else float(inputs.top_band_mm)
    if not (0.0 <= band_mm <= MAX_TOP_BAND_MM):
        raise FitFailure(FailureReason.INVALID_TARGET, f"top_band_mm must be 0-{MAX_TOP_BAND_MM:g} mm (0: no band)")
    inputs.fabric.validate()

    class_info = None
    if inputs.targets_mmhg is not None:
        targets = validate_targets(inputs.targets_mmhg)
    else:
        standard, cls, bounds = normalize_class(inputs.standard, inputs.compression_class or "")
        targets = gradient_targets(class_target_mmhg(bounds))
        class_info = {"standard": standard, "class": cls, "range_mmHg": list(bounds), "source": COMPRESSION_CLASSES[standard]["source"]}

    landmark_z = {name: float(landmarks[name]["height_mm"]) for name in LANDMARK_NAMES}
    z = np.array([landmark_z[n] for n in LANDMARK_NAMES])
    if np.any(np.diff(z) <= 0):
        raise FitFailure(FailureReason.INVALID_RECORD, "landmark heights must rise B < B1 < C < D")
    grid = np.arange(z[0], z[-1] + 1e-9, inputs.step_mm)
    heights = np.unique(np.round(np.concatenate([grid, z]), 6))
    heights = np.clip(heights, z[0], z[-1])
    rings = surface_rings(surface, heights, inputs.n_around)
    target_mmhg = np.interp(heights, z, [targets[n] for n in LANDMARK_NAMES])
    knitted = knit_rows(heights, target_mmhg, rings.hull_perimeter, inputs.fabric, inputs.resolution_mm)
    relaxed_knit, strain_knit, tension_knit = knitted.relaxed_mm, knitted.strain, knitted.tension_n_per_cm
    local = local_pressure_pa(rings, tension_knit)
    mean = mean_pressure_pa(rings, tension_knit)
    directions, side_assumed = side_directions(side)
    sides = sector_means(rings, local, directions)

    index = {name: int(np.argmin(np.abs(heights - landmark_z[name]))) for name in LANDMARK_NAMES}
    per_landmark = {
        name: LandmarkPressure(
            height_mm=float(heights[i]),
            target_mmhg=float(target_mmhg[i]),
            mean_pressure_pa=float(mean[i]),
            peak_pressure_pa=float(local[i].max()),
            stretched_circumference_mm=float(rings.hull_perimeter[i]),
            skin_circumference_mm=float(rings.perimeter[i]),
            relaxed_circumference_mm=float(relaxed_knit[i]),
            strain=float(strain_knit[i]),
            tension_n_per_cm=float(tension_knit[i]),
            sides_pa={k: float(v[i]) for k, v in sides.items()},
        )
        for name, i in index.items()
    }
    p = {name: per_landmark[name].mean_pressure_mmhg for name in LANDMARK_NAMES}
    ratios = {f"{n}/B": p[n] / p["B"] for n in ("B1", "C", "D")}
    checks = _checks(p, ratios, class_info)
    spec = KnittingSpec(heights, target_mmhg, rings.hull_perimeter, tension_knit, strain_knit, relaxed_knit, mean)
    thigh = None
    if thigh_chart is not None:
        profile, levels = thigh_chart
        thigh = thigh_part(np.asarray(profile["heights_mm"]), np.asarray(profile["tape_girth_mm"]), levels,
                           targets["B"], p["D"], inputs.fabric, inputs.step_mm, inputs.resolution_mm)
        checks += thigh.checks
        spec = spec.joined(thigh.rows)
    if band_mm > 0.5 * float(spec.heights_mm[-1] - spec.heights_mm[0]):
        raise FitFailure(FailureReason.INVALID_TARGET, f"a top band of {band_mm:g} mm is more than half the stocking's "
                                                       f"graded length ({spec.heights_mm[-1] - spec.heights_mm[0]:.0f} mm)")
    return StockingDesign(
        compression_class=class_info,
        targets_mmhg=targets,
        fabric=inputs.fabric,
        landmarks=per_landmark,
        ratios=ratios,
        checks=tuple(checks),
        hot_spots=tuple(find_hot_spots(rings, local, inputs.hot_spot_limit_mmhg * PA_PER_MMHG, directions)),
        hot_spot_limit_mmhg=inputs.hot_spot_limit_mmhg,
        side=side,
        side_assumed=side_assumed,
        knitting_spec=spec,
        thigh=thigh,
        foot=foot_part(chart, targets["B"], inputs.toe, inputs.fabric, inputs.resolution_mm),
        top_band=top_band(spec, band_mm, inputs.fabric),
        uncertain_inputs=_uncertain_landmarks(landmarks)
        + _uncertain_points(chart, ("cA", "cY") + (THIGH_POINTS if thigh is not None else ())) + _off_skin(noticed.get("surface_to_scan"))
        + _doubled_skin(noticed.get("skin_layers"))
        + _stepped_skin(noticed.get("skin_seam"))
        + _sparse_thigh(noticed.get("sparse_points_per_mm"), thigh is not None),
    )


def _off_skin(skin: dict | None) -> tuple[str, ...]:
    """The sentence for a calf surface that stands off the scan's skin over an arc of a
    ring (the fit's own warning, :attr:`SkinDistance.off_skin`): the rings the stocking
    is knitted from are not the leg's there."""
    distances = SkinDistance.from_dict(skin)
    if distances is None or not distances.off_skin:
        return ()
    return (f"the calf surface {distances.off_skin_text}: the girths the stocking is knitted from are not the leg's "
            "there; check the fit, or take that girth by tape",)


def _doubled_skin(skin_layers: dict | None) -> tuple[str, ...]:
    """The sentence for a record fitted from a cloud holding the skin twice (the fit's own
    warning, :attr:`SkinLayers.doubled`): its girths may read wide by up to twice the
    layers' separation, and the stocking would be knitted loose by as much."""
    layers = SkinLayers.from_dict(skin_layers)
    if layers is None or not layers.doubled:
        return ()
    return (f"{layers.doubled_text}; the stocking is knitted from these girths: take B, C and D by tape before "
            "ordering",)


def _stepped_skin(skin_seam: dict | None) -> tuple[str, ...]:
    """The sentence for a record fitted from a cloud whose skin steps along a line up the
    calf (the fit's own warning, :attr:`SkinSeam.moved`): the leg moved between the parts
    of the scan, its girths may read off by up to about twice the move, and the stocking
    would be knitted loose or tight by as much."""
    seam = SkinSeam.from_dict(skin_seam)
    if seam is None or not seam.moved:
        return ()
    return (f"{seam.moved_text}; the stocking is knitted from these girths: take B, C and D by tape before ordering",)


def _sparse_thigh(points_per_mm: object, thigh_high: bool) -> tuple[str, ...]:
    """The sentence for a thigh-high from a cloud too sparse for thin slabs (the fit's own
    warning): a body's 6.5k vertices read cE, cF, cG 3-5 mm off and, on one generated leg,
    G 150 mm low (benchmarks/chart_accuracy.py, body_vertices) - the thigh is knitted from
    them.  ``points_per_mm`` not a positive number (none, or an imported record's own
    entry): no sentence."""
    if isinstance(points_per_mm, bool) or not isinstance(points_per_mm, (int, float)) or not thigh_high:
        return ()
    if not (np.isfinite(points_per_mm) and points_per_mm > 0):
        return ()
    return (f"the scan is a sparse cloud ({points_per_mm:.1f} points per mm of the calf's height): its thigh's girths "
            "and the gluteal fold G may be off; take cE, cF, cG and lG by tape (RAL-GZ 387) before knitting",)


def _by_tape(name: str, why: str) -> str:
    """The review reason for a point whose girth the record cannot stand behind: ``why``,
    then what to do (RAL-GZ 387: take it by tape)."""
    return f"{name} {why}: take {name} by tape (RAL-GZ 387) before knitting"


def _uncertain_landmarks(landmarks: dict) -> tuple[str, ...]:
    """A sentence for each of B, B1, C, D whose tape girth the record says may be off
    (its ``girth_uncertainty_mm``: the scan misses an arc of the skin there,
    app.geometry.placement.coverage): the stocking's pressure there is graded from it."""
    return tuple(_by_tape(f"c{name}", f"may be off by up to {uncertainty:.0f} mm (the scan misses an arc of the skin "
                                      "there; the record's warnings say where)")
                 for name in LANDMARK_NAMES
                 if (uncertainty := (landmarks.get(name) or {}).get("girth_uncertainty_mm")) is not None)


def _uncertain_points(chart: dict | None, names: tuple[str, ...]) -> tuple[str, ...]:
    """A sentence for each of ``names`` whose girth the record's chart says is uncertain
    (its ``uncertainty_mm``, set beyond an order's 3 mm by app.geometry.anatomy.thigh, and by
    app.geometry.anatomy.foot where a sparse loop leaves cA or cY short)."""
    return tuple(_by_tape(name, f"is uncertain by about {uncertainty:.0f} mm (the record's warnings say why)")
                 for name in names
                 if (uncertainty := ((chart or {}).get(name) or {}).get("uncertainty_mm")) is not None)


def _thigh_chart(chart: dict | None) -> tuple[dict, dict[str, float]]:
    """The thigh profile and the heights of E, F, G a thigh-high needs, or FitFailure
    INVALID_TARGET saying what the record lacks (a bent knee, a scan below the hips)."""
    chart = chart or {}
    missing = [name for name in ("cE", "cF", "cG") if (chart.get(name) or {}).get("value_mm") is None]
    if missing or not chart.get("thigh_profile"):
        reasons = sorted({str(r) for name in missing if (r := (chart.get(name) or {}).get("reason"))})
        why = "; ".join(reasons) if reasons else "the record has no thigh measurements (fitted before 2026-12-02)"
        if len(missing) > 1:
            lacking = f"{', '.join(missing[:-1])} and {missing[-1]} are"
        else:
            lacking = f"{missing[0] if missing else 'the thigh profile'} is"
        raise FitFailure(FailureReason.INVALID_TARGET,
                         f"a thigh-high (AG) design needs cE, cF and cG from the scan, and {lacking} not there: {why}")
    return chart["thigh_profile"], {name[1]: float(chart[name]["height_mm"]) for name in ("cE", "cF", "cG")}


def _checks(p: dict, ratios: dict, class_info: dict | None) -> list[DesignCheck]:
    checks = []
    if class_info is not None:
        lo, hi = class_info["range_mmHg"]
        ok = p["B"] >= lo - 1e-9 and (hi is None or p["B"] <= hi + 1e-9)
        label = f"{lo:g}-{hi:g}" if hi is not None else f">= {lo:g}"
        checks.append(DesignCheck(f"B in {class_info['standard']} class {class_info['class']} ({label} mmHg)",
                                  p["B"], bool(ok), True))
    checks.append(DesignCheck("graded B > B1 > C > D", [p[n] for n in LANDMARK_NAMES],
                              bool(p["B"] > p["B1"] > p["C"] > p["D"]), True))
    for name, row in GRADIENT.items():
        lo, hi = row["range"]
        value = ratios[f"{name}/B"]
        checks.append(DesignCheck(f"{name}/B in {lo:.0%}-{hi:.0%} ({row['source']})", value,
                                  bool(lo - 1e-9 <= value <= hi + 1e-9), row["normative"]))
    return checks
