"""`report --archive` gives the report of the original files, apart from the list of inputs."""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from console.archive.history import replay_inputs, report_data
from console.archive.reader import Window
from console.cli.app import app
from console.drivers.batch import ReadOptions
from tests.conftest import SAMPLES

runner = CliRunner()


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    arc = tmp_path_factory.mktemp("report") / "arc"
    res = runner.invoke(app, ["ingest", str(SAMPLES), "--archive", str(arc), "--layout", "example"])
    assert res.exit_code == 0, res.output
    return arc


def test_json_report_from_the_archive_equals_the_report_on_the_files(archive: Path) -> None:
    from_files = runner.invoke(app, ["report", str(SAMPLES), "--layout", "example", "--format", "json"])
    from_archive = runner.invoke(app, ["report", "--archive", str(archive), "--format", "json"])
    assert from_files.exit_code == from_archive.exit_code == 0, from_archive.output
    a, b = json.loads(from_archive.stdout), json.loads(from_files.stdout)
    a_inputs, b_inputs = a.pop("inputs"), b.pop("inputs")
    # Only the archive has history: its report adds the daily trends (tests/test_archive_trends.py) and the
    # forecast from them (tests/test_forecast.py).
    assert "trends" not in b and a.pop("trends")["axles_per_head_per_day"]
    assert "forecast" not in b and sum(a.pop("forecast")["counts"].values()) > 0
    assert a == b
    # The inputs list names the archived files (absolute), every one the files' report read.
    read = {Path(f["file"]).name for f in b_inputs["files"] if f["read"]}
    assert {Path(f["file"]).name for f in a_inputs["files"]} == read
    assert a["passages"] and a["sections"] and a["crossings"] and a["health"]


def test_markdown_report_from_the_archive_differs_only_in_the_inputs(archive: Path) -> None:
    def body(text: str) -> list[str]:
        # Input rows name files; the header line and the total row count them.
        skip = ("Layout:", "| **total** |")
        return [ln for ln in text.splitlines() if "sample\\_logs" not in ln and not ln.startswith(skip)]

    md_files = runner.invoke(app, ["report", str(SAMPLES), "--layout", "example"]).stdout
    md_archive = runner.invoke(app, ["report", "--archive", str(archive)]).stdout
    # The archive's report ends with its trends part, which a report on files has not.
    md_archive, trends = md_archive.split("\n## 8. Trends per day\n")
    assert "### Axles per head per day" in trends and "## 8. Trends" not in md_files
    assert body(md_archive) == body(md_files)
    assert "| **total** |" in md_archive


def test_a_window_and_a_head_cut_the_history(archive: Path) -> None:
    whole = report_data(archive)
    one = report_data(archive, window=Window(head="WS2"))
    assert whole.job is not None and one.job is not None
    assert set(one.job.analysis.passages["counting_head"]) == {"WS2"}
    assert len(one.job.analysis.passages) < len(whole.job.analysis.passages)
    t0 = int(one.job.analysis.passages["start_ns"].min())
    later = report_data(archive, window=Window(start=_dt(t0 + 600 * 10**9), head="WS2"))
    assert later.job is not None
    assert later.job.analysis.passages["start_ns"].min() >= t0 + 600 * 10**9


def test_the_derived_tables_give_the_report_the_records_give(archive: Path) -> None:
    # report --archive reads the derived tables; recomputing every analysis from the records is the oracle.
    from console.archive.history_diag import derived_for
    from console.archive.store import read_current
    from console.sinks.report.command import render

    assert derived_for(read_current(archive), None)
    history = render(report_data(archive, job="history"), "json")
    assert history == render(report_data(archive, job="read"), "json")
    doc = json.loads(history)
    assert doc["passages"] and doc["sections"]["timeline"] and doc["sections"]["ledger"] and doc["devices"]


