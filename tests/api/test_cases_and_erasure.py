"""Case references on uploads and records, and erasure of a scan or a whole case
(app.services.cases, app.services.erasure)."""

from __future__ import annotations

import pytest

from app.errors import Unprocessable
from app.services.cases import validate_case_ref
from tests.api.conftest import wait_for_job
from tests.conftest import REAL

LEG = REAL / "bodyparts3d_right_leg.stl"


@pytest.mark.parametrize("value", ["CASE-0042", "12345678", "k.17_b", "a"])
def test_pseudonymous_case_references_are_kept(value):
    assert validate_case_ref(value) == value


@pytest.mark.parametrize("value", ["Doe Jane", "1961-03-04", "04.03.1961", "-x", "x" * 65, "Müller", "a/b"])
def test_names_dates_and_odd_characters_are_refused_without_repeating_them(value):
    with pytest.raises(Unprocessable) as info:
        validate_case_ref(value)
    assert info.value.code == "invalid_case_ref" and value not in info.value.detail


@pytest.mark.parametrize("method,path,params", [
    ("post", "/api/v1/scans", {"case_ref": "Doe Jane"}),
    ("get", "/api/v1/records", {"case_ref": "Doe Jane"}),
    ("delete", "/api/v1/cases/Doe Jane", {}),
    ("post", "/api/v1/scans", {"case_ref": "1961-03-04"}),
])
def test_a_name_or_a_date_in_any_case_ref_answers_invalid_case_ref_saying_the_form(service_client, method, path, params):
    """Where the parameter's pattern refuses it (a space) as where the service does (a
    date): the code and title of a case reference, the form it must have in words (it
    said "expected another form", code invalid_request), and never the value."""
    answer = getattr(service_client(), method)(path, params=params, **(
        {"content": LEG.read_bytes(), "headers": {"Content-Type": "model/stl"}} if method == "post" else {}))
    problem = answer.json()
    assert answer.status_code == 422 and problem["code"] == "invalid_case_ref", problem
    assert problem["title"] == "Invalid case reference"
    assert "pseudonymous case id" in problem["detail"] and "Doe" not in answer.text and "1961" not in answer.text


def _upload(client, case_ref: str | None, data: bytes, **params) -> dict:
    params = {"points": 8, **params, **({"case_ref": case_ref} if case_ref else {})}
    answer = client.post("/api/v1/scans", content=data, params=params, headers={"Content-Type": "model/stl"})
    assert answer.status_code == 202, answer.text
    job = wait_for_job(client, answer.headers["location"])
    assert job["status"] == "succeeded", job
    return job


def test_a_case_is_listed_and_erased_with_its_scans_records_designs_jobs_and_answers(service_client):
    client = service_client()
    data = LEG.read_bytes()
    job = _upload(client, "CASE-7", data)
    assert job["case_ref"] == "CASE-7"
    record = client.get(f"/api/v1/records/{job['record_id']}").json()
    assert record["case_ref"] == "CASE-7"
    design = client.post(f"/api/v1/records/{record['id']}/designs", json={"fabric": {"stiffness_n_per_cm": 10}},
                         headers={"Idempotency-Key": "design-of-case-7"})
    assert design.status_code == 201, design.text
    # another case: the same leg with another 80-byte binary STL header (other bytes, another scan)
    other = _upload(client, "CASE-8", b"case 8".ljust(80, b"\0") + data[80:])
    listed = client.get("/api/v1/records", params={"case_ref": "CASE-7"}).json()["items"]
    assert [r["id"] for r in listed] == [record["id"]] and listed[0]["case_ref"] == "CASE-7"
    assert client.get("/api/v1/records", params={"case_ref": "Doe Jane"}).status_code == 422

    erased = client.delete("/api/v1/cases/CASE-7")
    assert erased.status_code == 200, erased.text
    assert erased.json() == {"scans": 1, "jobs": 1, "records": 1, "designs": 1, "idempotency_entries": 1, "files": 1}
    assert client.get(f"/api/v1/records/{record['id']}").status_code == 404
    assert client.get(f"/api/v1/jobs/{job['id']}").status_code == 404
    assert client.get(f"/api/v1/designs/{design.json()['id']}").status_code == 404
    assert client.delete("/api/v1/cases/CASE-7").status_code == 404  # nothing left of it
    # the other case is untouched, and the same bytes uploaded again are a new scan
    assert client.get(f"/api/v1/records/{other['record_id']}").status_code == 200
    again = _upload(client, "CASE-7", data)
    assert again["scan_id"] != job["scan_id"] and again["scan_sha256"] == job["scan_sha256"]


