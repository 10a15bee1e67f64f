"""The ``Idempotency-Key`` header of uploads and design creation (see
app.services.idempotency for the rules)."""

from __future__ import annotations

import json
from collections.abc import Awaitable, Callable

from fastapi import Header, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse
from sqlalchemy.orm import Session

from app.api.problems import problems
from app.services.idempotency import KEY_PATTERN, IdempotencyService, Replay, Stage, fingerprint
from app.services.keys import Principal

KEY_DESCRIPTION = ("a unique key (a UUID) of this request: a retry with the same key and content gets the first "
                   "response again instead of doing the work twice; the same key with other content answers 409")
IDEMPOTENCY_PROBLEMS = problems(
    s409="idempotency_key_reused (the key was used for another request) or idempotency_key_in_use (the first "
    "request with this key is still being answered; Retry-After)",
)
REPLAYED = {"Idempotent-Replayed": {"schema": {"type": "string", "enum": ["true"]},
                                    "description": "present on a replayed first response"}}


def idempotency_key(key: str | None = Header(None, alias="Idempotency-Key", pattern=KEY_PATTERN.pattern,
                                             description=KEY_DESCRIPTION)):
    return key




async def answer_once(request: Request, session: Session, principal: Principal, key: str | None, operation: str,
                      content: dict, respond: Callable[[Stage | None], Awaitable[JSONResponse]],
                      on_replay: Callable[[], None] | None = None) -> JSONResponse:
    """``respond(stage)``, once per key: without a key, just respond; with one, replay the
    stored response, or respond and keep its 2xx answer under the key.  A ``respond`` that
    calls ``stage`` before its service commits stores the answer in the same transaction
    as the work (crash-safe); otherwise the answer is stored after it."""
    if key is None:
        return await respond(None)
    settings = request.app.state.settings
    service = IdempotencyService(session, principal.tenant_id, settings.idempotency_hours,
                                 hold_s=settings.validation_timeout_s + 60.0)
    outcome = await run_in_threadpool(service.begin, key, operation, fingerprint(content))
    if isinstance(outcome, Replay):
        if on_replay is not None:
            on_replay()
        headers = {"Idempotent-Replayed": "true", **({"Location": outcome.location} if outcome.location else {})}
        return JSONResponse(outcome.body, status_code=outcome.status_code, headers=headers)
    staged = []

    def stage(status_code: int, body: dict, location: str | None) -> None:
        service.stage(outcome, status_code, body, location)
        staged.append(status_code)

    try:
        response = await respond(stage)
    except BaseException:
        await run_in_threadpool(service.abandon, outcome)
        raise
    if 200 <= response.status_code < 300:
        if not staged:
            await run_in_threadpool(service.finish, outcome, response.status_code, json.loads(response.body),
                                    response.headers.get("location"))
    else:
        await run_in_threadpool(service.abandon, outcome)
    return response
