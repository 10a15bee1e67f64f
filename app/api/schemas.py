"""Response and request bodies as documented in the OpenAPI document."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from app.geometry.garment.design import (
    DEFAULT_CLASS,
    DEFAULT_HOT_SPOT_MMHG,
    DEFAULT_RESOLUTION_MM,
    DEFAULT_STANDARD,
    DEFAULT_STEP_MM,
    DEFAULT_STOCKING_TYPE,
    DEFAULT_TOE,
)
from app.geometry.garment.fabric import DEFAULT_MAX_STRAIN
from app.records.surface_codec import MAX_CONTROL_MM, MAX_NET

#: a control point's coordinate, mm (calf frame); a weight; a knot
Coordinate = Annotated[float, Field(ge=-MAX_CONTROL_MM, le=MAX_CONTROL_MM)]
Weight = Annotated[float, Field(gt=0, le=1e6)]
Knot = Annotated[float, Field(ge=-1e6, le=1e6)]
Point3 = Annotated[list[Coordinate], Field(min_length=3, max_length=3)]


class Landmark(BaseModel):
    model_config = ConfigDict(allow_inf_nan=False)
    height_mm: float = Field(ge=-MAX_CONTROL_MM, le=MAX_CONTROL_MM, description="calf-frame z; B is 0")
    circumference_mm: float = Field(gt=0, le=10 * MAX_CONTROL_MM, description="perimeter of the scan's section at this height")
    tape_girth_mm: float | None = Field(
        None, gt=0, le=10 * MAX_CONTROL_MM,
        description="perimeter of its convex hull: what a tape measure, ANSUR and the hosiery standards "
        "read (record version 2; absent in version 1)")
    at_scan_edge: bool = Field(
        False, description="B or D was taken at the scan's edge (the scan starts at the ankle minimum or ends "
        "at the knee waist); see warnings")
    height_tolerance_mm: float | None = Field(
        None, ge=0, le=10 * MAX_CONTROL_MM, description="heights within this distance of the landmark have a girth a "
        "tape cannot tell from its own: how sharply the profile places it (absent in records fitted before 2026-12)")
    girth_uncertainty_mm: float | None = Field(
        None, ge=0, le=10 * MAX_CONTROL_MM, description="how far tape_girth_mm may be off where the scan misses an arc "
        "of the skin at this height (a hole, a strip the scanner missed): the gap between the arc's chord and its "
        "tangents; present only beyond an order's 3 mm (then a warning says so)")
    confidence: Literal["high", "medium", "low"] | None = Field(
        None, description="high: tolerance <= 10 mm; medium: <= 25 mm; low: beyond, or taken at the scan's or its "
        "search window's edge (then a warning says why)")


class SideInference(BaseModel):
    side: str | None = Field(description="left | right | null when it could not be told")
    confidence: float | None = Field(None, description="0.5-1 for a side read from the foot")
    source: str | None = Field(None, description="given (the side option) | body (the other leg of the scan) | "
                               "foot (the hallux, arch and malleoli of a single leg) | null")


class Surface(BaseModel):
    """A NURBS tube closed around the leg (checked: its two u ends coincide)."""

    model_config = ConfigDict(allow_inf_nan=False)
    degree_u: int = Field(ge=1, le=5)
    degree_v: int = Field(ge=1, le=5)
    knots_u: list[Knot] = Field(min_length=4, max_length=MAX_NET + 6, description="nu + degree_u + 1 knots; u runs around the leg")
    knots_v: list[Knot] = Field(min_length=4, max_length=MAX_NET + 6, description="nv + degree_v + 1 knots; v runs from B to D")
    control_points: list[Annotated[list[Point3], Field(min_length=2, max_length=MAX_NET)]] = Field(
        min_length=2, max_length=MAX_NET, description="[nu][nv][3], mm, calf frame")
    weights: list[Annotated[list[Weight], Field(min_length=2, max_length=MAX_NET)]] = Field(
        min_length=2, max_length=MAX_NET, description="[nu][nv], all > 0")
    periodic_u: bool = Field(description="closed around the leg: the first degree_u control columns repeat at the end; "
                             "false: a clamped u whose first and last control columns coincide")


class ChartPoint(BaseModel):
    """A point of the order form measured from the scan (mm), or why it is not."""

    model_config = ConfigDict(allow_inf_nan=False)
    value_mm: float | None = Field(None, gt=0, le=1000, description="tape girth (cA, cY) or foot length; null: see reason")
    at_mm: list[Annotated[float, Field(ge=-2000, le=2000)]] | None = Field(
        None, min_length=3, max_length=3, description="where the tape lies (foot) or its section's centre (thigh), calf frame mm")
    height_mm: float | None = Field(None, ge=-2000, le=2000, description="its height (the thigh's points), calf frame mm")
    reason: str | None = Field(None, max_length=500, description="why it is not measured")
    uncertainty_mm: float | None = Field(
        None, ge=0, le=1000, description="how far the girth may be off where the scan leaves the point's place uncertain "
        "(a knee without a level crown, a smooth gluteal fold: the record's warnings say why); absent: within 3 mm")
    height_uncertainty_mm: float | None = Field(
        None, ge=0, le=1000, description="how far the point's height may be off (the thigh's points: E's level stretch, "
        "G's smooth fold, F halfway), mm; its length from the floor says it beyond 10 mm")


class ThighProfile(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    heights_mm: list[Annotated[float, Field(ge=-2000, le=2000)]] = Field(min_length=2, max_length=400)
    tape_girth_mm: list[Annotated[float, Field(gt=0, le=1000)]] = Field(min_length=2, max_length=400)


class RecordChart(BaseModel):
    """The order form's points off the calf (schema version 3), each measured or with the
    reason it is not; with G, the thigh's tape girth profile from D to G."""

    model_config = ConfigDict(extra="forbid")
    foot_length: ChartPoint | None = None
    cA: ChartPoint | None = None
    cY: ChartPoint | None = None
    cE: ChartPoint | None = None
    cF: ChartPoint | None = None
    cG: ChartPoint | None = None
    thigh_profile: ThighProfile | None = Field(None, description="tape girths from D to G (a thigh-high design knits from them)")