def test_erasing_a_scan_removes_its_file_and_everything_made_from_it(service_client, tmp_path):
    client = service_client()
    job = _upload(client, None, LEG.read_bytes())
    stored = list((tmp_path / "scans").rglob(job["scan_sha256"]))
    assert stored, "the scan file is stored under the data folder"
    erased = client.delete(f"/api/v1/scans/{job['scan_id']}")
    assert erased.status_code == 200, erased.text
    report = erased.json()
    assert (report["scans"], report["jobs"], report["records"], report["files"]) == (1, 1, 1, 1)
    assert not any(path.exists() for path in stored)
    assert client.get(f"/api/v1/records/{job['record_id']}").status_code == 404
    missing = client.delete(f"/api/v1/scans/{job['scan_id']}")
    assert missing.status_code == 404 and missing.headers["content-type"].startswith("application/problem+json")


def test_a_scan_another_case_also_used_stays_when_one_case_is_erased(service_client):
    client = service_client()
    data = LEG.read_bytes()
    first, second = _upload(client, "CASE-A", data), _upload(client, "CASE-B", data)
    assert first["scan_id"] == second["scan_id"]  # the same bytes: one stored scan
    erased = client.delete("/api/v1/cases/CASE-A").json()
    assert (erased["scans"], erased["files"], erased["jobs"], erased["records"]) == (0, 0, 1, 1)
    assert client.get(f"/api/v1/records/{second['record_id']}").status_code == 200
    assert client.delete("/api/v1/cases/CASE-B").json()["files"] == 1  # the last case takes the file with it


def test_the_leg_the_check_cut_out_waits_for_its_job_only_and_is_erased_with_it(service_client, tmp_path):
    """app.services.placed_legs: the check's leg is handed to the queued job (and to no
    one else), read and removed by its fit, and erased with a job that never ran."""
    data = LEG.read_bytes()
    waiting = service_client(data_dir=tmp_path / "waiting", run_jobs=False)  # accepts, never fits
    answer = waiting.post("/api/v1/scans", content=data, params={"points": 8}, headers={"Content-Type": "model/stl"})
    assert answer.status_code == 202, answer.text
    queued = answer.json()
    assert [p.name for p in (tmp_path / "waiting" / "placed").iterdir()] == [f"{queued['id']}.npz"]
    refused = waiting.post("/api/v1/scans", content=b"solid nothing\nendsolid nothing\n", headers={"Content-Type": "model/stl"})
    assert refused.status_code == 422
    assert not list((tmp_path / "waiting" / "tmp").iterdir())  # neither upload nor leg left behind
    erased = waiting.delete(f"/api/v1/scans/{queued['scan_id']}").json()
    assert (erased["jobs"], erased["files"]) == (1, 2)  # the scan's file and the job's leg
    assert not list((tmp_path / "waiting" / "placed").iterdir())

    fitting = service_client(data_dir=tmp_path / "fitting")
    job = _upload(fitting, None, data)
    assert fitting.get(f"/api/v1/records/{job['record_id']}").status_code == 200
    assert not list((tmp_path / "fitting" / "placed").iterdir())  # read by the fit and gone
    assert job["stage_seconds"]["calf_frame"] == 0.0  # the fit placed nothing again: it started from the leg
