"""The order as a PDF (reportlab's platypus, A4): the identity of the case and the
garment, a leg diagram with every measured point at its height, the measurement table
(each point's value or why it has none), the size decision, the warnings and the knitting
specification.  Everything printed comes from the JSON order (:mod:`app.services.orders`):
the two forms cannot disagree.
"""

from __future__ import annotations

import io
import math
from datetime import datetime
from xml.sax.saxutils import escape

from reportlab.graphics.shapes import Drawing, Line, Polygon, PolyLine, String
from reportlab.lib import colors
from reportlab.lib.pagesizes import A4
from reportlab.lib.styles import getSampleStyleSheet
from reportlab.lib.units import mm as MM
from reportlab.platypus import KeepTogether, Paragraph, SimpleDocTemplate, Spacer, Table, TableStyle

from app.services.designs import band_text, foot_text

#: the diagram's box (points) and the drawn leg's scale: 1 mm of leg is SCALE points
DIAGRAM_W, DIAGRAM_H = 70 * MM, 100 * MM
GRID = colors.HexColor("#b8c0cc")
INK = colors.HexColor("#1f2a37")
MARK = colors.HexColor("#c0392b")


def _styles():
    sheet = getSampleStyleSheet()
    return sheet["Title"], sheet["Heading2"], sheet["BodyText"], sheet["Code"]


def _value(m: dict) -> str:
    if m["value_mm"] is None:
        return "not measured"
    if m.get("uncertainty_mm") is not None:  # the warnings say why (a girth, the foot length) or its point's height tolerance
        return f"{m['value_mm']:.1f} mm &plusmn; {m['uncertainty_mm']:.0f}"
    return f"{m['value_mm']:.1f} mm"


def leg_diagram(order: dict) -> Drawing:
    """A front view of the calf from the order's outline (radius = tape girth / 2 pi at
    each height: the diagram shows where the points are, not the leg's true shape), the
    floor when the sole is in the scan, and each measured point as a line across the leg
    labelled with its value."""
    outline = order["leg_outline"]
    heights = [row["height_mm"] for row in outline]
    radii = [row["tape_girth_mm"] / (2 * math.pi) for row in outline]
    floor = order["sole_height_mm"]
    low = floor if floor is not None else heights[0] - 20.0
    high = heights[-1] + 20.0
    scale = min((DIAGRAM_H - 16) / (high - low), (DIAGRAM_W * 0.45) / (2 * max(radii)))
    cx = DIAGRAM_W * 0.3

    def y(height: float) -> float:
        return 8 + (height - low) * scale

    drawing = Drawing(DIAGRAM_W, DIAGRAM_H)
    right = [(cx + r * scale, y(h)) for h, r in zip(heights, radii)]
    left = [(cx - r * scale, y(h)) for h, r in zip(heights, radii)][::-1]
    points = [c for xy in right + left for c in xy]
    drawing.add(Polygon(points, fillColor=colors.HexColor("#e8edf3"), strokeColor=INK, strokeWidth=0.8))
    # below B and above D: the leg goes on (dashed: not modelled by the record)
    for (h0, r0), h1 in (((heights[0], radii[0]), low), ((heights[-1], radii[-1]), high)):
        for sign in (1, -1):
            drawing.add(PolyLine([cx + sign * r0 * scale, y(h0), cx + sign * r0 * scale, y(h1)],
                                 strokeColor=GRID, strokeDashArray=[2, 2], strokeWidth=0.6))
    if floor is not None:
        drawing.add(Line(4, y(floor), DIAGRAM_W - 4, y(floor), strokeColor=INK, strokeWidth=1))
        drawing.add(String(4, y(floor) + 2, "floor", fontSize=6, fillColor=INK))
    by_point = {m["point"]: m for m in order["measurements"]}
    for m in order["measurements"]:
        if not m["needed"] or m["kind"] != "circumference" or m["value_mm"] is None or m["height_mm"] is None:
            continue
        r = m["value_mm"] / (2 * math.pi)
        at = y(m["height_mm"])
        drawing.add(Line(cx - r * scale - 3, at, cx + r * scale + 3, at, strokeColor=MARK, strokeWidth=1))
        length = by_point.get("l" + m["point"][1:])
        label = f"{m['point']} {m['value_mm']:.0f}"
        if length is not None and length["value_mm"] is not None:
            label += f"  l{m['point'][1:]} {length['value_mm']:.0f}"
        drawing.add(String(cx + r * scale + 6, at - 2, label, fontSize=7, fillColor=MARK))
    return drawing