class LegModel(BaseModel):
    """The leg's surface from B to G (app.geometry.fit.leg_model), or the reason there is none."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    reason: str | None = Field(None, max_length=500, description="why the record has no leg model (no surface then)")
    range: Literal["B-G"] | None = None
    grid: str | None = Field(None, max_length=16, description="control rows along x columns around")
    layers_mm: dict[Literal["B", "B1", "C", "D", "E", "F", "G"], Annotated[float, Field(ge=-2000, le=2000)]] | None = Field(
        None, description="the heights its v is anchored at (v = k/6), calf frame mm")
    correction_rms_mm: list[float] | None = None
    surface_to_scan: dict | None = Field(None, description="the surface's distance to the scan (as the calf's fit has)")
    surface: Surface | None = Field(None, description="a tube from B (v = 0) to G (v = 1), calf frame mm")


class CalfRecordBody(BaseModel):
    """A calf record (see app.records.codec for every field)."""

    model_config = ConfigDict(extra="allow", allow_inf_nan=False)
    schema_version: Literal[1, 2, 3] = Field(3, description="1, 2 or 3; version 2 adds tape girths, warnings and "
                                             "side_inference, version 3 the chart (the foot's points of the order form)")
    units: Literal["mm"] = "mm"
    side: Literal["left", "right"] | None = None
    side_inference: SideInference | None = None
    warnings: list[str] = Field(default_factory=list, description="what the fit noticed about the scan, in words: "
                                "landmarks at its edge, a floor or spikes removed, pieces ignored, a bent knee")
    surface: Surface
    frame: Annotated[list[Annotated[list[Annotated[float, Field(ge=-1e7, le=1e7)]], Field(min_length=4, max_length=4)]],
                     Field(min_length=4, max_length=4)] = Field(
        description="4x4: calf-frame mm -> the scan's own coordinates and units")
    landmarks: dict[Literal["B", "B1", "C", "D"], Landmark] = Field(default_factory=dict)
    chart: RecordChart | None = Field(
        None, description="version 3: the order form's points off the calf (foot, knee, thigh) measured from the scan")
    leg_model: LegModel | None = Field(
        None, description="version 3: the leg from B to G when the scan reaches the top of the thigh, or why not")
    fit: dict = Field(default_factory=dict)


class RecordOut(CalfRecordBody):
    id: str
    source: str = Field(description="fit | import")
    created_at: datetime
    scan_id: str | None = None
    case_ref: str | None = Field(None, description="the clinic's pseudonymous case id sent with the upload")


class RecordSummary(BaseModel):
    id: str
    source: str
    side: str | None
    case_ref: str | None = None
    error_index: float | None
    created_at: datetime
    landmarks: dict[str, Landmark]
    links: dict[str, str]


class RecordPage(BaseModel):
    items: list[RecordSummary]
    next_cursor: str | None = Field(description="pass as ?cursor= for the next page; null on the last page")


class JobError(BaseModel):
    type: str
    code: str
    title: str
    detail: str


class JobOut(BaseModel):
    id: str
    status: str = Field(description="queued | running | succeeded | failed")
    scan_id: str
    scan_sha256: str
    scan_reused: bool | None = Field(None, description="on upload: the same bytes were already stored")
    options: dict
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    attempts: int
    stage_seconds: dict | None = Field(description="seconds per fitting stage, once succeeded")
    error: JobError | None
    record_id: str | None
    case_ref: str | None = Field(None, description="the case reference sent with the upload")
    warnings: list[str] = Field(default_factory=list, description="the record's warnings, once the job has one: "
                                "what the fit noticed (a given side the foot contradicts, the surface off the skin, "
                                "landmarks at the scan's edge...)")
    links: dict[str, str]


class GirthOut(BaseModel):
    height_mm: float
    circumference_mm: float = Field(description="perimeter of the surface's cross-section")
    tape_circumference_mm: float = Field(description="perimeter of its convex hull (tape measure)")


class LandmarkGirth(GirthOut):
    scan_circumference_mm: float = Field(description="the girth measured on the scan when the record was fitted")
    scan_tape_girth_mm: float | None = Field(None, description="the tape girth measured on the scan (record version 2)")
    at_scan_edge: bool = Field(False, description="the landmark lies at the scan's edge (see warnings)")
    height_tolerance_mm: float | None = Field(None, description="how sharply the scan's profile places the landmark, mm")
    confidence: str | None = Field(None, description="high | medium | low (see the record's landmarks)")


class OrderMeasurement(BaseModel):
    """A measuring point of the order form (RAL-GZ 387) on a record, mm."""

    point: str = Field(description="RAL-GZ 387 letter: cA, cY, cB ... cG (circumferences), lB ... lG (from the floor), foot_length")
    kind: Literal["circumference", "length"]
    description: str
    needed_for: list[Literal["AD", "AG"]] = Field(description="the stocking types whose order form asks for it")
    needed: bool = Field(description="the stocking type in question asks for it (AG for a record's chart)")
    value_mm: float | None = Field(description="tape girth or length from the floor; null when not measured (see reason)")
    height_mm: float | None = Field(description="the point's height in the calf frame (mm), where it is on the leg diagram")
    at_mm: list[float] | None = Field(None, description="where the tape lies (foot) or its section's centre (thigh), calf frame mm")
    reason: str | None = Field(description="why there is no value")
    uncertainty_mm: float | None = Field(None, description="how far the value may be off: a girth where the scan leaves "
                                         "the point's place uncertain (the record's warnings say why; null: within 3 mm), a "
                                         "length where the point's height is (a flat calf crown, a long knee waist, a knee "
                                         "without a level crown, a smooth gluteal fold; null: within 10 mm)")


class MeasurementsOut(BaseModel):
    record_id: str
    units: str
    height_range_mm: list[float]
    landmarks: dict[str, LandmarkGirth]
    heights: list[GirthOut]
    lengths_mm: dict[str, float] = Field(description="height differences along the calf axis between landmarks")
    above_floor_mm: dict[str, float] | None = Field(
        None, description="landmark heights above the sole (the floor of a standing person), when the foot is in the scan")
    chart: list[OrderMeasurement] = Field(default_factory=list, description="the order form's measuring points (RAL-GZ "
                                          "387), each with its value or the reason it has none")
    warnings: list[str] = Field(default_factory=list, description="the record's warnings about its scan")


class Health(BaseModel):
    status: str
    database: str | None = Field(None, description="the database kind (an operator key only)")
    revision: str | None = Field(None, description="the migration revision (an operator key only)")


class UsageOut(BaseModel):
    jobs: dict[str, int] = Field(description="your clinic's jobs by status")
    limits: dict[str, float] = Field(description="the fair-share limits on your clinic: max_active_jobs (queued or "
                                     "running), max_concurrent_checks, uploads_per_minute, requests_per_minute "
                                     "(0: none), max_upload_bytes, max_json_bytes")


#: the most rows of a measured tension-strain table (a tensile tester's curve resampled
#: every 1% of strain up to 200% has 200; more says nothing more about the fabric)
MAX_FABRIC_ROWS = 200
FabricRow = Annotated[list[Annotated[float, Field(ge=0, le=1000)]], Field(min_length=2, max_length=2)]


class FabricIn(BaseModel):
    """A fabric: linear (stiffness_n_per_cm, max_strain) or a measured table - one of the two."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    stiffness_n_per_cm: float | None = Field(None, gt=0, le=1000,
                                             description="linear fabric: tension per unit width per unit strain, N/cm")
    max_strain: float = Field(DEFAULT_MAX_STRAIN, gt=0, le=5,
                              description="linear fabric: the largest strain it may be designed at")
    table: list[FabricRow] | None = Field(
        None, min_length=2, max_length=MAX_FABRIC_ROWS,
        description=f"measured fabric: [[strain, tension N/cm], ...], strictly increasing; 2-{MAX_FABRIC_ROWS} rows")

    @model_validator(mode="after")
    def one_fabric(self):
        if self.table is not None and self.stiffness_n_per_cm is not None:
            raise ValueError("give the fabric as stiffness_n_per_cm or as a table, not both")
        if self.table is None and self.stiffness_n_per_cm is None:
            raise ValueError("give the fabric as stiffness_n_per_cm or as a tension-strain table")
        return self


