"""The leg model over HTTP: the record carries it, GET .../surface?part=leg exports it
like the calf (meshes in the scan's coordinates, exact CAD in the calf frame), and a
record without one answers 404 saying why."""

from __future__ import annotations

import io

import trimesh

from app.records.surface_codec import parse_surface


def test_the_leg_model_is_exported_like_the_calf(shared_client, fitted_record):
    client, record = shared_client, fitted_record
    leg = record["leg_model"]
    assert leg["range"] == "B-G" and leg["layers_mm"]["G"] == record["chart"]["cG"]["height_mm"]
    assert parse_surface(leg["surface"]).shape[1] == 24  # the open-standard form, read back
    base = f"/api/v1/records/{record['id']}/surface"
    calf = trimesh.load(io.BytesIO(client.get(base, params={"format": "stl"}).content), file_type="stl")
    response = client.get(base, params={"format": "stl", "part": "leg"})
    assert response.status_code == 200 and 'filename="leg-' in response.headers["content-disposition"]
    whole = trimesh.load(io.BytesIO(response.content), file_type="stl")
    # in the scan's coordinates (mm for this STL): the leg model holds the calf and reaches G, 617 mm above B
    assert whole.extents.max() > 1.8 * calf.extents.max() and whole.extents.max() > 550
    assert response.headers["etag"] != client.get(base, params={"format": "stl"}).headers["etag"]
    for fmt, magic in (("step", b"ISO-10303-21"), ("iges", None), ("3dm", None), ("glb", b"glTF")):
        exported = client.get(base, params={"format": fmt, "part": "leg"})
        assert exported.status_code == 200 and len(exported.content) > 1000, fmt
        if magic:
            assert exported.content.startswith(magic)
    # a record without a leg model (one imported from before them) says why
    body = {k: v for k, v in record.items() if k not in ("id", "source", "created_at", "scan_id", "leg_model")}
    imported = client.post("/api/v1/records", json=body)
    assert imported.status_code == 201, imported.text
    missing = client.get(f"/api/v1/records/{imported.json()['id']}/surface", params={"format": "stl", "part": "leg"})
    assert missing.status_code == 404 and missing.json()["code"] == "leg_model_not_found"
    assert "fit the scan again" in missing.json()["detail"]
    assert client.get(base, params={"part": "thigh"}).status_code == 422
