"""Structured logs: one JSON object per line (structlog), for the service and the
libraries it runs (uvicorn, SQLAlchemy, the job runner), each carrying the request id.

What never reaches a log line:
- API keys: any ``cnk_<8 hex>_<secret>`` in a message or a field keeps its public
  prefix and loses its secret; fields named like credentials are dropped;
- patient data: the service logs ids, sizes, codes and durations, never a file name, a
  form field or a scan's content (uploaded file names can hold a patient's name).
Raw exception text and tracebacks do go to the log (with the request id), never to a
client: that is where an operator looks when a client quotes its ``X-Request-ID``.
"""

from __future__ import annotations

import logging
import re
import sys
from typing import IO

import structlog

#: an API key: the public prefix is kept, the secret part replaced
KEY_SECRET = re.compile(r"(cnk_[0-9a-f]{8})_[A-Za-z0-9_-]+")
#: fields that would carry a credential or patient data whatever their value
DROPPED_FIELDS = frozenset({"authorization", "x-api-key", "api_key", "key", "password", "filename", "file_name"})
LOGGER_NAMES = ("calf_nurbs", "uvicorn", "uvicorn.error", "sqlalchemy", "alembic")


def redact(text: str) -> str:
    """``text`` with every API key's secret replaced (its prefix kept)."""
    return KEY_SECRET.sub(r"\1_[redacted]", text)


def _redact_event(_logger, _method: str, event: dict) -> dict:
    event.pop("color_message", None)  # uvicorn's terminal copy of the message
    for name in list(event):
        if name.lower() in DROPPED_FIELDS:
            event[name] = "[redacted]"
        elif isinstance(event[name], str):
            event[name] = redact(event[name])
    return event


def configure_logging(level: str = "INFO", stream: IO[str] | None = None, json: bool = True) -> None:
    """Route every log record (structlog's and the standard library's) through one
    handler on ``stream`` (stderr), rendered as JSON lines (or aligned text for a
    terminal with ``json=False``), keys redacted."""
    shared = [
        structlog.contextvars.merge_contextvars,
        structlog.stdlib.add_log_level,
        structlog.stdlib.add_logger_name,
        structlog.processors.TimeStamper(fmt="iso", utc=True),
    ]
    structlog.configure(
        processors=[*shared, structlog.stdlib.ProcessorFormatter.wrap_for_formatter],
        logger_factory=structlog.stdlib.LoggerFactory(),
        wrapper_class=structlog.stdlib.BoundLogger,
        cache_logger_on_first_use=False,
    )
    renderer = structlog.processors.JSONRenderer() if json else structlog.dev.ConsoleRenderer(colors=False)
    formatter = structlog.stdlib.ProcessorFormatter(
        foreign_pre_chain=[*shared, structlog.stdlib.ExtraAdder()],
        processors=[
            structlog.stdlib.ProcessorFormatter.remove_processors_meta,
            structlog.processors.format_exc_info,
            _redact_event,
            renderer,
        ],
    )
    handler = logging.StreamHandler(stream or sys.stderr)
    handler.setFormatter(formatter)
    root = logging.getLogger()
    root.handlers = [handler]
    root.setLevel(level.upper())
    for name in LOGGER_NAMES:  # one handler, at the root: no line twice, none plain
        logger = logging.getLogger(name)
        logger.handlers = []
        logger.propagate = True
    logging.getLogger("uvicorn.access").disabled = True  # the request line is ours
    logging.getLogger("sqlalchemy").setLevel("WARNING")


def get_logger(name: str):
    return structlog.stdlib.get_logger(name)
