"""Case references: the clinic's own pseudonymous patient or case id on uploads, records,
designs and orders.

A case reference groups the records of one person's legs over time ("another record of
this leg" is the same case and side) and names what "erase this case" removes.  It must
be pseudonymous: the clinic's key into its own files, never a name, a birth date or an
insurance number, so it is restricted to 1-64 letters, digits and ``. _ -`` (no spaces,
so no "Doe Jane 1961-03-04"; a value that is a date is refused too, as it is most likely a
birth date; a clinic's numeric patient number is its own key and is accepted).  It is never logged: the service
logs route templates, not paths or query strings, and no error detail repeats it.
"""

from __future__ import annotations

import re

from app.errors import Unprocessable

CASE_REF_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$"
#: the form CASE_REF_PATTERN asks, in words, and the problem's title
CASE_REF_FORM = ("1-64 letters, digits, '.', '_' or '-' (starting with a letter or a digit): the clinic's own "
                 "pseudonymous case id, never a name")
CASE_REF_TITLE = "Invalid case reference"
_CASE_REF = re.compile(CASE_REF_PATTERN)
#: a date (1961-03-04, 04.03.1961)
_IDENTIFYING = re.compile(r"^(\d{4}[-._]\d{2}[-._]\d{2}|\d{2}[-._]\d{2}[-._]\d{4})$")


def validate_case_ref(value: str | None) -> str | None:
    """The case reference, or None when absent/empty; Unprocessable (invalid_case_ref)
    when it is not pseudonymous in the sense of the module docstring."""
    if value is None or value == "":
        return None
    if not isinstance(value, str) or not _CASE_REF.match(value):
        raise Unprocessable(f"case_ref must be {CASE_REF_FORM}", code="invalid_case_ref", title=CASE_REF_TITLE)
    if _IDENTIFYING.match(value):
        raise Unprocessable("case_ref looks like a date (a birth date?); send the clinic's pseudonymous case id "
                            "instead (e.g. CASE-0042)", code="invalid_case_ref", title=CASE_REF_TITLE)
    return value
