"""The order of a design over HTTP: JSON and PDF, what they carry, and their refusals.
The leg is the BodyParts3D right leg (foot to knee: the floor is in the scan)."""

from __future__ import annotations

import io

import pytest

from tests.api.conftest import SHARED_CASE, wait_for_job
from tests.conftest import REAL

pypdf = pytest.importorskip("pypdf", reason="pypdf (the test extra) reads the order PDF back")

CASE = SHARED_CASE


@pytest.fixture(scope="module")
def client(shared_client):
    """The session's service: the order is of its fitted record (tests/api/conftest.py)."""
    return shared_client


@pytest.fixture(scope="module")
def design(client, fitted_record):
    made = client.post(f"/api/v1/records/{fitted_record['id']}/designs",
                       json={"compression_class": "II", "toe": "open", "fabric": {"stiffness_n_per_cm": 10.0}})
    assert made.status_code == 201, made.text
    return made.json()


@pytest.fixture(scope="module")
def order(client, design):
    response = client.get(f"/api/v1/designs/{design['id']}/order")
    assert response.status_code == 200 and response.headers["content-type"].startswith("application/json")
    return response.json()


def test_the_order_carries_the_case_the_garment_and_every_point_of_the_form(client, design, order):
    assert design["case_ref"] == CASE and design["inputs"]["toe"] == "open"
    assert design["links"]["order"] == f"/api/v1/designs/{design['id']}/order"
    record = client.get(f"/api/v1/records/{design['record_id']}").json()
    measured = client.get(f"/api/v1/records/{design['record_id']}/measurements").json()
    assert (order["case_ref"], order["record_id"], order["design_id"]) == (CASE, record["id"], design["id"])
    assert order["side"] == record["side"] == "right"
    stocking = order["stocking"]
    assert (stocking["type"], stocking["toe"], stocking["standard"], stocking["compression_class"]) == ("AD", "open", "RAL", "II")
    assert stocking["class_range_mmHg_at_B"] == design["class"]["range_mmHg"]
    points = {m["point"]: m for m in order["measurements"]}
    # the form's points in its order, each with a value or the reason it has none
    assert list(points)[:6] == ["cA", "cY", "cB", "cB1", "cC", "cD"]
    for name in ("B", "B1", "C", "D"):
        assert points[f"c{name}"]["value_mm"] == record["landmarks"][name]["tape_girth_mm"]
        assert points[f"l{name}"]["value_mm"] == pytest.approx(measured["above_floor_mm"][name], abs=1e-9)
        assert points[f"c{name}"]["height_mm"] == record["landmarks"][name]["height_mm"]
    assert all((m["value_mm"] is None) == (m["reason"] is not None) for m in points.values())
    assert [p for p in ("cE", "cF", "cG", "lE", "lF", "lG") if points[p]["needed"]] == []  # a knee-high stocking
    # the foot is in this scan: its points come from the record's chart (schema version 3)
    assert record["schema_version"] == 3
    for name in ("cA", "cY", "foot_length"):
        assert points[name]["value_mm"] == record["chart"][name]["value_mm"] is not None
    assert [m["point"] for m in order["measurements"] if m["needed"] and m["value_mm"] is None] == []
    # the record's measurement chart (every type's points) agrees with the order's (AD's)
    chart = {m["point"]: m for m in measured["chart"]}
    assert [m["value_mm"] for m in order["measurements"]] == [chart[m["point"]]["value_mm"] for m in order["measurements"]]
    # this leg reaches the hip: the thigh-high points are measured too (an AD order lists, not asks, them)
    assert chart["cG"]["needed_for"] == ["AG"] and chart["cG"]["value_mm"] > chart["cE"]["value_mm"] > 0
    assert chart["lG"]["value_mm"] > chart["lF"]["value_mm"] > chart["lE"]["value_mm"] > chart["lD"]["value_mm"]
    assert chart["cA"]["at_mm"][2] < record["landmarks"]["B"]["height_mm"]  # on the foot, below B
    for name in ("cE", "cF", "cG"):  # the thigh's tapes: their sections' centres, at their heights, over the leg's axis
        assert chart[name]["at_mm"][2] == chart[name]["height_mm"] == record["chart"][name]["at_mm"][2]
        assert abs(chart[name]["at_mm"][0]) < 80 and abs(chart[name]["at_mm"][1]) < 80
    assert not any(w.startswith("not measured from the scan") for w in order["warnings"])
    # the decision and the knitting specification are the ones the API gives on their own
    decision = client.get(f"/api/v1/records/{record['id']}/size-decision", params={"chart": "example-ansur2-ad"}).json()
    assert order["size_decision"] == decision
    assert any("EXAMPLE chart" in w for w in order["warnings"])
    assert order["knitting_spec"] == design["knitting_spec"] and order["verdict"] == design["verdict"]
    if design["verdict"] != "pass":
        assert any(w.startswith(f"the design's verdict is {design['verdict']}") for w in order["warnings"])
    # the leg diagram's outline runs from B to D and agrees with the landmarks' girths at its ends
    outline = order["leg_outline"]
    assert outline[0]["height_mm"] == record["landmarks"]["B"]["height_mm"]
    assert outline[-1]["height_mm"] == pytest.approx(record["landmarks"]["D"]["height_mm"])
    assert outline[0]["tape_girth_mm"] == pytest.approx(measured["landmarks"]["B"]["tape_circumference_mm"], abs=0.5)