def _identity_table(order: dict, body) -> Table:
    s = order["stocking"]
    klass = (f"{s['standard']} class {s['compression_class']} ({s['class_range_mmHg_at_B'][0]:g}-"
             f"{s['class_range_mmHg_at_B'][1]:g} mmHg at B)" if s["compression_class"] else
             f"explicit targets: {', '.join(f'{k} {v:g}' for k, v in (s['targets_mmHg'] or {}).items())} mmHg")
    issued = order["issued_at"]
    issued = issued.strftime("%Y-%m-%d %H:%M UTC") if isinstance(issued, datetime) else str(issued)
    rows = [
        ("Case reference", order["case_ref"] or "none given"),
        ("Side", (order["side"] or "unknown") + (" (not inferred from the scan: confirm)" if order["side_assumed"] else "")),
        ("Stocking", s["description"]),
        ("Toe", s["toe"]),
        ("Compression", klass),
        ("Fabric", s["fabric_text"]),
        ("Verdict", order["verdict"]),
        ("Record", order["record_id"]),
        ("Design", order["design_id"]),
        ("Issued", issued),
    ]
    table = Table([[Paragraph(f"<b>{escape(k)}</b>", body), Paragraph(escape(str(v)), body)] for k, v in rows],
                  colWidths=[32 * MM, 140 * MM])
    table.setStyle(TableStyle([("VALIGN", (0, 0), (-1, -1), "TOP"), ("LINEBELOW", (0, 0), (-1, -1), 0.25, GRID),
                               ("TOPPADDING", (0, 0), (-1, -1), 1), ("BOTTOMPADDING", (0, 0), (-1, -1), 1)]))
    return table


def _measurement_table(order: dict, small) -> Table:
    rows = [[Paragraph("<b>Point</b>", small), Paragraph("<b>What</b>", small), Paragraph("<b>Value</b>", small)]]
    for m in order["measurements"]:
        if not m["needed"]:
            continue
        what = escape(m["description"]) + (f"<br/><i>{escape(m['reason'])}</i>" if m["reason"] else "")
        rows.append([Paragraph(m["point"], small), Paragraph(what, small), Paragraph(_value(m), small)])
    table = Table(rows, colWidths=[18 * MM, 60 * MM, 22 * MM], repeatRows=1)
    table.setStyle(TableStyle([("VALIGN", (0, 0), (-1, -1), "TOP"), ("LINEBELOW", (0, 0), (-1, -1), 0.25, GRID),
                               ("TOPPADDING", (0, 0), (-1, -1), 1), ("BOTTOMPADDING", (0, 0), (-1, -1), 1)]))
    return table


def _size_text(decision: dict) -> str:
    chart = decision["chart"]
    whose = f"{chart['product']} ({chart['type']}{', EXAMPLE chart' if chart['example'] else ''})"
    if decision["decision"] == "ready_to_wear":
        return f"Ready to wear: size {decision['best']} of {whose} fits every point (fitting: {', '.join(decision['fitting'])})."
    if decision["decision"] == "not_measured":
        return f"No size of {whose} can be confirmed: {', '.join(decision.get('missing') or [])} not measured."
    outside = "; ".join(f"{o['point']} {o['measured_mm']:.1f} mm, {o['excess_mm']:+.1f} mm outside "
                        f"{o['low_mm']:.0f}-{o['high_mm']:.0f}" for o in decision.get("outside") or [])
    return f"Made to measure: no size of {whose} fits every point (nearest {decision.get('nearest')}: {outside})."


