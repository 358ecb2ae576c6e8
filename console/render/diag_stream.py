"""``--jsonl``: diagnostic results as JSON lines, each written and flushed as it is found.

One object per line, each with a ``type``: ``rejected`` (an input line that
was not parsed, as the parser meets it), ``passage`` (as soon as it is whole),
then at the end one ``device`` per board (its type as ``device_type``) and one ``summary`` (settings, parse
report counts, status-passage counts).  A 30 M-record log can be piped into
``jq`` without waiting for the end or buffering the whole output.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from typing import Any, TextIO

from console.analysis.head_table import Heads
from console.analysis.passages import Columns
from console.jsonout import valid_unicode
from parsers.report import Rejection


def line(obj: dict[str, Any]) -> str:
    # ensure_ascii: no raw control byte of a log reaches a terminal.
    return valid_unicode(json.dumps(obj, ensure_ascii=True, separators=(",", ":"), allow_nan=False)) + "\n"


class JsonLinesOut:
    """Writes the lines of one ``--jsonl`` run to ``out``."""

    def __init__(self, out: TextIO, rejections_shown: int | None) -> None:
        self.out = out
        self.rejections_shown = rejections_shown  # None: all
        self.rejections_written = 0

    def rejected(self, r: Rejection) -> None:
        if self.rejections_shown is not None and self.rejections_written >= self.rejections_shown:
            return
        self.rejections_written += 1
        self.out.write(line({"type": "rejected", **r.to_dict()}))
        self.out.flush()

    def passages(self, cols: Columns, heads: Heads) -> None:
        from console.analysis.passages_json import encode_passages

        text = encode_passages(cols, heads, workers=1, lines_of_type="passage")
        if text is None:  # text the byte encoder does not cover: pandas' encoder
            from console.analysis.diagnostics import _passages_frame, passages_json_text

            rows = json.loads(passages_json_text(_passages_frame(cols, heads)))
            text = "".join(line({"type": "passage", **p}) for p in rows)
        self.out.write(text)
        self.out.flush()

    def finish(self, devices: Iterable[dict[str, Any]], summary: dict[str, Any]) -> None:
        from console.jsonout import write

        for d in devices:
            # "type" names the line; the board's own type is "device_type" here.
            self.out.write(line({"type": "device", **{("device_type" if k == "type" else k): v for k, v in d.items()}}))
        write({"type": "summary", **summary}, self.out)  # as line(): its larger parts may be streamed
        self.out.flush()
