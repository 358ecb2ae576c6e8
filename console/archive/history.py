"""The archive's history as the analyses' inputs: the report's data for a window, and a replay in time order.

:func:`report_data` returns the :class:`~console.report.model.ReportData`
that ``trackside report`` builds from files, built instead from the
archive's records, fixes and frames (optionally cut to a time window, a
counting head, a device), by calling the same analyses the same way:
``DiagAccumulator`` over the records in file and line order, then
``detection_events``, ``health_findings``, ``run_sections`` (preparatory
start), ``frames_to_events``, ``run_crossings``.  The derived tables
(:mod:`console.archive.derive`) are this data written down.

:func:`replay` yields the archive's records in time order, in batches, for
the station view's replay.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from console.archive.store import Manifest, read_current
from console.archive.views import connect

if TYPE_CHECKING:
    import pandas as pd
    import pyarrow as pa

    from console.jobs import DiagJob
    from console.layout import Layout
    from console.report.model import ReportData
    from parsers.report import ParseReport

BATCH_ROWS = 1 << 20


@dataclass(frozen=True)
class Window:
    """Which history: a time range [from, to), a counting head, a device id (None: all)."""

    start: dt.datetime | None = None
    end: dt.datetime | None = None
    head: str | None = None
    device_id: int | None = None

    def where(self) -> tuple[str, list[Any]]:
        conds: list[str] = []
        params: list[Any] = []
        if self.start is not None:
            conds.append("time >= ?")
            params.append(self.start)
        if self.end is not None:
            conds.append("time < ?")
            params.append(self.end)
        if self.head is not None:
            conds.append("counting_head = ?")
            params.append(self.head)
        if self.device_id is not None:
            conds.append("device_id = ?")
            params.append(self.device_id)
        if self.start is not None or self.end is not None:
            # Partition pruning: the day keys are in the paths.
            if self.start is not None:
                conds.append("day >= ?")
                params.append(self.start.date())
            if self.end is not None:
                conds.append("day <= ?")
                params.append(self.end.date())
        return (" WHERE " + " AND ".join(conds)) if conds else "", params

    @property
    def whole(self) -> bool:
        return self == Window()


def parse_time(text: str) -> dt.datetime:
    """``2026-03-02``, ``2026-03-02T10:00``, ``2026-03-02 10:00:05``: naive, as the logs write time."""
    try:
        t = dt.datetime.fromisoformat(text.strip())
    except ValueError:
        raise ValueError(f"expected an ISO date or time (2026-03-02 or 2026-03-02T10:00), found {text!r}") from None
    return t.replace(tzinfo=None) if t.tzinfo is None else t.astimezone(dt.UTC).replace(tzinfo=None)


_RECORD_COLUMNS = (
    "time, diag_id, device_id, device, type, gs, counting_head, channel, address, label, label_canonical, "
    "label_encoding, data, value, data_kind, subsecond, file, file_seq, line"
)


def record_batches(root: Path, manifest: Manifest, window: Window = Window()) -> Iterator[pa.RecordBatch]:
    """The records (in file, line order: the order a batch read sees them), in Arrow batches."""
    if not manifest.parts("records"):
        return
    con, _ = connect(root, manifest)
    try:
        where, params = window.where()
        rel = con.sql(f"SELECT {_RECORD_COLUMNS} FROM records{where} ORDER BY file_seq, line", params=params)
        yield from rel.to_arrow_reader(BATCH_ROWS)
    finally:
        con.close()


def diag_report(manifest: Manifest, root: Path, window: Window) -> ParseReport:
    """The diagnostic parse report, summed over every ingest of every file (rejections from the archive)."""
    from parsers.report import FileReport, ParseReport, Rejection

    report = ParseReport()
    report.max_rejections_kept = 1 << 62
    for e in sorted(manifest.files, key=lambda e: int(e["file_seq"])):
        if e["kind"] != "diagnostic" or not e.get("active", True):
            continue
        report.files.append(
            FileReport(
                file=e["path"],
                lines_read=int(e["lines"]),
                records=int(e["records"]),
                blank=int(e["blank"]),
                rejected=int(e["rejected"]),
                bytes_read=int(e["bytes"]),
                encoding=str(e.get("encoding", "utf-8")),
                compressed=bool(e.get("compressed", False)),
                ends_without_newline=bool(e.get("ends_without_newline", False)),
            )
        )
    active = {int(e["file_seq"]) for e in manifest.files if e["kind"] == "diagnostic" and e.get("active", True)}
    if manifest.parts("rejected") and active:
        con, _ = connect(root, manifest)
        try:
            rows = con.execute(
                "SELECT file, line, reason, text FROM rejected WHERE file_seq IN (SELECT unnest(?)) "
                "ORDER BY file_seq, line",
                [sorted(active)],
            ).fetchall()
        finally:
            con.close()
        for f, line, reason, text in rows:
            report.rejections.append(Rejection(str(f), int(line), str(reason), str(text)))
    return report


def diag_job(root: Path, manifest: Manifest, window: Window = Window()) -> DiagJob | None:
    """What ``analyze_files`` returns for the archive's diagnostic records (None: there are none)."""
    from console.analysis.diagnostics import DiagAccumulator
    from console.archive.records import ChunkRebuilder
    from console.jobs import HEALTH_REGISTERS, DiagJob
    from parsers.diag import DiagChunk, chunks_to_frame

    settings = speed_settings(manifest)
    rebuild = ChunkRebuilder()
    acc = DiagAccumulator(rebuild.registry, keep_releases=True)
    kept: list[DiagChunk] = []
    n = 0
    for batch in record_batches(root, manifest, window):
        for chunk in rebuild.chunks(batch):
            n += len(chunk)
            acc.add(chunk)
            regs = rebuild.registry.registers
            wanted = np.fromiter((r.label_canonical in HEALTH_REGISTERS for r in regs), bool, len(regs))
            mask = wanted[chunk.register_id]
            if mask.any():
                kept.append(chunk.take(mask))
    if n == 0:
        return None
    analysis = acc.result(settings)
    records = chunks_to_frame(kept, rebuild.registry)
    report = diag_report(manifest, root, window)
    report.unknown_labels.update(rebuild.registry.unknown_labels())
    files = [f.file for f in report.files]
    return DiagJob(files=files, report=report, analysis=analysis, kept_records=records)


