"""Content negotiation, one rule for every resource with more than one representation.

RFC 9110 section 12.5.1: ``Accept`` lists media ranges with optional ``q`` weights; the
representation chosen is the acceptable one with the highest weight, ties going to the
range listed first; ``type/*`` and ``*/*`` take the resource's default form within that
type; ``q=0`` means "not this".  ``?format=`` (a query parameter) overrides ``Accept``.
"""

from __future__ import annotations

from app.errors import NotAcceptable


def accepted_ranges(accept: str) -> list[tuple[str, float]]:
    """The media ranges of an Accept header, best first: [(range, q)], q > 0 only."""
    offers = []
    for position, item in enumerate(accept.split(",")):
        media, *params = (part.strip() for part in item.split(";"))
        q = 1.0
        for param in params:
            name, _, value = param.partition("=")
            if name.strip().lower() == "q":
                try:
                    q = float(value)
                except ValueError:
                    q = 0.0
        if media and q > 0:
            offers.append((q, -position, media.lower()))
    return [(media, q) for q, _, media in sorted(offers, reverse=True)]


def negotiate(accept: str | None, query_format: str | None, representations: dict[str, str], what: str) -> str:
    """The format key of ``representations`` (format -> media type, the default first) to send.

    Raises NotAcceptable naming what ``what`` is available as.
    """
    if query_format:
        fmt = query_format.lower()
        if fmt not in representations:
            raise NotAcceptable(f"format must be one of {', '.join(representations)}, not {query_format!r}")
        return fmt
    if not accept:
        return next(iter(representations))
    by_media = {media: fmt for fmt, media in representations.items()}
    for media, _ in accepted_ranges(accept):
        if media in by_media:
            return by_media[media]
        kind = media.partition("/")[0]
        if media == "*/*":
            return next(iter(representations))
        if media.endswith("/*"):
            for fmt, offered in representations.items():  # the first form of that type
                if offered.partition("/")[0] == kind:
                    return fmt
    raise NotAcceptable(f"cannot produce {accept!r}; {what} is available as {', '.join(representations.values())}")
