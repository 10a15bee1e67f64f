"""Prometheus metrics of one service process (served at ``GET /metrics``).

- ``calf_http_request_duration_seconds{method,route,status}``: request latency, by the
  route's template (``/api/v1/records/{record_id}``), never the raw path, so that the
  label set stays small and no id is a label;
- ``calf_upload_check_duration_seconds{outcome}``: the acceptance check of an upload
  (accepted, or the failure reason);
- ``calf_fit_duration_seconds{outcome}``: a fitting job in its worker (succeeded,
  failed);
- ``calf_jobs_total{outcome,reason}``: jobs ended, with the failure reason;
- ``calf_jobs_by_status{status}``: jobs queued and running now (read from the jobs table when
  scraped);
- ``calf_rate_limited_total``: requests refused with 429.

No tenant, key or patient appears in any label.  Each app has its own registry (tests
build many apps in one process).
"""

from __future__ import annotations

from prometheus_client import CONTENT_TYPE_LATEST, CollectorRegistry, Counter, Gauge, Histogram, generate_latest

REQUEST_BUCKETS = (0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0)
FIT_BUCKETS = (0.1, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 30.0, 60.0, 120.0, 300.0, 600.0)


class Metrics:
    content_type = CONTENT_TYPE_LATEST

    def __init__(self) -> None:
        self.registry = CollectorRegistry()
        self.request_seconds = Histogram("calf_http_request_duration_seconds", "HTTP request latency by route template",
                                         ("method", "route", "status"), buckets=REQUEST_BUCKETS, registry=self.registry)
        self.check_seconds = Histogram("calf_upload_check_duration_seconds", "Acceptance check of an uploaded scan",
                                       ("outcome",), buckets=FIT_BUCKETS, registry=self.registry)
        self.fit_seconds = Histogram("calf_fit_duration_seconds", "A fitting job in its worker process",
                                     ("outcome",), buckets=FIT_BUCKETS, registry=self.registry)
        self.jobs_ended = Counter("calf_jobs_total", "Fitting jobs ended", ("outcome", "reason"), registry=self.registry)
        self.jobs_now = Gauge("calf_jobs_by_status", "Fitting jobs by status now", ("status",), registry=self.registry)
        self.rate_limited = Counter("calf_rate_limited_total", "Requests refused with 429", registry=self.registry)

    def job_ended(self, seconds: float, reason: str | None) -> None:
        """A job finished: ``reason`` None for a record, else the failure code."""
        outcome = "succeeded" if reason is None else "failed"
        self.fit_seconds.labels(outcome).observe(seconds)
        self.jobs_ended.labels(outcome, reason or "").inc()

    def render(self, job_counts: dict[str, int]) -> bytes:
        for status in ("queued", "running", "succeeded", "failed"):
            self.jobs_now.labels(status).set(job_counts.get(status, 0))
        return generate_latest(self.registry)
