"""Size charts over HTTP: the shipped example, a chart registered as CSV, a record's
size decision."""

from __future__ import annotations

CSV = """# product: Clinic test knee-high
# type: AD
size,point,min_mm,max_mm
S,cB,190,212
S,cC,320,380
M,cB,205,225
M,cC,340,400
"""


def test_the_example_chart_a_registered_chart_and_a_records_decision(shared_client, fitted_record):
    client = shared_client
    charts = client.get("/api/v1/size-charts").json()
    assert charts[0]["id"] == "example-ansur2-ad" and charts[0]["example"] and "EXAMPLE" in charts[0]["product"]
    assert charts[1]["id"] == "example-ansur2-ag" and charts[1]["example"] and charts[1]["type"] == "AG"
    made = client.post("/api/v1/size-charts", content=CSV, headers={"Content-Type": "text/csv"})
    assert made.status_code == 201, made.text
    chart = made.json()
    assert [s["name"] for s in chart["sizes"]] == ["S", "M"] and chart["sizes"][1]["ranges"]["cC"] == [340.0, 400.0]
    assert client.get(made.headers["location"]).json()["id"] == chart["id"]
    bad = client.post("/api/v1/size-charts", json={"product": "x", "type": "AG", "sizes": [{"name": "S", "ranges": {"cB": [3, 1]}}]})
    assert bad.status_code == 422 and "0 < min < max" in bad.json()["detail"]
    assert bad.json()["code"] == "invalid_size_chart" and bad.json()["title"] == "Invalid size chart"

    record = fitted_record
    tape_b = record["landmarks"]["B"]["tape_girth_mm"]
    decision = client.get(f"/api/v1/records/{record['id']}/size-decision", params={"chart": chart["id"]}).json()
    assert decision["measures_mm"]["cB"] == tape_b
    # the leg's C (about 379 mm) lies in both sizes' cC ranges only if its B does too: whatever the
    # decision, it must agree with the ranges
    for name, checks in decision["checks"].items():
        inside = all(c["excess_mm"] == 0 for c in checks)
        assert (name in decision["fitting"]) == inside
    if decision["decision"] == "made_to_measure":
        assert decision["outside"] and decision["nearest"] in ("S", "M")
    example = client.get(f"/api/v1/records/{record['id']}/size-decision", params={"chart": "example-ansur2-ad"})
    assert example.status_code == 200 and example.json()["decision"] in ("ready_to_wear", "made_to_measure")
    assert client.get(f"/api/v1/records/{record['id']}/size-decision", params={"chart": "nope"}).status_code == 404
