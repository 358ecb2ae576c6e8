"""One JSON document on stdout, with large parts pre-encoded by pandas' C encoder."""

from __future__ import annotations

import json
from typing import Any, TextIO


class RawJSON(str):
    """Text that is already valid JSON (ASCII only) and is spliced in as is."""


def _encode(value: Any) -> str:
    if isinstance(value, RawJSON):
        return value
    # ensure_ascii: no raw control or C1 bytes from a log can reach a terminal.
    # Compact: json's C encoder only runs without indent (pipe into jq to read).
    return json.dumps(value, ensure_ascii=True, separators=(",", ":"), allow_nan=False)


def dumps(doc: dict[str, Any]) -> str:
    """Compact, ASCII-only JSON; top-level :class:`RawJSON` values go in verbatim."""
    return "{" + ",".join(f"{json.dumps(k)}:{_encode(v)}" for k, v in doc.items()) + "}"


def write(doc: dict[str, Any], out: TextIO) -> None:
    """Write ``dumps(doc)`` and a newline part by part: no second copy of a large document."""
    out.write("{")
    for i, (key, value) in enumerate(doc.items()):
        out.write(("," if i else "") + json.dumps(key) + ":")
        out.write(_encode(value))
    out.write("}\n")
