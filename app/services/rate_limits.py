"""Per-key request rate limits: a token bucket per API key (GCRA-equivalent; Turner's
token bucket, RFC 2697's single-rate form).

A key's bucket holds at most ``burst`` tokens and refills at ``per_minute / 60`` tokens a
second; a request takes one.  An empty bucket answers 429 with ``Retry-After``: the
whole seconds until a token is back.  Uploads have a second, smaller bucket of their own
(a fit costs seconds of a worker; a read costs milliseconds).

The buckets live in this process's memory: a service run as N API processes behind a
balancer admits up to N times the rate per key.  That is a stated trade-off: the limit
protects a process from one client's flood, and the jobs table (not this limit) bounds
the work queued.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass


@dataclass
class _Bucket:
    tokens: float
    stamp: float


class RateLimiter:
    """Token buckets keyed by who asks (a key prefix, or a client address)."""

    def __init__(self, per_minute: float, burst: int, clock=time.monotonic):
        self.rate = per_minute / 60.0  # tokens per second
        self.burst = float(max(burst, 1))
        self.clock = clock
        self._buckets: dict[str, _Bucket] = {}
        self._lock = threading.Lock()

    @property
    def enabled(self) -> bool:
        return self.rate > 0

    def take(self, who: str) -> int:
        """Take a token for ``who``: 0 when the request may go on, else the whole seconds
        (at least 1) until a token is back."""
        if not self.enabled:
            return 0
        now = self.clock()
        with self._lock:
            bucket = self._buckets.get(who)
            if bucket is None:
                bucket = self._buckets[who] = _Bucket(self.burst, now)
            bucket.tokens = min(self.burst, bucket.tokens + (now - bucket.stamp) * self.rate)
            bucket.stamp = now
            if bucket.tokens >= 1.0:
                bucket.tokens -= 1.0
                return 0
            return max(1, math.ceil((1.0 - bucket.tokens) / self.rate))
