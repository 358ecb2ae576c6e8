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
from collections import defaultdict
from collections.abc import Callable, Collection, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from console.archive.store import Manifest, read_current
from console.archive.views import connect

if TYPE_CHECKING:
    import pandas as pd
    import pyarrow as pa

    from console.analysis.events import DetectionEvent
    from console.drivers.batch import DiagJob
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


RECORD_COLUMNS = (
    "time",
    "diag_id",
    "device_id",
    "device",
    "type",
    "gs",
    "counting_head",
    "channel",
    "address",
    "label",
    "label_canonical",
    "label_encoding",
    "data",
    "value",
    "data_kind",
    "subsecond",
    "file",
    "file_seq",
    "line",
)
_RECORD_COLUMNS = ", ".join(RECORD_COLUMNS)


def record_batches(
    root: Path,
    manifest: Manifest,
    window: Window = Window(),
    tables: Collection[str] | None = None,
    *,
    labels: Collection[str] | None = None,
) -> Iterator[pa.RecordBatch]:
    """The records (in file, line order: the order a batch read sees them), in Arrow batches.

    ``tables``: only these views are built (a partition's derivation needs only ``records``).
    ``labels``: only the records of these canonical labels (the health registers).
    """
    if not manifest.parts("records"):
        return
    import shutil
    import tempfile

    from console.archive.store import TMP

    (root / TMP).mkdir(parents=True, exist_ok=True)
    spill = Path(tempfile.mkdtemp(prefix="duckdb-", dir=root / TMP))
    con, _ = connect(root, manifest, spill_dir=spill, tables=tables)
    try:
        where, params = window.where()
        if labels is not None:
            where += (" AND " if where else " WHERE ") + "label_canonical IN (SELECT unnest(?))"
            params.append(sorted(labels))
        rel = con.sql(f"SELECT {_RECORD_COLUMNS} FROM records{where} ORDER BY file_seq, line", params=params)
        yield from rel.to_arrow_reader(BATCH_ROWS)
    finally:
        con.close()
        shutil.rmtree(spill, ignore_errors=True)


def diag_job(root: Path, manifest: Manifest, window: Window = Window()) -> DiagJob | None:
    """What ``analyze_files`` returns for the archive's diagnostic records (None: there are none)."""
    from console.analysis.diagnostics import DiagAccumulator
    from console.archive.records import ChunkRebuilder
    from console.drivers.batch import DiagJob
    from console.engine.pipeline import HEALTH_REGISTERS
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
    report = parse_reports(root, manifest)["diagnostic"]
    report.unknown_labels.update(rebuild.registry.unknown_labels())
    files = [f.file for f in report.files]
    return DiagJob(files=files, report=report, analysis=analysis, kept_records=records)


