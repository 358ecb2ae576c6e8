"""`trackside report` in bounded memory (issue 12): the streamed report is the whole-document report.

A diagnostic log's passages and section history are spooled to disk as the
log is read and the report is written as it is rendered
(:mod:`console.sinks.report.spooled`, :mod:`console.sinks.report.jsonwrite`).  The old
path holds them as tables (``collect(whole=True)``, as the archive's report
does) and serialises the whole document at once (:func:`console.sinks.report.document.json_text`).
Both give the same bytes in every format, on the shipped samples, simulated
runs and realistic multi-board logs with and without a layout, and with
several files (read whole).  The JSON writer is ``json.dumps(indent=1)``
piece by piece; ``-o`` stays atomic while the file is written in pieces.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from benchmarks.bench_memory_commands import write_layout
from benchmarks.gen_realistic_diag import generate
from console.analysis.sections.state import LedgerEntry, SectionState, Transition
from console.jsonout import valid_unicode
from console.layout import load_layout
from console.sim.faults import Fault
from console.sim.line_values import SimConfig
from console.sim.station import StationSim
from console.sim.writers import write_run
from console.sinks.report import command, markdown, outline
from console.sinks.report.collect import collect
from console.sinks.report.command import CHUNK_CHARS, render, render_to, run_report
from console.sinks.report.document import document, json_text
from console.sinks.report.jsonwrite import Rows, indented, write_json
from console.sinks.report.model import ReportData
from console.sinks.report.spooled import ROW_DEPTH, _transition_text
from console.sinks.tables.section_history import SPILL_BLOCK_BYTES, LedgerText
from console.sinks.tables.section_tables import sections_json
from tests.conftest import ROOT

FORMATS = ("md", "html", "json")
SAMPLES = [
    ROOT / "sample_logs" / "example_station.log",
    ROOT / "sample_logs" / "crossing_example.csv",
    ROOT / "sample_logs" / "am_thuong_2021-06-06_voltages.csv",
]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[list[Path], str | None]]:
    """Report inputs by name: (files or directories, layout)."""
    tmp = tmp_path_factory.mktemp("report-stream")
    sim = tmp / "sim"
    run = StationSim(load_layout("example"), SimConfig(seed=5))
    run.run(40 * 60)
    write_run(run, sim)
    faulty = tmp / "faulty"
    faults = (
        Fault("missed_detections", "WS3", 150.0, 500.0, channel=2, probability=0.3),
        Fault("isolated_pulse", "WS2", 250.0),
        Fault("power_loss", "WS5", 350.0, 420.0),
        Fault("dead_channel", "WS1", 650.0, 720.0, channel=1),
        Fault("damped_head", "WS4", 780.0, 820.0),
    )
    cfg = SimConfig(seed=9, faults=faults)
    run = StationSim(load_layout("example"), cfg)
    run.run(30 * 60)
    write_run(run, faulty)
    log, other = tmp / "realistic.log", tmp / "other.log"
    generate(50_000, log, boards=4, seed=7)
    generate(8_000, other, boards=4, seed=8, resolution="s")
    layout = tmp / "layout.toml"
    write_layout(layout, boards=4)
    return {
        "samples": (SAMPLES, "example"),
        "simulated run": ([sim], None),
        "simulated faults": ([faulty], None),
        "realistic log": ([log], str(layout)),
        "realistic log, no layout": ([log], None),
        "two logs (read whole)": ([log, other], str(layout)),
    }


def _plain(value: Any) -> Any:
    """The document with every Rows made a plain list of its items (the ledger's dicts, built alone)."""
    if isinstance(value, Rows):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


def _streamed_and_whole(
    given: tuple[list[Path], str | None], fmt: str | None = None
) -> Iterator[tuple[ReportData, ReportData]]:
    paths, layout = given
    streamed = collect(paths, layout, for_format=fmt)
    whole = collect(paths, layout, whole=True)
    try:
        yield streamed, whole
    finally:
        streamed.close()
        whole.close()


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize(
    "case",
    [
        "samples",
        "simulated run",
        "simulated faults",
        "realistic log",
        "realistic log, no layout",
        "two logs (read whole)",
    ],
)
def test_the_streamed_report_is_the_whole_document_report(
    inputs: dict[str, tuple[list[Path], str | None]], whole_of: Callable[[str], ReportData], case: str, fmt: str
) -> None:
    paths, layout = inputs[case]
    streamed = collect(paths, layout, for_format=fmt)
    try:
        whole = whole_of(case)
        text = render(streamed, fmt)
        assert text == render(whole, fmt)
        if fmt == "json":
            # The old serialiser: the whole document as plain values (long lists made item by item), one json.dumps.
            assert text == valid_unicode(json_text(_plain(document(whole))))
        assert len(text) > 10_000
    finally:
        streamed.close()


@pytest.fixture(scope="module")
def whole_of(inputs: dict[str, tuple[list[Path], str | None]]) -> Iterator[Callable[[str], ReportData]]:
    """An input's whole-document report data, collected once for the three formats (it does not depend on
    the format: the streamed one does, and is collected for each)."""
    made: dict[str, ReportData] = {}

    def whole(case: str) -> ReportData:
        if case not in made:
            paths, layout = inputs[case]
            made[case] = collect(paths, layout, whole=True)
        return made[case]

    yield whole
    for data in made.values():
        data.close()


def test_the_markdown_timeline_shows_its_first_rows_of_the_spool(
    inputs: dict[str, tuple[list[Path], str | None]], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(outline, "TIMELINE_ROWS_SHOWN", 7)
    for streamed, whole in _streamed_and_whole(inputs["simulated run"], "md"):
        text = render(streamed, "md")
        assert text == render(whole, "md")
        assert f"First 7 of {len(whole.sections.timeline):,} changes" in text  # type: ignore[union-attr]


def test_passage_places_and_plot_numbers_read_back_in_blocks_give_the_same_page(
    inputs: dict[str, tuple[list[Path], str | None]], monkeypatch: pytest.MonkeyPatch
) -> None:
    # The spool's records on disk read back a few at a time (blocks cut anywhere, trains picked from each).
    monkeypatch.setattr("console.sinks.tables.passage_spool._INDEX_ROWS", 37)
    for streamed, whole in _streamed_and_whole(inputs["realistic log"], "html"):
        assert len(streamed.passage_spool or []) > 37 * 10
        assert render(streamed, "html") == render(whole, "html")


def test_spilled_rows_read_back_are_the_whole_history(
    inputs: dict[str, tuple[list[Path], str | None]], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Rows cut across the spill's blocks are read back whole.
    monkeypatch.setattr("console.sinks.tables.section_history.SPILL_BLOCK_BYTES", 97)
    for streamed, whole in _streamed_and_whole(inputs["realistic log"]):
        assert streamed.history is not None and whole.sections is not None
        expected = sections_json(whole.sections)
        assert list(streamed.history.timeline()) == expected["timeline"]
        ledger = streamed.history.ledger()
        assert len(ledger) > 1000 and list(ledger) == expected["ledger"]
        # Written at a depth other than the spill's form: re-indented, as json.dumps would.
        pieces: list[str] = []
        ledger.write_json(pieces.append, 0)
        assert "".join(pieces) == json.dumps(expected["ledger"], ensure_ascii=True, indent=1)


def test_a_streamed_log_holds_no_passage_and_no_history_row_in_memory(
    inputs: dict[str, tuple[list[Path], str | None]],
) -> None:
    paths, layout = inputs["realistic log"]
    data = collect(paths, layout)
    try:
        assert data.job is not None and data.job.analysis.passage_columns is None
        assert data.sections is None and data.history is not None
        sink = data.history.sink
        assert sink.timeline_all == [] and sink.ledger_all == [] and sink.ledger_rows > 5000
        doc = document(data)
        assert isinstance(doc["passages"], Rows) and len(doc["passages"]) == len(data.passage_spool or [])
        assert isinstance(doc["sections"]["timeline"], Rows) and isinstance(doc["sections"]["ledger"], Rows)
        for fmt in FORMATS:
            pieces: list[str] = []
            render_to(data, fmt, pieces.append)
            # Written as it is made: a piece (at least) per passage; spilled rows copied a block at a time.
            assert len(pieces) > len(doc["passages"]) > 500
            assert max(map(len, pieces)) <= SPILL_BLOCK_BYTES
    finally:
        data.close()


# ----------------------------------------------------------------------------- the JSON writer

FINITE = st.floats(allow_nan=False, allow_infinity=False)  # json.dumps(allow_nan=False) refuses the others
JSON_SCALARS = st.none() | st.booleans() | st.integers(-(2**70), 2**70) | FINITE | st.text()
JSON_VALUES = st.recursive(
    JSON_SCALARS,
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=8), inner, max_size=5),
    max_leaves=30,
)


@settings(max_examples=300, deadline=None)
@given(value=JSON_VALUES, depth=st.integers(0, 6))
def test_indented_is_json_dumps_with_indent_one_at_any_depth(value: Any, depth: int) -> None:
    expected = json.dumps(value, ensure_ascii=True, indent=1, allow_nan=False).replace("\n", "\n" + " " * depth)
    assert indented(value, depth) == expected


@settings(max_examples=100, deadline=None)
@given(doc=st.dictionaries(st.text(max_size=8), JSON_VALUES, min_size=1, max_size=6), rows=st.lists(JSON_VALUES))
def test_write_json_with_rows_is_one_json_dumps_of_the_whole_document(doc: dict[str, Any], rows: list[Any]) -> None:
    lazy = {**doc, "nested": {"rows": Rows(len(rows), lambda: iter(rows)), "after": 1}}
    lazy["rows"] = Rows(len(rows), lambda: iter(rows))
    plain = {**doc, "nested": {"rows": rows, "after": 1}, "rows": rows}
    pieces: list[str] = []
    write_json(lazy, pieces.append)
    assert "".join(pieces) == valid_unicode(json_text(plain))


SECTION_NAMES = st.text(min_size=1, max_size=12) | st.sampled_from(["B1", "S\udcff", 'say "hi"', "\u202e"])


@settings(max_examples=200, deadline=None)
@given(
    section=SECTION_NAMES,
    head=SECTION_NAMES,
    time_ns=st.integers(0, 2**62),
    delta=st.sampled_from([-1, 1]),
    count=st.integers(-500, 500),
    reason=st.text(max_size=40),
    state=st.sampled_from(list(SectionState)),
)
def test_spilled_rows_are_the_report_json_of_their_row(
    section: str, head: str, time_ns: int, delta: int, count: int, reason: str, state: SectionState
) -> None:
    pad = "\n" + " " * ROW_DEPTH
    row = sections_json_row(time_ns, section=section, head=head, delta=delta, count=count)
    assert LedgerText(ROW_DEPTH)(LedgerEntry(time_ns, section, head, delta, count)) == pad + row
    tr = sections_json_row(time_ns, section=section, state=str(state), count=count, reason=reason)
    assert _transition_text(Transition(time_ns, section, state, count, reason)) == pad + tr


def sections_json_row(time_ns: int, **fields: Any) -> str:
    """A row as the whole document holds it (``sections_json``: the columns, then the time) at the rows' depth."""
    from console.analysis.timefmt import iso

    return valid_unicode(indented({**fields, "time": iso(time_ns)}, ROW_DEPTH))


# ----------------------------------------------------------------------------- -o written in pieces


def test_o_writes_a_temporary_file_in_pieces_and_a_failure_half_way_leaves_the_old_report(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "report.md"
    target.write_text("the old report\n")
    seen: list[int] = []

    def half_way(doc: dict[str, Any], write: Any) -> None:
        write("x" * (CHUNK_CHARS + 1))  # more than a chunk: on its way to disk
        seen.extend(p.stat().st_size for p in tmp_path.glob(".report.md.*.tmp"))
        raise RuntimeError("renderer crashed half-way")

    monkeypatch.setattr(markdown, "render_markdown", half_way)  # the command imports it when asked for Markdown
    code = run_report(SAMPLES, "example", "md", target, None)
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("trackside: error: internal error: RuntimeError")
    assert seen and seen[0] > CHUNK_CHARS  # the temporary file grew as the report was written
    assert target.read_text() == "the old report\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.md"]


def test_ctrl_c_while_writing_leaves_the_old_report(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "report.json"
    target.write_text("{}\n")

    def interrupted(doc: dict[str, Any], write: Any) -> None:
        write("x" * (CHUNK_CHARS + 1))
        raise KeyboardInterrupt

    monkeypatch.setattr(command, "write_json", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_report(SAMPLES, "example", "json", target, None)
    assert target.read_text() == "{}\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.json"]


def test_spool_files_are_gone_once_the_report_is_written(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    closed: list[str] = []
    real_close = ReportData.close

    def close(self: ReportData) -> None:
        closed.append("closed")
        real_close(self)
        assert self.history is None or self.history.sink._timeline.file.closed  # type: ignore[union-attr]

    monkeypatch.setattr(ReportData, "close", close)
    assert run_report(SAMPLES, "example", "md", tmp_path / "r.md", None) == 0
    assert closed == ["closed"]
    assert os.path.getsize(tmp_path / "r.md") > 1000


def test_a_report_on_diagnostic_logs_loads_no_frame_can_or_gnss_parser(tmp_path: Path) -> None:
    # The recogniser of kinds reads GNSS header names (parsers.gnss.headers, fields): no parser, no library.
    NOT_LOADED = (
        "can",
        "shapely",
        "pyubx2",
        "parsers.frames.sensor",
        "parsers.frames.can",
        "parsers.gnss.centre",
        "parsers.gnss.stream",
        "parsers.gnss.packets",
        "parsers.gnss_files",
    )
    # Those parsers and the libraries under them (python-can, shapely) cost ~20 MB of the 256 MB budget.
    code = (
        "import sys; from pathlib import Path; from console.sinks.report import run_report; "
        f"run_report([Path({str(SAMPLES[0])!r})], 'example', 'md', Path({str(tmp_path / 'r.md')!r}), None); "
        f"print(sorted(m for m in {NOT_LOADED!r} if m in sys.modules))"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "[]"
    assert (tmp_path / "r.md").read_text().startswith("# trackside report")
