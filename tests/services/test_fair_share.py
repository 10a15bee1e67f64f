"""Per-clinic slots of the upload check pool (app.services.fair_share.CheckGate)."""

from __future__ import annotations

import asyncio

import pytest

from app.errors import TooManyRequests
from app.services.fair_share import CheckGate


def test_a_clinic_waits_for_its_own_slot_and_another_clinic_does_not():
    async def scenario():
        gate = CheckGate(per_tenant=1, wait_s=0.2)
        order = []
        async with gate.slot("clinic-a"):
            async with gate.slot("clinic-b"):  # B is not held by A's running check
                order.append("b")
            with pytest.raises(TooManyRequests) as refused:
                async with gate.slot("clinic-a"):  # A's second check waits, then is refused
                    order.append("a again")
            assert refused.value.code == "too_many_checks" and refused.value.headers["Retry-After"]
        async with gate.slot("clinic-a"):  # the slot is free again once the first check ended
            order.append("a")
        return order

    assert asyncio.run(scenario()) == ["b", "a"]


def test_a_waiting_check_starts_when_its_clinics_slot_frees():
    async def scenario():
        gate = CheckGate(per_tenant=1, wait_s=5.0)
        events = []

        async def check(name: str, seconds: float):
            async with gate.slot("clinic-a"):
                events.append(f"{name} starts")
                await asyncio.sleep(seconds)
                events.append(f"{name} ends")

        await asyncio.gather(check("first", 0.05), check("second", 0.0))
        return events

    assert asyncio.run(scenario()) == ["first starts", "first ends", "second starts", "second ends"]