def test_a_window_is_the_history_cut_to_it(archive: Path) -> None:
    whole = report_data(archive, job="history")
    assert whole.job is not None and whole.sections is not None
    p = whole.job.analysis.passages
    ordered = sorted(p["start_ns"].tolist())
    # Cut through the busy hours, just after a passage's start (window bounds are whole microseconds).
    a, b = (ordered[len(ordered) * i // 3] // 1000 * 1000 + 1000 for i in (1, 2))
    cut = report_data(archive, window=Window(start=_dt(a), end=_dt(b)), job="history")
    assert cut.job is not None and cut.sections is not None
    # Passages: those starting in the window, no more, no less (a passage belongs to the window it starts in).
    starts = p["start_ns"].to_numpy()
    want = sorted(starts[(starts >= a) & (starts < b)].tolist())
    assert sorted(cut.job.analysis.passages["start_ns"].tolist()) == want and want
    # Section states: the whole timeline's rows in the window; each section's final state is the last before b.
    tl = whole.sections.timeline
    inside = tl[(tl["time_ns"] >= a) & (tl["time_ns"] < b)]
    assert cut.sections.timeline["time_ns"].tolist() == inside["time_ns"].tolist()
    for sid, (state, *_rest) in cut.sections.final.items():
        before = tl[(tl["section"] == sid) & (tl["time_ns"] < b)]
        if len(before):
            assert state == before["state"].iloc[-1], sid
    led = whole.sections.ledger
    n_in = int(((led["time_ns"] >= a) & (led["time_ns"] < b) & (led["delta"] > 0)).sum())
    assert sum(v[2] for v in cut.sections.final.values()) == n_in
    # The devices are those with records in the window, each counting only those records.
    assert sum(d.records for d in cut.job.analysis.devices) < sum(d.records for d in whole.job.analysis.devices)


def test_a_report_with_another_layout_is_recomputed_from_the_records(archive: Path) -> None:
    from console.archive.history_diag import derived_for
    from console.archive.store import read_current

    m = read_current(archive)
    assert derived_for(m, "example") and not derived_for(m, "osong")


def test_an_archive_on_read_only_media_is_still_read_from_its_records(
    archive: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Reading the records made DuckDB's spill folder inside the archive: on a read-only snapshot, or another
    user's archive, `report --archive A --layout osong` and `station --replay --archive` ended with
    "internal error: OSError: [Errno 30] Read-only file system"."""
    import errno
    import tempfile

    made = tempfile.mkdtemp

    def read_only(*args: object, **kw: object) -> str:
        if str(kw.get("dir", "")).startswith(str(archive)):
            raise OSError(errno.EROFS, "Read-only file system", str(kw["dir"]))
        return made(*args, **kw)  # type: ignore[call-overload,no-any-return]

    monkeypatch.setattr(tempfile, "mkdtemp", read_only)
    res = runner.invoke(app, ["report", "--archive", str(archive), "--layout", "osong", "--format", "json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["passages"]
    records, _ = replay_inputs(archive)
    assert records is not None and sum(len(c) for c in records.open(ReadOptions())[1]) > 0


def test_bad_window_and_missing_archive_are_one_line_errors(tmp_path: Path, archive: Path) -> None:
    res = runner.invoke(app, ["report", "--archive", str(archive), "--from", "yesterday"])
    assert res.exit_code == 2 and res.stderr.startswith("trackside: error: --from/--to")
    res = runner.invoke(app, ["report", "--archive", str(tmp_path / "none")])
    assert res.exit_code == 2 and "no archive here yet" in res.stderr


def test_replay_inputs_are_the_records_and_the_fixes_in_time_order(archive: Path) -> None:
    from console.drivers.batch import ReadOptions

    records, fixes = replay_inputs(archive)
    assert records is not None
    _registry, chunks, _report = records.open(ReadOptions())
    assert sum(len(c) for c in chunks) > 0
    assert fixes is not None and len(fixes) and fixes["time"].is_monotonic_increasing


def _dt(ns: int) -> dt.datetime:
    return dt.datetime(1970, 1, 1) + dt.timedelta(microseconds=ns // 1000)


def test_passages_read_as_columns_equal_those_read_as_a_table(archive: Path) -> None:
    # The history reads a window's passages straight into the pipeline's columns; a head the manifest does not
    # list makes it read them as a table instead (the unlisted head's passages after the listed ones, by time).
    # Unlisting the last head keeps the order, so both reads must write the same passages, byte for byte (the
    # heads' list also says which heads the layout does not count: the warnings differ).
    import dataclasses

    from console.archive.store import read_current
    from console.sinks.report.command import render

    m = read_current(archive)
    heads = m.derived["heads"]
    assert len(heads) > 1
    fewer = dataclasses.replace(m, derived={**m.derived, "heads": heads[:-1]})
    for window in (Window(), Window(head=heads[-1][1]), Window(device_id=int(heads[-1][0]))):
        columns = report_data(archive, window=window, manifest=m, job="history")
        table = report_data(archive, window=window, manifest=fewer, job="history")
        assert columns.job is not None and table.job is not None
        # The columns read builds no table; the other read holds one.
        assert "passages" not in columns.job.analysis.__dict__ and "passages" in table.job.analysis.__dict__
        for fmt, start, end in (("json", '"passages": [', '"sections":'), ("md", "## 4. ", "## 5. ")):
            a, b = render(columns, fmt), render(table, fmt)
            part = a[a.index(start) : a.index(end)]
            assert part == b[b.index(start) : b.index(end)], (window, fmt)
            assert len(part) > 1000
