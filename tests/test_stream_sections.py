"""Sections, health and their events from a streamed read equal the whole-file path (issue 12).

:func:`console.stream_jobs.stream_diag` reads a log in chunks, counts each
batch of closed passages through per-head counters and releases the events
to the section engine below a watermark.  The whole-file path holds every
wheel record, then every event.  Over realistic multi-board logs (µs, ms and
whole-second boards interleaved, damaged lines) and simulated runs with
faults (missed wheels, lone pulses, power losses, dead channels, damped
heads), at chunk sizes down to a few records, with and without a power gap,
operator resets and a short isolation time, both give the same section
timeline, ledger, resets and final states, the same warnings, and the same
health findings.  The CLI's ``sections --json`` (history spilled to disk and
copied in) is the document the whole-file result gives.

CI runs a few examples; ``TRACKSIDE_LONG=1`` runs many more.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from benchmarks.bench_memory_commands import write_layout
from benchmarks.gen_realistic_diag import generate
from console.analysis.counting.wheels import CountingSettings
from console.analysis.diag_events import DiagEventSettings
from console.analysis.events.detection import DetectionEvent, EventKind
from console.analysis.passages.speed_settings import SpeedSettings
from console.analysis.sections.engine import ledger_summary_frame, run_sections
from console.analysis.sections.state import SectionState
from console.cli.app import app
from console.drivers.batch import health_findings
from console.engine.pipeline import HEALTH_REGISTERS
from console.jsonout import dumps
from console.layout import Layout, load_layout
from console.sim.faults import Fault
from console.sim.line_values import SimConfig
from console.sim.station import StationSim
from console.sim.writers import write_diagnostic
from console.sinks.tables.section_history import LedgerText, SectionsSink, ledger_json
from console.sinks.tables.section_tables import sections_json
from tests.reads import detection_events, pipeline_sections, whole_job

LONG = bool(os.environ.get("TRACKSIDE_LONG"))
EXAMPLES = 150 if LONG else 4
# A chunk costs about a millisecond of fixed work: CI's logs are small enough for chunks of one record.
RECORDS = (300, 5000) if LONG else (200, 600)
SIM_RUN_S = 3 * 3600 if LONG else 900

CASE = settings(
    max_examples=EXAMPLES,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
SPEED = SpeedSettings(spacing_m=0.13, train_length_m=28.6, idle_gap_s=10.0)
POWER_GAPS = st.sampled_from([None, 5.0, 45.0])
ISOLATIONS = st.sampled_from([5.0, 60.0])


def assert_streamed_equals_whole(
    path: Path,
    layout: Layout | None,
    chunk_bytes: int,
    es: DiagEventSettings,
    resets: list[DetectionEvent] = (),  # type: ignore[assignment]
    initial: SectionState = SectionState.PREPARATORY,
) -> int:
    """Both paths over one log; returns the number of events the whole path found."""
    job = whole_job([path], SPEED, keep_registers=HEALTH_REGISTERS, keep_releases=True)
    events, warnings = detection_events(job, layout, es)
    sections_lay = layout if layout is not None and layout.sections else None
    sink = SectionsSink(keep_all=True) if sections_lay is not None else None
    run = pipeline_sections(
        [path],
        SPEED,
        layout=layout,
        event_settings=es,
        sections_layout=sections_lay,
        resets=resets,
        initial=initial,
        sink=sink,
        keep_registers=HEALTH_REGISTERS,
        chunk_bytes=chunk_bytes,
    )
    assert run.warnings == warnings
    assert run.report.to_dict() == job.report.to_dict()
    whole_findings = [f.to_dict() for f in health_findings(job, layout, events)]
    assert [f.to_dict() for f in health_findings(run, layout)] == whole_findings
    assert (run.last_event.time_ns if run.last_event else None) == (events[-1].time_ns if events else None)
    if sections_lay is not None:
        assert run.sections is not None and sink is not None
        whole = run_sections(sections_lay, [*events, *resets], initial=initial)
        sk = sink
        streamed = run.sections.result(sk.timeline_all, sk.ledger_all, sk.reset_rows)
        assert sections_json(streamed) == sections_json(whole)
        assert ledger_summary_frame(sk.ledger_totals).values.tolist() == whole.ledger_summary().values.tolist()
        assert (sk.timeline_rows, sk.ledger_rows) == (len(whole.timeline), len(whole.ledger))
        assert sk.timeline_first == sk.timeline_all[: len(sk.timeline_first)]
        fast = LedgerText()
        assert [fast(x) for x in sk.ledger_all] == [ledger_json(x) for x in sk.ledger_all]
    return len(events)


def _resets(layout: Layout, times: list[int]) -> list[DetectionEvent]:
    sections = [s.id for s in layout.sections]
    return [
        DetectionEvent(t, EventKind.RESET, sections[i % len(sections)], source="operator", detail="--reset")
        for i, t in enumerate(times)
    ]


@pytest.fixture(scope="module")
def bench_layout(tmp_path_factory: pytest.TempPathFactory) -> Layout:
    path = tmp_path_factory.mktemp("layout") / "layout.toml"
    write_layout(path, boards=6)
    return load_layout(str(path))


@CASE
@given(
    records=st.integers(*RECORDS),
    boards=st.integers(2, 6),
    seed=st.integers(1, 10_000),
    interleave=st.integers(0, 2**31),
    chunk_bytes=st.integers(64, 50_000),
    power_gap=POWER_GAPS,
    isolation=ISOLATIONS,
    with_layout=st.booleans(),
)
def test_realistic_log_streamed_in_any_chunks_gives_the_whole_file_sections_and_health(
    tmp_path: Path,
    bench_layout: Layout,
    records: int,
    boards: int,
    seed: int,
    interleave: int,
    chunk_bytes: int,
    power_gap: float | None,
    isolation: float,
    with_layout: bool,
) -> None:
    path = tmp_path / "real.log"
    generate(records, path, boards=boards, seed=seed, interleave_seed=interleave)
    es = DiagEventSettings(counting=CountingSettings(isolation_s=isolation), power_gap_s=power_gap)
    n = assert_streamed_equals_whole(path, bench_layout if with_layout else None, chunk_bytes, es)
    assert n > 0


@pytest.fixture(scope="module")
def faulty_run() -> StationSim:
    faults = (
        Fault("missed_detections", "WS3", 150.0, 500.0, channel=2, probability=0.3),
        Fault("isolated_pulse", "WS2", 250.0),
        Fault("isolated_pulse", "WS4", 600.0),
        Fault("power_loss", "WS5", 350.0, 420.0),
        Fault("dead_channel", "WS1", 650.0, 720.0, channel=1),
        Fault("damped_head", "WS4", 780.0, 820.0),
    )
    sim = StationSim(load_layout("example"), SimConfig(seed=11, trains_per_hour=30, faults=faults))
    sim.run(SIM_RUN_S)
    return sim


@CASE
@given(
    resolution=st.sampled_from(["us", "ms", "s", "mixed"]),
    interleave=st.integers(0, 2**31),
    chunk_bytes=st.integers(64, 100_000),
    power_gap=POWER_GAPS,
    isolation=ISOLATIONS,
    reset_offsets=st.lists(st.integers(0, SIM_RUN_S), max_size=3),
    initial=st.sampled_from([SectionState.PREPARATORY, SectionState.CLEAR]),
)
def test_simulated_faulty_run_streamed_in_any_chunks_gives_the_whole_file_sections_and_health(
    tmp_path: Path,
    faulty_run: StationSim,
    resolution: str,
    interleave: int,
    chunk_bytes: int,
    power_gap: float | None,
    isolation: float,
    reset_offsets: list[int],
    initial: SectionState,
) -> None:
    heads = [h.id for h in faulty_run.layout.heads]
    res: str | dict[str, str] = (
        {h: ("us", "ms", "s")[i % 3] for i, h in enumerate(heads)} if resolution == "mixed" else resolution
    )
    path = tmp_path / "sim.log"
    write_diagnostic(faulty_run, path, resolution=res, interleave_seed=interleave)
    es = DiagEventSettings(counting=CountingSettings(isolation_s=isolation), power_gap_s=power_gap)
    start = faulty_run.cfg.start_ns
    resets = _resets(faulty_run.layout, [start + s * 1_000_000_000 for s in reset_offsets])
    assert assert_streamed_equals_whole(path, faulty_run.layout, chunk_bytes, es, resets, initial) > 0


def _line(head: str, ch: int, value: int, when: str, device: int = 4081) -> str:
    return (
        f"Diag_id:00002\tID:{device}\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:{head}\tch:{ch}\tAdr:026\t"
        f"Label:Radsensor\tData:{value}\tDate:2026-03-02\tTime:{when}\n"
    )


def test_a_head_that_changes_its_facts_mid_log_is_read_again_with_the_whole_log_facts(tmp_path: Path) -> None:
    # WS1 writes onsets only at first (point mode), releases from its second passage on;
    # WS2 stamps milliseconds at first, whole seconds later.  The first passages say the
    # opposite of the whole log: the stream notices and reads again.
    lines = [
        _line("WS1", 1, 1, "09:00:00.100"),
        _line("WS1", 2, 1, "09:00:00.110"),
        _line("WS2", 1, 1, "09:00:00.300", 4082),
        _line("WS2", 2, 1, "09:00:00.310", 4082),
        _line("WS2", 1, 0, "09:00:00.400", 4082),
        _line("WS2", 2, 0, "09:00:00.410", 4082),
    ]
    for k in range(3):
        m = 10 + k
        lines += [
            _line("WS1", 1, 1, f"09:{m}:00.100"),
            _line("WS1", 2, 1, f"09:{m}:00.110"),
            _line("WS1", 1, 0, f"09:{m}:00.200"),
            _line("WS1", 2, 0, f"09:{m}:00.210"),
            _line("WS2", 1, 1, f"09:{m}:30", 4082),
            _line("WS2", 2, 1, f"09:{m}:30", 4082),
            _line("WS2", 1, 0, f"09:{m}:31", 4082),
            _line("WS2", 2, 0, f"09:{m}:31", 4082),
        ]
    path = tmp_path / "changing.log"
    path.write_text("".join(lines), encoding="utf-8")
    layout = load_layout("example")
    run = pipeline_sections([path], SPEED, layout=layout, event_settings=DiagEventSettings(), chunk_bytes=200)
    assert run.reads == 2
    assert assert_streamed_equals_whole(path, layout, 200, DiagEventSettings()) > 0


def test_sections_json_from_the_cli_is_the_whole_file_document(tmp_path: Path, faulty_run: StationSim) -> None:
    path = tmp_path / "sim.log"
    write_diagnostic(faulty_run, path, resolution="ms")
    layout = load_layout("example")
    res = CliRunner().invoke(app, ["sections", str(path), "--layout", "example", "--json", "--power-gap", "45"])
    assert res.exit_code in (0, 1), res.output
    job = whole_job([path], SPEED, keep_releases=True)
    events, warnings = detection_events(job, layout, DiagEventSettings(power_gap_s=45.0))
    whole = run_sections(layout, events)
    doc = {
        "schema": "trackside.sections/1",
        "files": job.files,
        "layout": layout.source,
        "parse_report": job.report.to_dict(),
        "warnings": warnings,
        **sections_json(whole),
    }
    assert res.stdout == dumps(doc) + "\n"
    assert len(json.loads(res.stdout)["ledger"]) == len(whole.ledger) > 0


def test_sections_table_counts_every_change_though_it_keeps_only_the_first(tmp_path: Path) -> None:
    path = tmp_path / "real.log"
    generate(30_000, path, boards=2, seed=5)
    layout_path = tmp_path / "layout.toml"
    write_layout(layout_path, boards=2)
    layout = load_layout(str(layout_path))
    job = whole_job([path], SPEED, keep_releases=True)
    events, _ = detection_events(job, layout, DiagEventSettings(counting=CountingSettings(isolation_s=5.0)))
    whole = run_sections(layout, events, initial=SectionState.CLEAR)
    res = CliRunner().invoke(
        app, ["sections", str(path), "--layout", str(layout_path), "--initial", "clear", "--isolation", "5"]
    )
    assert res.exit_code == 0, res.output
    assert f"State timeline ({len(whole.timeline)} changes)" in res.stdout
    if len(whole.timeline) > 200:
        assert f"first 200 of {len(whole.timeline)}" in res.stdout
