"""Is a scan file whole?  Truncation and corruption checks of STL and PLY, made on the
bytes before any parser reads them (a truncated binary STL or PLY would otherwise be
read as a smaller scan, silently).

Binary STL: 80-byte header, uint32 triangle count n, then exactly 50 n bytes; ASCII STL
between ``solid`` and ``endsolid``.  PLY: the header's elements, their counts and
property types give the exact data length (binary) or line count (ASCII).
"""

from __future__ import annotations

import re

import numpy as np

from app.geometry.errors import FailureReason, FitFailure


def check_stl_integrity(data: bytes) -> None:
    """Refuse truncated or corrupt STL before parsing.

    Binary STL: 80-byte header, uint32 triangle count n, then exactly 50 * n bytes.
    ASCII STL: starts with ``solid`` and ends with ``endsolid``.
    """
    if binary_stl_count(data) is not None:
        return  # a well-formed binary STL (even if its header says "solid")
    head = data[:512].lstrip().lower()
    if head.startswith(b"solid") and b"facet" in data[:4096].lower():
        if not data.rstrip().lower().split(b"\n")[-1].strip().startswith(b"endsolid"):
            raise FitFailure(FailureReason.TRUNCATED_FILE, "the ASCII STL is truncated: it does not end with 'endsolid'")
        return
    if len(data) < 84:
        raise FitFailure(FailureReason.TRUNCATED_FILE, f"the STL is {len(data)} bytes, shorter than a binary STL header (84)")
    count = int(np.frombuffer(data[80:84], dtype="<u4")[0])
    expected = 84 + 50 * count
    if len(data) < expected:
        raise FitFailure(
            FailureReason.TRUNCATED_FILE,
            f"the binary STL is truncated: its header announces {count} triangles "
            f"({expected} bytes) but the file has {len(data)} bytes",
        )
    raise FitFailure(
        FailureReason.UNREADABLE_FILE,
        f"the binary STL announces {count} triangles ({expected} bytes) but the file has {len(data)} bytes",
    )


#: bytes of the PLY scalar types (PLY 1.0 names and their sized aliases)
_PLY_TYPE_BYTES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2,
                   "uint16": 2, "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4,
                   "double": 8, "float64": 8}


#: a line holding something other than white space (one C-level pass over a body)
_DATA_LINE = re.compile(rb"^[ \t\r]*\S", re.MULTILINE)


def check_ply_integrity(data: bytes) -> None:
    """Refuse a PLY that holds fewer elements than its header announces.

    The header lists ``element vertex N`` and ``element face M`` with their properties
    and ends with ``end_header``.  ASCII: one element per line, so at least N + M data
    lines must follow.  Binary: at least N vertex records (fixed size from the scalar
    properties) plus M face records of a triangle (list count + 3 indices) must follow.
    A reader would otherwise return the elements present and a scan cut short would be
    fitted, or refused for the wrong reason.
    """
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        return  # not a PLY header: the reader gives the reason
    body_start = data.find(b"\n", end)
    body = data[body_start + 1 :] if body_start >= 0 else b""
    elements: list[list] = []  # [name, count, fixed bytes, minimum list bytes]
    fmt = "ascii"
    for line in data[:end].decode("ascii", "replace").splitlines():
        words = line.split()
        if len(words) >= 2 and words[0] == "format":
            fmt = words[1]
        elif len(words) == 3 and words[0] == "element" and words[2].isdigit():
            elements.append([words[1], int(words[2]), 0, 0])
        elif elements and len(words) == 3 and words[0] == "property":
            elements[-1][2] += _PLY_TYPE_BYTES.get(words[1], 0)
        elif elements and len(words) == 5 and words[:2] == ["property", "list"]:
            count_bytes, item_bytes = _PLY_TYPE_BYTES.get(words[2], 0), _PLY_TYPE_BYTES.get(words[3], 0)
            elements[-1][3] += count_bytes + 3 * item_bytes  # at least a triangle
    plural = {"vertex": "vertices"}
    announced = ", ".join(f"{count} {plural.get(name, name + 's') if count != 1 else name}"
                          for name, count, _, _ in elements)
    if fmt == "ascii":
        needed = sum(count for _, count, _, _ in elements)
        present = len(_DATA_LINE.findall(body))
        unit = "lines"
    else:
        needed = sum(count * (fixed + listed) for _, count, fixed, listed in elements)
        present, unit = len(body), "bytes"
    if present < needed:
        raise FitFailure(
            FailureReason.TRUNCATED_FILE,
            f"the PLY is truncated: its header announces {announced} ({needed} {unit} of data) "
            f"but the file has {present}",
        )


def binary_stl_count(data: bytes) -> int | None:
    """The triangle count of a well-formed binary STL (80-byte header, uint32 n, then
    exactly 50 n bytes), or None when ``data`` is not one (even if it says "solid")."""
    if len(data) < 84:
        return None
    count = int(np.frombuffer(data[80:84], dtype="<u4")[0])
    return count if len(data) == 84 + 50 * count else None