def test_the_pdf_prints_what_the_json_says(client, design, order):
    response = client.get(f"/api/v1/designs/{design['id']}/order", headers={"Accept": "application/pdf"})
    assert response.status_code == 200 and response.headers["content-type"] == "application/pdf"
    assert response.content.startswith(b"%PDF-")
    assert f'filename="order-{design["id"][:12]}.pdf"' in response.headers["content-disposition"]
    pdf = pypdf.PdfReader(io.BytesIO(response.content))
    text = "\n".join(page.extract_text() for page in pdf.pages)
    assert CASE in text and design["id"] in text and design["record_id"] in text
    assert "knee-high (AD)" in text and "open" in text and "RAL class II" in text
    for m in order["measurements"]:
        if m["needed"]:
            assert m["point"] in text
            assert (f"{m['value_mm']:.1f} mm" if m["value_mm"] is not None else "not measured") in text
    for warning in order["warnings"]:
        assert warning.split(":")[0][:40] in text.replace("\n", " ")
    # every knitting row is printed: its height and its relaxed circumference
    for row in order["knitting_spec"]:
        assert f"{row['relaxed_circumference_mm']:.1f}" in text
    assert pdf.metadata.title == f"Compression stocking order, case {CASE}"
    # ?format= overrides Accept, and the JSON stays the default
    assert client.get(f"/api/v1/designs/{design['id']}/order", params={"format": "pdf"},
                      headers={"Accept": "application/json"}).headers["content-type"] == "application/pdf"


def test_a_registered_chart_decides_and_the_refusals_say_what_is_wrong(client, design):
    chart = client.post("/api/v1/size-charts", json={"product": "Clinic knee-high", "type": "AD",
                                                     "sizes": [{"name": "S", "ranges": {"cB": [150, 160], "cC": [250, 270]}}]})
    assert chart.status_code == 201, chart.text
    order = client.get(f"/api/v1/designs/{design['id']}/order", params={"chart": chart.json()["id"]}).json()
    decision = order["size_decision"]
    assert decision["chart"]["product"] == "Clinic knee-high" and not decision["chart"]["example"]
    assert decision["decision"] == "made_to_measure" and {o["point"] for o in decision["outside"]} == {"cB", "cC"}
    assert not any("EXAMPLE chart" in w for w in order["warnings"])
    missing_chart = client.get(f"/api/v1/designs/{design['id']}/order", params={"chart": "nope"})
    assert missing_chart.status_code == 404 and missing_chart.json()["code"] == "size_chart_not_found"
    missing_design = client.get("/api/v1/designs/nope/order")
    assert missing_design.status_code == 404 and missing_design.json()["code"] == "design_not_found"
    png = client.get(f"/api/v1/designs/{design['id']}/order", headers={"Accept": "image/png"})
    assert png.status_code == 406 and "application/pdf" in png.json()["detail"]


