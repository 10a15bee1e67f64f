"""Point clouds as text (XYZ, CSV, TXT and Leica's PTS written as .txt or .xyz): the first
three numbers of each row are x, y, z.

Scanners and the software clinics export from write these in several dialects; each is
told from the rows themselves, never guessed per row:

- **separators**: spaces, tabs, commas or semicolons between the columns;
- **decimal commas** (a German or French locale's export: ``12,5;130,25;7,5``,
  ``12,5 130,25 7,5``, with thousands ``1.234,5``): the columns are separated without
  commas - most of the first rows (the median) hold three or more split on spaces, tabs
  and semicolons alone (a comma followed by a space is a separator in every dialect) -
  and a comma stands between two digits somewhere in the file.  A comma CSV's row
  (``12,130,7``) is one such column, so its commas stay separators.  In a file of decimal
  commas a dot is a thousands separator (three digits follow it); any other dot makes
  the file ambiguous, and it is refused.  Read with its commas as separators, such a
  file gave six coordinates of a row's integer and fraction parts - x = 12, y = 5,
  z = 130 - and a scan of nothing.  The rule is decided once, for the whole file;
- **more than three columns** (intensity, colour, normals): the rest of a row is not read,
  and rows may differ in how many they hold;
- **header and comment rows** (``x,y,z``, ``# exported by ...``, ``//``): rows that do not
  start with a number are skipped;
- **point counts**: a row holding a single whole number is PTS's count of the points that
  follow (a PTS file holds one per scan it joins) and is skipped.

A row with one or two numbers that is not a count is refused with its line number in the
file (not its content: a scan is health data), a column that is not a number as rows that
are not all numbers.  Units are the caller's (app.geometry.scan.reader).  Returns (n, 3)
float64.
"""

from __future__ import annotations

import io
import itertools
import re

import numpy as np

from app.geometry.errors import FailureReason, FitFailure

#: a row that does not start with a number (a header or comment): emptied, so the rows
#: keep their line numbers; whole lines, one C-level substitution instead of a Python loop
_OTHER_ROW = re.compile(r"^(?![ \t]*(?:[-+0-9.]|nan|inf)).*$", re.IGNORECASE | re.MULTILINE)
#: a row holding something (the rows the dialect is read from)
_DATA_ROW = re.compile(r"^[^\n]*\S[^\n]*$", re.MULTILINE)
#: a PTS point count: a row of one whole number
_COUNT_ROW = re.compile(r"^[ \t]*\+?[0-9]+[ \t]*$", re.MULTILINE)
#: a row of fewer than three columns (separators already spaces)
_SHORT_ROW = re.compile(r"^[ \t]*\S+(?:[ \t]+\S+)?[ \t]*$", re.MULTILINE)
#: a comma between two digits: a decimal comma, or a separator without spaces
_DIGIT_COMMA_DIGIT = re.compile(r"[0-9],[0-9]")
#: the separators a file of decimal commas has between its columns
_COLUMNS = re.compile(r"[ \t;]+")
#: a comma followed by a space (or a row's end): a separator in every dialect
_COMMA_SPACE = re.compile(r",(?=[ \t]|$)", re.MULTILINE)
#: a thousands separator of a file of decimal commas: a dot between a digit and three digits
_THOUSANDS_DOT = re.compile(r"(?<=[0-9])\.(?=[0-9]{3}(?![0-9]))")
#: the rows the dialect is read from
DIALECT_ROWS = 100


def decimal_comma(rows: list[str], body: str) -> bool:
    """Does a file write its decimals with commas? ``rows``: its first data rows, ``body``:
    the whole file, each with its comma-and-space separators already made spaces (module
    docstring: the columns are separated without commas, and a comma stands between two
    digits somewhere)."""
    if not rows or float(np.median([len(_COLUMNS.split(row.strip())) for row in rows])) < 3:
        return False
    return "," in body and _DIGIT_COMMA_DIGIT.search(body) is not None


def _text(data: bytes) -> str:
    """The file as text, one row per line: UTF-8 (a byte-order mark dropped), or - where a
    header or comment holds a name in another code page - Latin-1, whose bytes all
    decode; numbers are ASCII in both.  A file with NUL bytes is binary, not text."""
    if b"\x00" in data[:65536]:
        raise FitFailure(FailureReason.UNREADABLE_FILE,
                         "the point cloud is not text (it holds binary bytes): export it as XYZ or CSV text, or "
                         "upload the binary file with its own extension (.ply, .stl)")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    return text.replace("\r\n", "\n").replace("\r", "\n")


def read_text_cloud(data: bytes) -> np.ndarray:
    """(n, 3) float64: x, y, z of each data row of a text point cloud (module docstring)."""
    body = _OTHER_ROW.sub("", _text(data))  # headers and comments emptied: the rows keep their numbers
    if "," in body:  # (a C-level search: most clouds hold no comma at all)
        body = _COMMA_SPACE.sub(" ", body)
    first = [m.group() for m in itertools.islice(_DATA_ROW.finditer(body), DIALECT_ROWS)]
    if not first:
        raise FitFailure(FailureReason.EMPTY_SCAN, "the point cloud has no numeric rows")
    comma_decimals = decimal_comma([row for row in first if not _COUNT_ROW.fullmatch(row)], body)
    if comma_decimals:
        body = _THOUSANDS_DOT.sub("", body)
        if "." in body:
            row = body.count("\n", 0, body.index(".")) + 1
            raise FitFailure(
                FailureReason.UNREADABLE_FILE,
                f"the point cloud writes its decimals with commas, but row {row} has a decimal point too: export it "
                "with one decimal mark (a point, or a comma with semicolons or tabs between the columns)")
        body = body.replace(",", ".")
    body = _COUNT_ROW.sub("", body.replace(";", " ").replace(",", " ").replace("\t", " "))
    if not body.strip():
        raise FitFailure(FailureReason.EMPTY_SCAN, "the point cloud has no rows of x, y, z: only point counts")
    dialect = " (its decimals written with commas, as the file writes them)" if comma_decimals else ""
    try:
        return np.loadtxt(io.StringIO(body), dtype=np.float64, ndmin=2, usecols=(0, 1, 2))
    except ValueError as exc:
        short = _SHORT_ROW.search(body)  # (searched only here: it costs 3 times the reading)
        if short is not None:
            raise FitFailure(
                FailureReason.UNREADABLE_FILE,
                f"row {body.count(chr(10), 0, short.start()) + 1} of the point cloud has {len(short.group().split())} "
                f"number(s); each row must start with x y z{dialect} (spaces, commas, tabs or semicolons between)"
            ) from exc
        raise FitFailure(FailureReason.UNREADABLE_FILE,
                         f"the point cloud's rows are not all numbers: each row must start with x y z{dialect} "
                         "(spaces, commas, tabs or semicolons between)") from exc