def speed_settings(manifest: Manifest, layout: Layout | None = None) -> Any:
    from console.analysis.diagnostics import SpeedSettings

    lay = layout if layout is not None else _layout(manifest.derived.get("layout"))
    consist = lay.consist() if lay is not None else None
    return SpeedSettings(
        spacing_m=lay.heads[0].spacing_m if lay is not None and lay.heads else SpeedSettings.spacing_m,
        train_length_m=consist.length_m if consist is not None else SpeedSettings.train_length_m,
    )


def _layout(spec: str | None) -> Layout | None:
    from console.layout import load_layout

    return load_layout(spec) if spec else None


def _per_file_tables(root: Path, manifest: Manifest, table: str) -> list[tuple[int, pd.DataFrame]]:
    import pyarrow.parquet as pq

    out = []
    for rel in manifest.parts(table):
        t = pq.read_table(root / rel)
        df = t.to_pandas()
        seq = int(df["file_seq"].iloc[0]) if len(df) else -1
        out.append((seq, df.drop(columns=["file_seq"])))
    return sorted(out, key=lambda x: x[0])


def report_data(
    root: Path, layout_spec: str | None = None, window: Window = Window(), manifest: Manifest | None = None
) -> ReportData:
    """The report's data, from the archive (the inputs listed are the archived files)."""
    import pandas as pd

    from console.analysis.crossing_batch import run_crossings
    from console.analysis.diag_events import DiagEventSettings
    from console.analysis.events import DetectionEvent, sort_events
    from console.analysis.frame_events import frames_to_events
    from console.analysis.health import sort_findings
    from console.analysis.sections import SectionState, run_sections
    from console.jobs import detection_events, health_findings
    from console.report.model import CENTRE, InputFile, ReportData

    m = manifest if manifest is not None else read_current(root)
    spec = layout_spec if layout_spec is not None else m.derived.get("layout")
    layout = _layout(spec)
    settings = speed_settings(m, layout)
    inputs = [
        InputFile(str(e["path"]), str(e["kind"]), True, "from the archive")
        for e in sorted(m.files, key=lambda e: int(e["file_seq"]))
        if e.get("active", True)
    ]
    data = ReportData(inputs=inputs, layout=layout, settings=settings)
    job = diag_job(root, m, window)
    findings = []
    if job is not None:
        data.job = job
        data.reports["diagnostic"] = job.report
        data.events, ev_warnings = detection_events(job, layout, DiagEventSettings())
        data.warnings += ev_warnings
        findings += health_findings(job, layout, data.events, None)
    data.findings = sort_findings(findings)

    frames = _per_file_tables(root, m, "frames")
    if frames and window.whole:
        up: dict[str, bool] | bool = (
            {h.id: h.up_is_first_channel_first for h in layout.heads} if layout is not None else True
        )
        events: list[DetectionEvent] = []
        for _, part in frames:
            events += frames_to_events(part, up_is_s1_to_s3=up)
        data.frame_events = sort_events(events)
        data.frames = pd.concat([p for _, p in frames], ignore_index=True)[["time", "sensor", "file", "line"]]

    if layout is not None and layout.sections:
        if data.job is not None:
            data.section_source = "diagnostic"
            data.sections = run_sections(layout, data.events, initial=SectionState.PREPARATORY)
        elif data.frames is not None:
            data.section_source = "frames"
            data.sections = run_sections(layout, data.frame_events, initial=SectionState.PREPARATORY)

    fixes_parts = _per_file_tables(root, m, "fixes")
    if fixes_parts:
        fixes = pd.concat([p for _, p in fixes_parts], ignore_index=True)
        fixes = fixes.sort_values("time", kind="stable", na_position="last").reset_index(drop=True)
        if window.start is not None:
            fixes = fixes[fixes["time"] >= pd.Timestamp(window.start)]
        if window.end is not None:
            fixes = fixes[fixes["time"] < pd.Timestamp(window.end)]
        data.fixes = fixes
        if layout is not None and layout.crossings and len(layout.track) >= 2:
            own = fixes["source"].astype(str) != CENTRE
            data.crossing = run_crossings(fixes[own] if own.any() else fixes, layout)
    return data


def replay(root: Path, window: Window = Window()) -> Iterator[pd.DataFrame]:
    """The records in time order (ties in file, line order), a DataFrame per batch, for the station view."""
    m = read_current(root)
    if not m.parts("records"):
        return
    con, _ = connect(root, m)
    try:
        where, params = window.where()
        rel = con.sql(f"SELECT {_RECORD_COLUMNS} FROM records{where} ORDER BY time, file_seq, line", params=params)
        for batch in rel.to_arrow_reader(BATCH_ROWS):
            yield batch.to_pandas()
    finally:
        con.close()
