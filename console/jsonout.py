"""One JSON document on stdout, with large parts pre-encoded by pandas' C encoder."""

from __future__ import annotations

import itertools
import json
import re
from collections.abc import Iterable, Iterator, Mapping
from typing import Any, TextIO

# In JSON text from json.dumps(ensure_ascii=True): an escaped backslash, a
# surrogate pair (a character beyond the BMP), or a lone surrogate.
_SURROGATE = re.compile(r"\\\\|\\ud[89ab][0-9a-f]{2}\\ud[c-f][0-9a-f]{2}|\\u(d[89a-f][0-9a-f]{2})")


class RawJSON(str):
    """Text that is already valid JSON (ASCII only) and is spliced in as is."""


class JSONParts:
    """Pieces of text that together are valid JSON (ASCII only), written one by one:
    a large array is never one string.  Iterable once.

    A piece may be ASCII bytes: :func:`write` hands those to the output's byte layer as they are (a spool's
    megabytes of passages are never decoded to text and encoded back)."""

    def __init__(self, parts: Iterable[str | bytes]) -> None:
        self.parts = parts

    def texts(self) -> Iterator[str]:
        """The pieces as text."""
        for part in self.parts:
            yield part.decode("ascii") if isinstance(part, bytes) else part


def _lone_surrogate(match: re.Match[str]) -> str:
    if match.group(1) is None:
        return match.group()
    code = int(match.group(1), 16)
    # A byte of a file name that is not UTF-8 (surrogateescape) shows as \xff,
    # as in the terminal; any other lone surrogate as its code.
    return f"\\\\x{code - 0xDC00:02x}" if 0xDC80 <= code <= 0xDCFF else f"\\\\u{code:04x}"


def valid_unicode(text: str) -> str:
    """JSON text with lone surrogates (``\\udcff``: not Unicode, refused by strict readers) made visible escapes."""
    return _SURROGATE.sub(_lone_surrogate, text) if "\\ud" in text else text


def _encode(value: Any) -> str:
    if isinstance(value, RawJSON):
        return value
    if isinstance(value, JSONParts):
        return "".join(value.texts())
    # ensure_ascii: no raw control or C1 bytes from a log can reach a terminal.
    # Compact: json's C encoder only runs without indent (pipe into jq to read).
    return valid_unicode(json.dumps(value, ensure_ascii=True, separators=(",", ":"), allow_nan=False))


def encode(value: Any) -> str:
    """One value as compact, ASCII-only JSON text (lone surrogates made visible)."""
    return _encode(value)


def dumps(doc: dict[str, Any]) -> str:
    """Compact, ASCII-only JSON; :class:`RawJSON` and :class:`JSONParts` values go in verbatim."""
    return "{" + ",".join(f"{valid_unicode(json.dumps(k))}:{''.join(_texts(_parts(v)))}" for k, v in doc.items()) + "}"


def _texts(parts: Iterable[str | bytes]) -> Iterator[str]:
    for part in parts:
        yield part.decode("ascii") if isinstance(part, bytes) else part


def array_parts(items: Iterable[Any], block: int = 4096) -> JSONParts:
    """A JSON array of ``items`` (e.g. a generator), encoded ``block`` items at a time: the items
    need never be all in memory, nor their text."""

    def parts() -> Iterator[str]:
        it = iter(items)
        sep = "["
        while batch := list(itertools.islice(it, block)):
            yield sep + _encode(batch)[1:-1]
            sep = ","
        yield "[]" if sep == "[" else "]"

    return JSONParts(parts())


def _parts(value: Any) -> Iterator[str | bytes]:
    """The JSON text of a value whose parts may be :class:`JSONParts` (also inside a dict), piece by piece."""
    if isinstance(value, JSONParts):
        yield from value.parts
    elif isinstance(value, dict) and any(isinstance(v, JSONParts) for v in value.values()):
        for i, (key, item) in enumerate(value.items()):
            yield ("{" if i == 0 else ",") + valid_unicode(json.dumps(key)) + ":"
            yield from _parts(item)
        yield "}"
    else:
        yield _encode(value)


def write(doc: dict[str, Any], out: TextIO) -> None:
    """Write ``dumps(doc)`` and a newline part by part: no second copy of a large document."""
    raw = getattr(out, "buffer", None)
    out.write("{")
    for i, (key, value) in enumerate(doc.items()):
        out.write(("," if i else "") + valid_unicode(json.dumps(key)) + ":")
        for part in _parts(value):
            if not isinstance(part, bytes):
                out.write(part)
            elif raw is not None:
                out.flush()  # the text written before it goes first
                raw.write(part)
            else:
                out.write(part.decode("ascii"))
    out.write("}\n")


def typed_line(kind: str, item: Any) -> str:
    """One JSON line: the object ``item`` (or its JSON text, :class:`RawJSON`) with ``"type": kind`` first."""
    text = _encode(item)
    if not text.startswith("{"):
        text = _encode({"value": item})
    return '{"type":' + _encode(kind) + ("}" if text == "{}" else "," + text[1:])


def write_lines(doc: dict[str, Any], records: Mapping[str, str], out: TextIO) -> None:
    """``doc`` as JSON lines: each item of the arrays ``records`` names (key → type) a line of that type, in the
    document's order, then one ``summary`` line with the rest of the document (schema, files, report)."""
    summary = {}
    for key, value in doc.items():
        kind = records.get(key)
        if kind is None:
            summary[key] = value
            continue
        for item in value:
            out.write(typed_line(kind, item) + "\n")
    out.write(typed_line("summary", RawJSON(dumps(summary))) + "\n")