class DesignRequest(BaseModel):
    """A stocking design: a class (graded by the gradient table) or explicit targets."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    standard: str = Field(DEFAULT_STANDARD, max_length=16, description="RAL (RAL-GZ 387), BS (BS 6612) or AFNOR (NF G30-102)")
    compression_class: str | None = Field(DEFAULT_CLASS, max_length=8, description="e.g. I, II, III, IV (RAL); 1-3 (BS); 1-4 (AFNOR)")
    targets_mmHg: dict[Literal["B", "B1", "C", "D"], Annotated[float, Field(gt=0, le=100)]] | None = Field(
        None, description="explicit mean pressures (0-100 mmHg) at B, B1, C, D; override the class")
    fabric: FabricIn
    hot_spot_limit_mmHg: float = Field(DEFAULT_HOT_SPOT_MMHG, gt=0, le=300,
                                       description="local pressure above this is reported as a hot spot")
    step_mm: float = Field(DEFAULT_STEP_MM, ge=1, le=50, description="knitting specification every step_mm (1-50) from B to D "
                           "(and at the landmarks)")
    resolution_mm: float = Field(DEFAULT_RESOLUTION_MM, ge=0.01, le=10,
                                 description="resolution of the relaxed circumferences L0 (0.01-10 mm)")
    toe: Literal["closed", "open"] = Field(DEFAULT_TOE, description="the stocking's toe, carried to the order")
    stocking_type: Literal["AD", "AG"] = Field(DEFAULT_STOCKING_TYPE, description="AD knee-high (B to D), AG thigh-high "
                                               "(on to G: needs a record whose scan reaches the gluteal fold)")
    top_band_mm: float | None = Field(None, ge=0, le=100, description="the top band's width, mm (default 25 for AD, 50 for AG; "
                                      "0: no band): one relaxed circumference, nowhere tighter than the graded rows it replaces")


class KnittingRow(BaseModel):
    """One knitted row: its part (foot, leg, top band), its measuring point where it has one,
    its height (calf frame mm: the foot's rows lie below B) and what is knitted there."""

    part: Literal["foot", "leg", "top band"] = "leg"
    point: str | None = Field(None, description="cA or cY on the foot; B, B1, C, D, E, F, G on the leg's rows at them")
    height_mm: float
    target_mmHg: float
    stretched_circumference_mm: float = Field(description="the skin's tape girth the fabric spans, mm")
    tension_N_per_cm: float
    strain: float
    relaxed_circumference_mm: float = Field(description="L0, the circumference to knit, mm")
    predicted_mean_mmHg: float = Field(description="what the knitted row gives: 2 pi T / L (Laplace round the hull)")


class DesignOut(BaseModel):
    model_config = ConfigDict(extra="allow")
    id: str
    record_id: str
    case_ref: str | None = Field(None, description="the case reference of the record it was made from")
    created_at: datetime
    inputs: dict
    landmarks: dict
    ratios: dict
    checks: list
    passed: bool = Field(description="every normative check passes (advisory checks and hot spots aside: see verdict)")
    verdict: Literal["pass", "review", "fail"] | None = Field(
        None, description="fail: a normative check fails; review: an advisory check fails or a hot spot exceeds the "
        "limit; pass: every check passes and no hot spot (designs made before 2026-12 have none)")
    verdict_reasons: list[str] | None = Field(None, description="why the verdict is not pass, a sentence each")
    hot_spots: list
    foot: dict | None = Field(None, description="the foot: designed (its toe, foot and knitted lengths, rows at cA and "
                              "cY) or the reason it is not (designs made before 2026-12-03 have none)")
    top_band: dict | None = Field(None, description="the top band (width, heights, relaxed circumference, its pressure "
                                  "against the graded rows'), or null")
    knitting_spec: list[KnittingRow] = Field(description="from the foot to the top, a row each")
    links: dict[str, str]


class OrderStocking(BaseModel):
    type: Literal["AD", "AG"]
    description: str
    toe: Literal["closed", "open"]
    standard: str | None
    compression_class: str | None
    class_range_mmHg_at_B: list[float] | None
    targets_mmHg: dict[str, float] | None
    fabric: dict | None
    fabric_text: str


class OrderOut(BaseModel):
    """A made-to-measure stocking order: what a clinic sends and a manufacturer knits from."""

    format: str
    units: dict[str, str]
    issued_at: datetime
    case_ref: str | None
    record_id: str
    design_id: str
    design_created_at: datetime
    side: Literal["left", "right"] | None
    side_assumed: bool
    stocking: OrderStocking
    measurements: list[OrderMeasurement]
    sole_height_mm: float | None = Field(description="the floor (sole plane) in the calf frame; null without the foot")
    leg_outline: list[dict[str, float]] = Field(description="tape girth at heights from B to D: the leg diagram")
    size_decision: dict
    verdict: Literal["pass", "review", "fail"]
    verdict_reasons: list[str]
    checks: list
    hot_spots: list
    foot: dict | None = None
    top_band: dict | None = None
    knitting_spec: list[KnittingRow]
    warnings: list[str] = Field(description="every warning of the record, the design and the order, a sentence each")


class GirthDifference(BaseModel):
    height_mm: float = Field(description="above the alignment landmark")
    girth_a_mm: float = Field(description="tape girth of record a")
    girth_b_mm: float
    difference_mm: float = Field(description="b - a")


class VolumeChange(BaseModel):
    low_mm: float = Field(description="from this height above the alignment landmark (a's B, or the shared start)")
    high_mm: float = Field(description="to this height (a's D, or the shared end)")
    a_ml: float
    b_ml: float
    change_ml: float = Field(description="b - a")
    change_percent: float


class ComparisonOut(BaseModel):
    record_a: str
    record_b: str
    align: str
    shift_mm: float = Field(description="b's calf-frame z = a's z + shift_mm")
    girths: list[GirthDifference] = Field(description="every 5 mm over the heights both records cover")
    volume: VolumeChange
    largest_girth_change_mm: float | None


class PopulationRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    record_ids: list[Annotated[str, Field(min_length=1, max_length=64)]] = Field(
        min_length=2, max_length=200, description="the records of the population (2-200); records that are not lsq "
        "records on the grid are refitted on their stored scans")
    grid: str | None = Field(None, pattern=r"^[0-9]{1,2}[xX][0-9]{1,2}$",
                             description="lsq grid ALONGxAROUND; default: the lsq records' most common, else 7x15")


class PopulationMode(BaseModel):
    mode: int
    variance_share: float = Field(description="share of the population's total variance")
    sd_mm: float = Field(description="RMS movement of the control points at 1 standard deviation")


class PopulationOut(BaseModel):
    record_id: str = Field(description="the average calf, stored as a record (source 'population')")
    n: int
    grid: str
    modes: list[PopulationMode]
    girth_percentiles: dict[str, dict[str, float]] = Field(description="landmark -> p5, p25, p50, p75, p95 of the tape girths, mm")
    refitted: list[str] = Field(description="records refitted in mode lsq on their stored scans")
    refit_records: dict[str, str] = Field(description="each refitted record -> the lsq record of its scan used")
    mirrored: list[str] = Field(description="left legs mirrored into right legs")
    links: dict[str, str]


class PopulationRefit(BaseModel):
    record_id: str = Field(description="a record of the population that is not an lsq record on the grid")
    job_id: str | None = Field(description="the fit job refitting it in mode lsq on its stored scan; null while it "
                               "waits for room in the clinic's job queue (CALF_TENANT_MAX_JOBS)")
    status: str = Field(description="queued, running, or waiting (no job yet: queued by a later request)")
    links: dict[str, str]


class PopulationRefitting(BaseModel):
    status: str = Field(description="refitting")
    grid: str
    refits: list[PopulationRefit]
    detail: str
    retry_after_s: int = Field(description="seconds to wait before making the same request again")


class ScanPointsOut(BaseModel):
    record_id: str
    frame: str
    n_points: int
    points: list[list[float]] = Field(description="[x, y, z] in the record's calf frame, mm")
    distance_mm: list[float] = Field(description="each point's distance to the surface, mm")
    median_distance_mm: float | None
    max_distance_mm: float | None


class ErasureOut(BaseModel):
    """What an erasure removed (rows per kind, stored files)."""

    scans: int
    jobs: int
    records: int
    designs: int
    idempotency_entries: int = Field(description="stored answers to Idempotency-Key requests that named them")
    files: int = Field(description="stored files deleted: scan files, and the legs the upload check cut out "
                       "of them for jobs that had not run yet")


class SizeChartOut(BaseModel):
    """A ready-to-wear size chart: ranges [min, max] in mm per RAL-GZ 387 point."""

    id: str
    example: bool = Field(description="the shipped example (derived from ANSUR II; not a manufacturer's chart)")
    product: str
    type: str = Field(description="AD knee-high | AG thigh-high")
    source: str
    sizes: list[dict]
    links: dict[str, str]


class PointCheckOut(BaseModel):
    point: str
    measured_mm: float
    low_mm: float
    high_mm: float
    excess_mm: float = Field(description="below the range (negative), above it (positive), 0 inside")


class SizeDecisionOut(BaseModel):
    record_id: str
    chart: dict
    measures_mm: dict[str, float] = Field(description="the record's chart points: tape girths cB..cD, and lengths "
                                          "lB..lD from the floor when the foot is in the scan")
    decision: str = Field(description="ready_to_wear | made_to_measure | not_measured")
    fitting: list[str] = Field(description="the sizes that fit at every point, best first")
    best: str | None
    nearest: str | None = Field(description="the size the leg is nearest to (the best, or the one to compare with)")
    outside: list[PointCheckOut] = Field(description="made to measure: the nearest size's points outside their ranges")
    missing: list[str] = Field(description="points the chart needs that the record does not measure")
    checks: dict[str, list[PointCheckOut]] = Field(description="every size's points against its ranges")
