"""The token bucket on a controlled clock."""

from app.services.rate_limits import RateLimiter


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_a_burst_then_one_request_per_refill_interval():
    clock = Clock()
    limiter = RateLimiter(per_minute=60.0, burst=3, clock=clock)  # one token a second
    assert [limiter.take("k") for _ in range(3)] == [0, 0, 0]
    assert limiter.take("k") == 1
    clock.now += 0.5
    assert limiter.take("k") == 1  # half a token back: still wait (rounded up to 1 s)
    clock.now += 0.5
    assert limiter.take("k") == 0
    clock.now += 3600
    assert [limiter.take("k") for _ in range(4)] == [0, 0, 0, 1]  # refills only to the burst


def test_keys_have_their_own_buckets_and_zero_means_no_limit():
    clock = Clock()
    limiter = RateLimiter(per_minute=1.0, burst=1, clock=clock)
    assert limiter.take("a") == 0
    assert limiter.take("a") == 60
    assert limiter.take("b") == 0
    unlimited = RateLimiter(per_minute=0.0, burst=1, clock=clock)
    assert all(unlimited.take("a") == 0 for _ in range(1000))
