"""Receiving a scan upload: stream to disk while hashing, enforcing the size limit on the
bytes actually received.

Two shapes of request:
- ``multipart/form-data`` (browsers, clinic portals): the scan in field ``file``,
  options as form fields ``side``, ``units``, ``points``;
- a raw body whose ``Content-Type`` is the scan's media type (scripts), options as
  query parameters.  ``application/octet-stream`` needs ``?format=``.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from pathlib import Path

from python_multipart.exceptions import MultipartParseError
from python_multipart.multipart import MultipartParser, MultipartState, parse_options_header

from app.errors import BadRequest, EmptyBody, PayloadTooLarge, UnsupportedMediaType
from app.geometry.scan.reader import SUPPORTED_FORMATS
from app.services.storage import ScanStore

#: media types the service accepts, and the scan format each means
MEDIA_TYPES = {
    "model/stl": "stl",
    "application/sla": "stl",
    "application/vnd.ms-pki.stl": "stl",
    "model/x.stl-binary": "stl",
    "model/x.stl-ascii": "stl",
    "model/gltf-binary": "glb",
    "model/gltf+json": "gltf",
    "model/obj": "obj",
    "application/x-ply": "ply",
    "application/ply": "ply",
    "model/ply": "ply",
    "model/x-off": "off",
    "application/off": "off",
    "text/csv": "csv",
    "chemical/x-xyz": "xyz",
    "text/x-xyz": "xyz",
}
OCTET_STREAM = "application/octet-stream"
#: a form field (not the file) larger than this is refused
MAX_FIELD_BYTES = 1024
#: longest header line of a part (python-multipart's default is 4224): a file name as
#: long as a deep path of a clinic's archive fits; more is refused with its own code
MAX_PART_HEADER_BYTES = 16384


@dataclass
class ReceivedUpload:
    """A fully received scan in a temporary file."""

    temp_path: Path
    sha256: str
    size_bytes: int
    file_format: str
    media_type: str
    fields: dict = field(default_factory=dict)

    def discard(self) -> None:
        self.temp_path.unlink(missing_ok=True)


class _HashingWriter:
    def __init__(self, store: ScanStore):
        self.fd, self.path = store.new_temp()
        self.digest = hashlib.sha256()
        self.size = 0

    def write(self, chunk: bytes) -> None:
        if chunk:
            self.digest.update(chunk)
            self.size += len(chunk)
            os.write(self.fd, chunk)

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1

    def abort(self) -> None:
        self.close()
        self.path.unlink(missing_ok=True)


def format_for_media_type(media_type: str, format_hint: str | None) -> str:
    """Scan format for a request/part media type (415 when unknown)."""
    if format_hint:
        hint = format_hint.lower().lstrip(".")
        if hint not in SUPPORTED_FORMATS:
            raise UnsupportedMediaType(f"unsupported scan format {format_hint[:40]!r}; use one of {', '.join(SUPPORTED_FORMATS)}")
        return hint
    if media_type in MEDIA_TYPES:
        return MEDIA_TYPES[media_type]
    raise UnsupportedMediaType(
        f"unsupported media type {media_type or '(none)'!r}; send one of {', '.join(sorted(MEDIA_TYPES))}, "
        f"or {OCTET_STREAM} with ?format=, or a multipart form with a file named *.stl, *.ply, ..."
    )


async def receive_upload(
    headers, stream: AsyncIterator[bytes], store: ScanStore, limit: int, query_format: str | None
) -> ReceivedUpload:
    """Read the request body (see module docstring) into the store's temp area."""
    declared = headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit:
        raise PayloadTooLarge(f"the upload declares {int(declared)} bytes; the limit is {limit} bytes")
    content_type, params = parse_options_header(headers.get("content-type", ""))
    media_type = content_type.decode("latin-1").lower()
    if media_type == "multipart/form-data":
        return await _receive_multipart(params.get(b"boundary"), stream, store, limit)
    if media_type == OCTET_STREAM and not query_format:
        raise UnsupportedMediaType(f"{OCTET_STREAM} needs ?format= (stl, ply, obj, off, glb, gltf, xyz, csv)")
    file_format = format_for_media_type(media_type if media_type != OCTET_STREAM else "", query_format)
    writer = _HashingWriter(store)
    try:
        async for chunk in stream:
            if writer.size + len(chunk) > limit:
                raise PayloadTooLarge(f"the upload exceeds the limit of {limit} bytes")
            writer.write(chunk)
    except BaseException:
        writer.abort()
        raise
    writer.close()
    if writer.size == 0:
        writer.abort()
        raise EmptyBody("the request body is empty: send the scan file as the body")
    return ReceivedUpload(writer.path, writer.digest.hexdigest(), writer.size, file_format, media_type)


