"""``--jsonl``: diagnostic results as JSON lines, each written and flushed as it is found.

One object per line, each with a ``type``: ``rejected`` (an input line that
was not parsed, as the parser meets it), ``passage`` (as soon as it is whole),
then at the end one ``device`` per board (its type as ``device_type``) and one ``summary`` (settings, parse
report counts, status-passage counts).  A 30 M-record log can be piped into
``jq`` without waiting for the end or buffering the whole output.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any, TextIO

from console.analysis.head_table import Heads
from console.analysis.passages.buckets import Columns
from console.analysis.passages.status import StatusSummary
from console.engine.sinks import Sink
from console.jsonout import valid_unicode
from console.sinks.tables.event_lines import health_event, section_event
from parsers.report import Rejection

if TYPE_CHECKING:
    from console.analysis.health.findings import Finding
    from console.analysis.sections.state import Transition
    from console.drivers.batch import DiagJob


def line(obj: dict[str, Any]) -> str:
    # ensure_ascii: no raw control byte of a log reaches a terminal.
    return valid_unicode(json.dumps(obj, ensure_ascii=True, separators=(",", ":"), allow_nan=False)) + "\n"


class JsonLinesOut(Sink):
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
        from console.analysis.passages.json_text import encode_passages

        text = encode_passages(cols, heads, workers=1, lines_of_type="passage")
        if text is None:  # text the byte encoder does not cover: pandas' encoder
            from console.analysis.passages.frame_json import passages_json_text
            from console.analysis.passages.passage_frame import passages_frame

            rows = json.loads(passages_json_text(passages_frame(cols, heads)))
            text = "".join(line({"type": "passage", **p}) for p in rows)
        self.out.write(text)
        self.out.flush()

    def transitions(self, rows: Sequence[Transition]) -> None:
        self.out.write("".join(line(section_event(t)) for t in rows))
        self.out.flush()

    def finish(
        self, devices: Iterable[dict[str, Any]], summary: dict[str, Any], findings: Sequence[Finding] = ()
    ) -> None:
        from console.jsonout import write

        for f in findings:
            self.out.write(line(health_event(f)))
        for d in devices:
            # "type" names the line; the board's own type is "device_type" here.
            self.out.write(line({"type": "device", **{("device_type" if k == "type" else k): v for k, v in d.items()}}))
        write({"type": "summary", **summary}, self.out)  # as line(): its larger parts may be streamed
        self.out.flush()


def status_json(status: StatusSummary, heads: Heads) -> dict[str, object]:
    """``status_passages`` of a JSON document: the rows per head encoded as they are written."""
    from console.jsonout import array_parts

    return {**status.totals(), "by_head": array_parts(status.by_head(heads))}


def summary_doc(job: DiagJob, schema: str) -> dict[str, object]:
    """The ``summary`` line of ``--jsonl``: what the JSON document holds besides passages and devices."""
    from console import __version__

    a, s = job.analysis, job.analysis.settings
    report = job.report.to_dict()
    report.pop("rejections")  # listed as lines of their own
    return {
        "schema": schema,
        "trackside_version": __version__,
        "files": job.files,
        "settings": s.to_json(),
        "passages": job.passage_count,
        **({"status_passages": status_json(job.status, a.heads)} if job.status is not None else {}),
        "overlap_records": a.overlap_records,
        "unpaired_detections": a.unpaired_detections,
        "parse_report": report,
        # Records that came after their passage closed, when the passages written are those of that read.
        **({"late_records": job.late_records} if job.late_records and job.reads == 1 else {}),
    }