def health_records(root: Path, manifest: Manifest, window: Window = Window()) -> pd.DataFrame:
    """The records of the health registers, as ``diag_job`` keeps them (without reading the other records).

    Read with pyarrow, part by part, filtered by label as each part is read: a DuckDB connection
    costs ~50 MB of memory to open, more than these few records.
    """
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    from console.archive.partition import key_of_part
    from console.archive.records import ChunkRebuilder
    from console.engine.pipeline import HEALTH_REGISTERS
    from parsers.diag import DiagChunk, chunks_to_frame

    wanted = pc.field("label_canonical").isin(sorted(HEALTH_REGISTERS))
    if window.start is not None:
        wanted &= pc.field("time") >= pa.scalar(window.start, pa.timestamp("ns"))
    if window.end is not None:
        wanted &= pc.field("time") < pa.scalar(window.end, pa.timestamp("ns"))
    if window.head is not None:
        wanted &= pc.field("counting_head") == window.head
    tables = []
    for rel in manifest.parts("records"):
        key = key_of_part(rel)
        if key is None or (window.device_id is not None and key.device_id != window.device_id):
            continue
        if (window.start is not None and key.day < window.start.date()) or (
            window.end is not None and key.day > window.end.date()
        ):
            continue
        t = pq.read_table(root / rel, filters=wanted, partitioning=None)
        if t.num_rows:
            t = t.cast(
                pa.schema(
                    [pa.field(f.name, f.type.value_type) if pa.types.is_dictionary(f.type) else f for f in t.schema]
                )
            )
            tables.append(t.append_column("device_id", pa.array(np.full(t.num_rows, key.device_id, np.int32))))
    rebuild = ChunkRebuilder()
    kept: list[DiagChunk] = []
    if tables:
        table = pa.concat_tables(tables, promote_options="permissive").select(list(RECORD_COLUMNS))
        order = np.lexsort((table.column("line").to_numpy(), table.column("file_seq").to_numpy()))
        for batch in table.take(pa.array(order)).to_batches(BATCH_ROWS):
            kept += rebuild.chunks(batch)
    return chunks_to_frame(kept, rebuild.registry)


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
    root: Path,
    layout_spec: str | None = None,
    window: Window = Window(),
    manifest: Manifest | None = None,
    *,
    job: DiagJob | Literal["read", "history"] | None = "read",
    streamed: tuple[list[Any], list[str], Any] | None = None,
) -> ReportData:
    """The report's data, from the archive (the inputs listed are the archived files).

    The same steps as :func:`console.report.collect.collect`, in the same
    order, on the archived tables instead of freshly parsed files.
    ``job``: the diagnostic job when the caller has it (the derivation builds it
    from the per-partition rows, :mod:`console.archive.derive`; the parse
    reports are then not rebuilt); ``"read"``: recomputed from the records;
    ``"history"``: read from the derived tables (:mod:`console.archive.history_diag`;
    the caller checks :func:`~console.archive.history_diag.derived_for` first).
    ``streamed``: the job's events already run (the derivation's bounded-memory
    step): (the channel events health reads, the warnings, the section engine's
    result or None); ``data.events`` is then left empty.
    """
    import pandas as pd

    from console.analysis.health import Finding, sort_findings, voltage_margin_findings
    from console.drivers.batch import health_findings
    from console.report.collect import _sections, crossings_from_fixes, frames_from_tables
    from console.report.model import InputFile, ReportData
    from parsers.can_logs import count_frames_only
    from parsers.report import ParseReport

    m = manifest if manifest is not None else read_current(root)
    spec = layout_spec if layout_spec is not None else m.derived.get("layout")
    layout = _layout(spec)
    settings = speed_settings(m, layout)
    active = sorted((e for e in m.files if e.get("active", True)), key=lambda e: int(e["file_seq"]))
    kind_of = {int(e["file_seq"]): str(e["kind"]) for e in active}
    inputs = [InputFile(str(e["path"]), str(e["kind"]), True, "from the archive") for e in active]
    data = ReportData(inputs=inputs, layout=layout, settings=settings)
    reports: dict[str, ParseReport] = parse_reports(root, m) if job in ("read", "history") else defaultdict(ParseReport)

    findings: list[Finding] = []
    if job == "history":
        from console.archive.history_diag import history_diag

        found = history_diag(root, m, layout, settings, window)
        job = None if found is None else found.job
        if found is not None:
            streamed = (found.channel_events, found.warnings, found.sections)
    elif job == "read":
        job = diag_job(root, m, window)
    if job is not None:
        data.job = job
        data.reports["diagnostic"] = job.report
        if streamed is not None:
            health_events, ev_warnings, sections = streamed
            if sections is not None:
                data.sections, data.section_source = sections, "diagnostic"
        else:
            data.events, ev_warnings = _detection_events(job, layout)
            health_events = data.events
        data.warnings += ev_warnings
        findings += health_findings(job, layout, health_events, None)

    frames = _per_file_tables(root, m, "frames")
    text = [df for seq, df in frames if kind_of.get(seq) == "frames"]
    can = [df for seq, df in frames if kind_of.get(seq) == "can"]
    tables: list[pd.DataFrame] = []
    if text:
        tables.append(_frame_window(pd.concat(text, ignore_index=True), window))
        data.reports["frames"] = reports["frames"]
    if can:
        tables.append(count_frames_only(_frame_window(pd.concat(can, ignore_index=True), window)))
        data.reports["can"] = reports["can"]
    frames_from_tables(data, tables)

    volts = _per_file_tables(root, m, "voltages")
    if volts:
        data.reports["voltages"] = reports["voltages"]
        findings += voltage_margin_findings(pd.concat([df for _, df in volts], ignore_index=True))
    data.findings = sort_findings(findings)

    _sections(data)
    fixes_parts = _per_file_tables(root, m, "fixes")
    if not fixes_parts:
        data.notes["crossings"] = "No level-crossing timelines: no GNSS telemetry among the inputs."
        return data
    fixes = pd.concat([p for _, p in fixes_parts], ignore_index=True)
    # parse_gnss sorts the fixes of all its files by time, stably, unknown times last.
    fixes = fixes.sort_values("time", kind="stable", na_position="last").reset_index(drop=True)
    data.reports["gnss"] = reports["gnss"]
    crossings_from_fixes(data, _cut_fixes(fixes, window))
    return data


def _frame_window(frames: pd.DataFrame, window: Window) -> pd.DataFrame:
    import pandas as pd

    if window.start is not None:
        frames = frames[frames["time"] >= pd.Timestamp(window.start)]
    if window.end is not None:
        frames = frames[frames["time"] < pd.Timestamp(window.end)]
    return frames


REPORT_KINDS = {
    "diagnostic": "diagnostic",
    "frames": "frames",
    "can": "can",
    "voltages": "voltages",
    "nmea": "gnss",
    "gnss-csv": "gnss",
    "gnss-jsonl": "gnss",
    "centre": "gnss",
}