async def _receive_multipart(boundary: bytes | None, stream, store: ScanStore, limit: int) -> ReceivedUpload:
    if not boundary:
        raise BadRequest("multipart/form-data without a boundary parameter")
    state: dict = {"headers": {}, "name": None, "filename": None, "ctype": "", "field": b"", "value": b""}
    fields: dict[str, str] = {}
    files: list[tuple[_HashingWriter, str | None, str]] = []
    current: dict = {"writer": None, "buffer": None}

    def on_part_begin():
        state["headers"] = {}

    def on_header_field(data, start, end):
        state["field"] += data[start:end]

    def on_header_value(data, start, end):
        state["value"] += data[start:end]

    def on_header_end():
        # header values stay bytes: browsers and curl send UTF-8 file and field names,
        # which a str round trip through Latin-1 cannot carry
        state["headers"][state["field"].decode("latin-1").lower()] = bytes(state["value"])
        state["field"], state["value"] = b"", b""

    def on_headers_finished():
        _, disposition = parse_options_header(state["headers"].get("content-disposition", b""))
        name = disposition.get(b"name", b"").decode("utf-8", "replace")
        filename = disposition.get(b"filename")
        state["name"] = name
        if filename is not None and name != "file":
            raise BadRequest(f"the scan must be sent in the form field named 'file', not {name!r}")
        if name == "file":
            writer = _HashingWriter(store)
            ctype = parse_options_header(state["headers"].get("content-type", b""))[0].decode("latin-1").lower()
            files.append((writer, filename.decode("utf-8", "replace") if filename else None, ctype))
            current["writer"], current["buffer"] = writer, None
        else:
            current["writer"], current["buffer"] = None, bytearray()

    def on_part_data(data, start, end):
        chunk = data[start:end]
        if current["writer"] is not None:
            current["writer"].write(chunk)
        elif current["buffer"] is not None:
            current["buffer"].extend(chunk)
            if len(current["buffer"]) > MAX_FIELD_BYTES:
                raise BadRequest(f"form field {state['name']!r} is longer than {MAX_FIELD_BYTES} bytes")

    def on_part_end():
        if current["buffer"] is not None and state["name"]:
            fields[state["name"]] = current["buffer"].decode("utf-8", "replace").strip()
        current["writer"], current["buffer"] = None, None

    parser = MultipartParser(
        boundary,
        {
            "on_part_begin": on_part_begin,
            "on_header_field": on_header_field,
            "on_header_value": on_header_value,
            "on_header_end": on_header_end,
            "on_headers_finished": on_headers_finished,
            "on_part_data": on_part_data,
            "on_part_end": on_part_end,
        },
        max_header_size=MAX_PART_HEADER_BYTES,
    )
    received = 0
    try:
        async for chunk in stream:
            received += len(chunk)
            if received > limit:
                raise PayloadTooLarge(f"the upload exceeds the limit of {limit} bytes")
            parser.write(chunk)
        parser.finalize()
        if received and parser.state not in (MultipartState.END, MultipartState.BOUNDARY_PADDING):
            # the body stopped before its closing boundary: a cut-off upload, not a scan
            raise BadRequest("the multipart body ends before its closing boundary: the upload was cut off; send it "
                             "again", code="truncated_body")
    except MultipartParseError as exc:
        for writer, _, _ in files:
            writer.abort()
        if "header size" in str(exc):
            raise BadRequest(f"a part of the multipart body has a header line longer than {MAX_PART_HEADER_BYTES} bytes: "
                             "shorten the file name", code="header_too_long") from exc
        raise BadRequest("malformed multipart body: its parts do not follow the boundary declared in Content-Type") from exc
    except BaseException:
        for writer, _, _ in files:
            writer.abort()
        raise
    for writer, _, _ in files:
        writer.close()
    if received == 0:
        raise EmptyBody("the request body is empty: send a multipart form with the scan in field 'file'")
    if len(files) != 1:
        for writer, _, _ in files:
            writer.abort()
        raise BadRequest("the form must carry exactly one scan, in the field named 'file'")
    writer, filename, part_type = files[0]
    try:
        extension = os.path.splitext(filename)[1].lower().lstrip(".") if filename else ""
        hint = fields.get("format") or (extension if extension in SUPPORTED_FORMATS else None)
        if not hint and part_type in ("", OCTET_STREAM):
            raise UnsupportedMediaType(
                f"cannot tell the scan format of {filename or 'the file'!r}: name it "
                f"{', '.join(f'*.{name}' for name in SUPPORTED_FORMATS)}, give its media type, or add a 'format' field"
            )
        file_format = format_for_media_type(part_type, hint)
        if writer.size == 0:
            raise EmptyBody("the scan file in field 'file' is empty")
    except BaseException:
        writer.abort()
        raise
    return ReceivedUpload(writer.path, writer.digest.hexdigest(), writer.size, file_format, part_type or OCTET_STREAM, fields)