def _ends_lines(order: dict) -> list[str]:
    """The foot's and the top band's lines above the knitting table (as the CSV's header
    says them: app.services.designs.foot_text, band_text)."""
    return [f"Foot: {foot_text(order.get('foot'))}.", f"Top band: {band_text(order.get('top_band'))}."]


def _knitting_table(order: dict, small) -> Table:
    columns = [("height_mm", "above B mm", 1), ("target_mmHg", "target mmHg", 1), ("predicted_mean_mmHg", "predicted mmHg", 1),
               ("stretched_circumference_mm", "on leg mm", 1), ("strain", "strain", 3),
               ("tension_N_per_cm", "tension N/cm", 2), ("relaxed_circumference_mm", "relaxed mm", 1)]
    rows = [[Paragraph("<b>part</b>", small)] + [Paragraph(f"<b>{title}</b>", small) for _, title, _ in columns]]
    rows += [[" ".join(str(x) for x in (row.get("part", "leg"), row.get("point") or "") if x).strip()]
             + [f"{row[key]:.{digits}f}" for key, _, digits in columns] for row in order["knitting_spec"]]
    table = Table(rows, repeatRows=1, colWidths=[20 * MM] + [22 * MM] * len(columns))
    table.setStyle(TableStyle([("FONTSIZE", (0, 1), (-1, -1), 7), ("ALIGN", (0, 1), (-1, -1), "RIGHT"),
                               ("LINEBELOW", (0, 0), (-1, 0), 0.5, INK), ("ROWBACKGROUNDS", (0, 1), (-1, -1),
                                                                             [colors.white, colors.HexColor("#f3f5f8")]),
                               ("TOPPADDING", (0, 0), (-1, -1), 0.5), ("BOTTOMPADDING", (0, 0), (-1, -1), 0.5)]))
    return table


def order_pdf(order: dict) -> bytes:
    """The order document (a dict from :func:`app.services.orders.order_document`) as PDF bytes."""
    title, heading, body, _ = _styles()
    small = body.clone("small", fontSize=7.5, leading=9)
    out = io.BytesIO()
    footer_text = f"calf-nurbs order - case {order['case_ref'] or 'none'} - design {order['design_id']}"

    def footer(canvas, doc) -> None:
        canvas.saveState()
        canvas.setFont("Helvetica", 7)
        canvas.drawString(15 * MM, 10 * MM, footer_text)
        canvas.drawRightString(A4[0] - 15 * MM, 10 * MM, f"page {doc.page}")
        canvas.restoreState()

    document = SimpleDocTemplate(out, pagesize=A4, leftMargin=15 * MM, rightMargin=15 * MM, topMargin=14 * MM,
                                 bottomMargin=16 * MM, title=f"Compression stocking order, case {order['case_ref'] or 'none'}",
                                 author="calf-nurbs", subject=order["format"])
    beside = Table([[leg_diagram(order), _measurement_table(order, small)]], colWidths=[DIAGRAM_W + 4 * MM, 104 * MM])
    beside.setStyle(TableStyle([("VALIGN", (0, 0), (-1, -1), "TOP")]))
    story = [
        Paragraph("Made-to-measure compression stocking order", title),
        _identity_table(order, body),
        Spacer(1, 4 * MM),
        KeepTogether([Paragraph("Measurements (RAL-GZ 387 points; tape girths and lengths from the floor)", heading), beside]),
        Paragraph("Ready-to-wear check", heading),
        Paragraph(escape(_size_text(order["size_decision"])), body),
        Paragraph("Warnings", heading),
        *[Paragraph("- " + escape(w), body) for w in order["warnings"]],
        Paragraph(f"Knitting specification ({'foot' if (order.get('foot') or {}).get('designed') else 'B'} to "
                  f"{'G' if order['stocking']['type'] == 'AG' else 'D'})", heading),
        *[Paragraph(escape(line), body) for line in _ends_lines(order)],
        _knitting_table(order, small),
    ]
    document.build(story, onFirstPage=footer, onLaterPages=footer)
    return out.getvalue()