def test_a_thigh_high_design_and_order_run_on_to_g_and_a_leg_without_its_thigh_is_refused(client, design):
    """The BodyParts3D leg reaches the gluteal fold: an AG design grades on from D to G on
    its thigh girths and its order asks for (and has) cE, cF, cG; the Visible Human
    female's leg is taken below the hips, so AG is refused saying why."""
    made = client.post(f"/api/v1/records/{design['record_id']}/designs",
                       json={"compression_class": "II", "stocking_type": "AG", "fabric": {"stiffness_n_per_cm": 10.0}})
    assert made.status_code == 201, made.text
    ag = made.json()
    record = client.get(f"/api/v1/records/{design['record_id']}").json()
    g = record["chart"]["cG"]["height_mm"]
    assert ag["stocking_type"] == "AG" and set(ag["thigh"]["levels"]) == {"E", "F", "G"}
    spec = [row for row in ag["knitting_spec"] if row["part"] != "foot"]
    heights = [row["height_mm"] for row in spec]
    assert heights == sorted(heights) and heights[-1] == pytest.approx(g) and heights[0] == 0.0
    assert [row["point"] for row in ag["knitting_spec"] if row["part"] == "foot"] == ["cA", "cY"]
    assert ag["top_band"]["width_mm"] == 50 and ag["top_band"]["to_height_mm"] == pytest.approx(g)
    # graded on: the predicted pressure falls from D to G, and each thigh row's mean
    # pressure is Laplace's 2 pi T / L of its knitted row (within rounding of L0)
    d = record["landmarks"]["D"]["height_mm"]
    thigh = [row for row in spec if row["height_mm"] > d and row["part"] == "leg"]  # the graded rows (not the band's)
    assert thigh[0]["predicted_mean_mmHg"] > thigh[-1]["predicted_mean_mmHg"]
    for row in thigh:
        laplace = 2 * 3.141592653589793 * row["tension_N_per_cm"] * 1e5 / row["stretched_circumference_mm"] / 133.322
        assert row["predicted_mean_mmHg"] == pytest.approx(laplace, rel=1e-6)
        assert row["predicted_mean_mmHg"] == pytest.approx(row["target_mmHg"], rel=0.03)
    knitting = client.get(f"/api/v1/designs/{ag['id']}/knitting-spec").text
    assert "# stocking: AG thigh-high, closed toe" in knitting and "# top band: 50 mm wide" in knitting
    # its local pressure map and charts cover the surface, B to D (the thigh has none)
    csv_map = client.get(f"/api/v1/designs/{ag['id']}/pressure-map", params={"format": "csv"})
    assert csv_map.status_code == 200
    map_heights = [float(line.split(",")[0]) for line in csv_map.text.splitlines()[1:]]
    assert max(map_heights) <= d + 1e-6
    for chart in ("profile", "pressure", "map"):
        assert client.get(f"/api/v1/designs/{ag['id']}/charts/{chart}.png").status_code == 200
    names = [c["name"] for c in ag["checks"]]
    assert "graded D > E > F > G" in names and any(n.startswith("G 20%-40% of B") for n in names)
    order = client.get(f"/api/v1/designs/{ag['id']}/order").json()
    assert order["stocking"]["type"] == "AG" and order["stocking"]["description"].startswith("thigh-high")
    assert order["size_decision"]["chart"]["id"] == "example-ansur2-ag"  # the thigh-high example, unless a chart is named
    needed = {m["point"]: m for m in order["measurements"] if m["needed"]}
    assert {"cE", "cF", "cG", "lE", "lF", "lG"} <= set(needed) and all(needed[p]["value_mm"] for p in ("cE", "cF", "cG"))
    assert order["leg_outline"][-1]["height_mm"] == pytest.approx(g)
    pdf = client.get(f"/api/v1/designs/{ag['id']}/order", params={"format": "pdf"})
    assert "Knitting specification (foot to G)" in "".join(p.extract_text() for p in pypdf.PdfReader(io.BytesIO(pdf.content)).pages)

    upload = client.post("/api/v1/scans", content=(REAL / "vh_female_skin.glb").read_bytes(), params={"side": "right"},
                         headers={"Content-Type": "model/gltf-binary"})
    body = wait_for_job(client, upload.headers["location"])
    refused = client.post(f"/api/v1/records/{body['record_id']}/designs",
                          json={"stocking_type": "AG", "fabric": {"stiffness_n_per_cm": 10.0}})
    assert refused.status_code == 422 and refused.json()["code"] == "invalid_target"
    assert "thigh-high (AG) design needs cE, cF and cG from the scan, and cF and cG are not there" in refused.json()["detail"]
    assert "gluteal fold" in refused.json()["detail"]