def parse_reports(root: Path, manifest: Manifest) -> dict[str, ParseReport]:
    """Per report section (diagnostic, frames, can, voltages, gnss): the parse report of the archived files.

    Rebuilt from each file's accounting in the ledger and its rejected lines,
    in file order, the first MAX_REJECTIONS_KEPT kept as a read of the files would.
    """
    from collections import Counter

    from parsers.report import FileReport, ParseReport, Rejection

    out: dict[str, ParseReport] = {k: ParseReport() for k in set(REPORT_KINDS.values())}
    section_of: dict[int, str] = {}
    for e in sorted(manifest.files, key=lambda e: int(e["file_seq"])):
        section = REPORT_KINDS.get(str(e["kind"]))
        if section is None or not e.get("active", True) or "report" not in e:
            continue
        section_of[int(e["file_seq"])] = section
        rep = out[section]
        known = set(FileReport.__dataclass_fields__)
        rep.files.append(FileReport(**{k: v for k, v in e["report"].items() if k in known}))
        rep.rejected_by_reason.update(Counter(e.get("rejected_by_reason", {})))
        rep.skipped.update(Counter(e.get("skipped", {})))
    if manifest.parts("rejected") and section_of:
        con, _ = connect(root, manifest)
        try:
            rows = con.execute(
                "SELECT file_seq, file, line, reason, text FROM rejected ORDER BY file_seq, line"
            ).fetchall()
        finally:
            con.close()
        for seq, f, line, reason, text in rows:
            section = section_of.get(int(seq))
            if section is None:
                continue
            rep = out[section]
            if len(rep.rejections) < rep.max_rejections_kept:
                rep.rejections.append(Rejection(str(f), int(line), str(reason), str(text)))
    return out


def _cut_fixes(fixes: pd.DataFrame, window: Window) -> pd.DataFrame:
    """Fixes inside the window (zone-aware fix times are compared in UTC)."""
    import pandas as pd

    tz = getattr(fixes["time"].dt, "tz", None)

    def stamp(t: dt.datetime) -> pd.Timestamp:
        ts = pd.Timestamp(t)
        return ts.tz_localize("UTC") if tz is not None else ts

    if window.start is not None:
        fixes = fixes[fixes["time"] >= stamp(window.start)]
    if window.end is not None:
        fixes = fixes[fixes["time"] < stamp(window.end)]
    return fixes


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


def archive_collector(
    archive: Path | None,
    layout: str | None,
    start: str | None,
    end: str | None,
    head: str | None,
    device_id: int | None,
) -> Callable[[], ReportData]:
    """For ``report --archive``: a collector giving the report's data from the archive, errors as one line."""
    from console.archive.store import ArchiveError, archive_dir
    from console.archive.views import require_archive
    from console.report.collect import ReportInputError

    root = archive_dir(archive)

    def collector() -> ReportData:
        # Errors raised here reach the report's one-line error handling.
        try:
            window = Window(
                start=parse_time(start) if start else None,
                end=parse_time(end) if end else None,
                head=head,
                device_id=device_id,
            )
        except ValueError as exc:
            raise ReportInputError(f"--from/--to: {exc}") from None
        try:
            from console.archive.history_diag import derived_for

            m = require_archive(root)
            # The derived tables when they hold this report (the layout they were derived with), else the records.
            how: Literal["read", "history"] = "history" if derived_for(m, layout) else "read"
            return report_data(root, layout, window, manifest=m, job=how)
        except ArchiveError as exc:
            raise ReportInputError(str(exc)) from None

    return collector


def replay_inputs(root: Path, layout: Layout, window: Window = Window()) -> tuple[list[Any], pd.DataFrame | None]:
    """For ``station --replay --archive``: (detection events in time order, GNSS fixes in time order) of a window.

    The same events and fixes the station view's ReplaySource builds from files
    (``detection_events`` over the records, the archived fixes).
    """
    from console.archive.views import require_archive

    m = require_archive(root)
    job = diag_job(root, m, window)
    events = _detection_events(job, layout)[0] if job is not None else []
    fixes = None
    parts = _per_file_tables(root, m, "fixes")
    if parts:
        import pandas as pd

        fixes = pd.concat([p for _, p in parts], ignore_index=True)
        fixes = fixes.sort_values("time", kind="stable", na_position="last").reset_index(drop=True)
        fixes = _cut_fixes(fixes, window)
    return sorted(events, key=lambda e: e.time_ns), fixes


def _detection_events(job: DiagJob, layout: Layout | None) -> tuple[list[DetectionEvent], list[str]]:
    """The stored wheel records' detection events on the layout, or on their own heads when none is given."""
    from console.analysis.diag_events import DiagEventSettings, diag_detection_events
    from console.layout import layout_from_heads

    lay = layout or layout_from_heads(sorted({name for _, name in job.analysis.heads}))
    return diag_detection_events(job.analysis, lay, DiagEventSettings())
