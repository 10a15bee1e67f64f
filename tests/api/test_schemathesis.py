"""The committed OpenAPI document (openapi/openapi.json) against the service as deployed:
Schemathesis generates requests for every operation, sends them to `calf-nurbs serve`
(auth required, a real key), and runs all of its checks on every response: no 5xx, and
status, headers, media type and body as documented.

Bounded: CALF_SCHEMATHESIS_EXAMPLES cases per operation (default 20), derandomized so a
run is repeatable.  The stateful phase chains calls along the links Schemathesis infers
from the document (a record's id from an import or a population into its measurements,
designs, surface, deletion...): CALF_SCHEMATHESIS_SEQUENCES sequences (default 15).  Path ids are, for half of the cases, those of a real record, design
and job of the key's clinic, so that the success responses are checked too, not only
the 404s of random ids.
"""

from __future__ import annotations

import os
from pathlib import Path

import httpx
import pytest

schemathesis = pytest.importorskip("schemathesis", reason="schemathesis is a test extra: pip install -e '.[test]'")
from hypothesis import HealthCheck, settings  # noqa: E402

from app.services.uploads import MEDIA_TYPES  # noqa: E402
from benchmarks.served import served_with_key  # noqa: E402
from tests.api.test_processes import fit_one  # noqa: E402

#: end to end and slow: `make test-slow` (and .ci/run) runs it, `make test` does not
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = int(os.environ.get("CALF_SCHEMATHESIS_EXAMPLES", "20"))
#: call sequences of the stateful phase (each up to STATEFUL_STEPS calls)
STATEFUL_EXAMPLES = int(os.environ.get("CALF_SCHEMATHESIS_SEQUENCES", "15"))
STATEFUL_STEPS = 6
#: operations whose 422 answers content that a JSON schema cannot judge: a scan's bytes
#: (is it a leg?), a record's geometry (a knot vector with a domain, a closed tube), a
#: design's physics (can the fabric reach the pressure?).  Schemathesis's positive-data
#: check then accepts the documented 422 for them; every other check runs unchanged.
#: An upload may also answer 415 (a raw application/octet-stream body needs ?format=, a
#: rule between the body's media type and a parameter that OpenAPI cannot state) and 400
#: (an empty body: Schemathesis does not apply minLength to binary strings).  A page
#: cursor is opaque: only the ones the service issued are valid (400 invalid_cursor).
SEMANTIC_STATUSES = {"POST /api/v1/scans": ("400", "415", "422"), "POST /api/v1/records": ("422",),
                     "POST /api/v1/records/{record_id}/designs": ("422",), "GET /api/v1/records": ("400", "422"),
                     # duplicate ids, records that cannot be refitted, a grid out of bounds
                     "POST /api/v1/populations": ("422",),
                     # two different legs, calves that share too little once aligned
                     "GET /api/v1/records/{record_a}/compare/{record_b}": ("422",),
                     # a chart's cross-field rules (min < max, unique size names) and a CSV
                     # body's table (its columns are content, not schema)
                     "POST /api/v1/size-charts": ("400", "422")}
CONFIG = "\n".join(
    f'[[operations]]\ninclude-name = "{name}"\n[operations.checks.positive_data_acceptance]\n'
    f'expected-statuses = {["2xx", "401", "403", "404", "409", "429", *statuses]!r}\n'.replace("'", '"')
    for name, statuses in SEMANTIC_STATUSES.items())
#: the scan media types are bytes on the wire, as application/octet-stream is
schemathesis.serializer.alias([m for m in MEDIA_TYPES if m != "text/csv"], "application/octet-stream")
schema = schemathesis.openapi.from_path(ROOT / "openapi" / "openapi.json", config=schemathesis.config.SchemathesisConfig.from_str(CONFIG))


@pytest.fixture(scope="module")
def deployed(tmp_path_factory):
    """(base URL, auth headers, real ids) of a served instance with one fitted record."""
    with served_with_key(tmp_path_factory.mktemp("schemathesis") / "var", "fuzz") as (base, key):
        auth = {"Authorization": f"Bearer {key}"}
        job = fit_one(base, auth)
        assert job["status"] == "succeeded", job
        design = httpx.post(f"{base}/api/v1/records/{job['record_id']}/designs", headers=auth, timeout=60,
                            json={"compression_class": "II", "fabric": {"stiffness_n_per_cm": 10}})
        assert design.status_code == 201, design.text
        ids = {"record_id": job["record_id"], "job_id": job["id"], "design_id": design.json()["id"]}
        yield base, auth, ids


@schema.parametrize()
@settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
          suppress_health_check=list(HealthCheck))
def test_every_operation_keeps_its_contract(case, deployed):
    base, auth, ids = deployed
    if case.path_parameters and len(str(next(iter(case.path_parameters.values())))) % 2 == 0:
        case.path_parameters = {name: ids.get(name, value) for name, value in case.path_parameters.items()}
    case.call_and_validate(base_url=base, headers=auth, timeout=60)


def test_call_sequences_keep_their_contract(deployed):
    """The stateful phase: sequences of calls linked by the ids one answer gives the next."""
    base, auth, _ = deployed

    class Sequences(schema.as_state_machine()):
        def get_call_kwargs(self, case):
            return {"base_url": base, "headers": auth, "timeout": 60}

    Sequences.run(settings=settings(max_examples=STATEFUL_EXAMPLES, stateful_step_count=STATEFUL_STEPS, deadline=None,
                                    derandomize=True, database=None, suppress_health_check=list(HealthCheck)))
