"""One JSON document on stdout, with large parts pre-encoded by pandas' C encoder."""

from __future__ import annotations

import json
from typing import Any


class RawJSON(str):
    """Text that is already valid JSON (ASCII only) and is spliced in as is."""


def dumps(doc: dict[str, Any]) -> str:
    """Compact, ASCII-only JSON (no raw control bytes can reach a terminal).

    Top-level values that are :class:`RawJSON` are inserted verbatim; json's C
    encoder only runs without ``indent``, so the output is compact (pipe it
    into ``jq`` to read it).
    """
    parts = []
    for key, value in doc.items():
        text = (
            value
            if isinstance(value, RawJSON)
            else json.dumps(value, ensure_ascii=True, separators=(",", ":"), allow_nan=False)
        )
        parts.append(f"{json.dumps(key)}:{text}")
    return "{" + ",".join(parts) + "}"