def test_a_girth_the_scan_leaves_uncertain_is_said_in_the_measurements_the_verdict_and_the_order(client, design):
    """The BodyParts3D record imported with its chart saying cG is uncertain by 6.6 mm (as
    a smooth gluteal fold makes it, app.geometry.anatomy.thigh) and cA by 12.4 and the
    foot length by 14 (a sparse foot, app.geometry.anatomy.foot): its measurements give
    the uncertainties, its thigh-high design is "review" naming cG and cA, and the
    order's table (JSON and PDF) gives them."""
    original = client.get(f"/api/v1/records/{design['record_id']}").json()
    for key in ("id", "source", "created_at", "scan_id"):
        original.pop(key, None)
    original["chart"]["cG"]["uncertainty_mm"] = 6.6
    original["chart"]["cA"]["uncertainty_mm"] = 12.4  # a sparse foot (app.geometry.anatomy.foot_loops)
    original["chart"]["foot_length"]["uncertainty_mm"] = 14.0
    created = client.post("/api/v1/records", json=original)
    assert created.status_code == 201, created.text
    record_id = created.json()["id"]
    try:
        assert created.json()["chart"]["cG"]["uncertainty_mm"] == 6.6
        points = {m["point"]: m for m in client.get(f"/api/v1/records/{record_id}/measurements").json()["chart"]}
        assert points["cG"]["uncertainty_mm"] == 6.6 and points["cE"]["uncertainty_mm"] is None
        assert points["cA"]["uncertainty_mm"] == 12.4 and points["foot_length"]["uncertainty_mm"] == 14.0
        made = client.post(f"/api/v1/records/{record_id}/designs",
                           json={"compression_class": "II", "stocking_type": "AG", "fabric": {"stiffness_n_per_cm": 10.0}})
        assert made.status_code == 201, made.text
        ag = made.json()
        assert ag["verdict"] in ("review", "fail") and any(r.startswith("cG is uncertain by about 7 mm") for r in ag["verdict_reasons"])
        assert any(r.startswith("cA is uncertain by about 12 mm") for r in ag["verdict_reasons"])
        order = client.get(f"/api/v1/designs/{ag['id']}/order").json()
        assert {m["point"]: m for m in order["measurements"]}["cG"]["uncertainty_mm"] == 6.6
        pdf = client.get(f"/api/v1/designs/{ag['id']}/order", params={"format": "pdf"})
        text = "".join(p.extract_text() for p in pypdf.PdfReader(io.BytesIO(pdf.content)).pages)
        assert "± 7" in text and "cG is uncertain" in text and "± 12" in text
    finally:
        assert client.delete(f"/api/v1/records/{record_id}").status_code == 204
