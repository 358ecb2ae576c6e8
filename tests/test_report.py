"""`trackside report` (issue 7): one document from every analysis, in Markdown, HTML and JSON.

Golden files: ``tests/golden/report.md`` and ``tests/golden/report.json`` are
the report of ``sample_logs/example_station.log`` (axle counting, sections,
a missed axle), ``sample_logs/crossing_example.csv`` (two trains over two
level crossings) and ``sample_logs/am_thuong_2021-06-06_voltages.csv``
(seed 000's receiver voltages) on the shipped layout ``example``: together
they fill every part of the report but the analog plot.  After a deliberate
change of the report, regenerate them and review the diff::

    UPDATE_GOLDEN=1 python -m pytest tests/test_report.py

The Chromium test (skipped where Debian's ``chromium`` is not installed)
opens the HTML of a simulated 2-hour run headless, takes a screenshot of the
whole page, and fails on any console message Chromium logs (``--enable-logging
=stderr`` prints each as an ``INFO:CONSOLE`` line: script errors, blocked
loads, Content-Security-Policy violations).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import struct
import subprocess
from pathlib import Path

import pytest

from console.analysis.crossing.timeline import TimelineRow
from console.analysis.crossing_batch import CrossingRun
from console.analysis.health.findings import Severity
from console.analysis.passages.speed_settings import SpeedSettings
from console.inputs.recognise import expand, natural_key
from console.layout import load_layout
from console.live.simulated import SimulatedConsole
from console.output_path import write_atomic
from console.sim.line_values import SimConfig
from console.sim.station import StationSim
from console.sim.writers import write_run
from console.sinks.report import command, html
from console.sinks.report.command import run_report
from console.sinks.report.document import document
from console.sinks.report.model import ReportData
from tests.conftest import ROOT, record

GOLDEN = Path(__file__).parent / "golden"
SAMPLE_INPUTS = [
    "sample_logs/example_station.log",
    "sample_logs/crossing_example.csv",
    "sample_logs/am_thuong_2021-06-06_voltages.csv",
]
PAYLOADS = ("<script>alert(1)</script>", "[bold red]x[/]", "\x1b[31m", "| pipe |", "# heading")


def _report(
    capsys: pytest.CaptureFixture[str],
    inputs: list[str | Path],
    fmt: str = "json",
    layout: str | None = None,
    fail_on: str | None = None,
    output: Path | None = None,
) -> tuple[int, str, str]:
    capsys.readouterr()
    code = run_report([Path(p) for p in inputs], layout, fmt, output, fail_on)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def at_root(monkeypatch: pytest.MonkeyPatch) -> Path:
    """Run from the repository root, so input paths are the relative ones the golden files record."""
    monkeypatch.chdir(ROOT)
    return ROOT


def _simulate(directory: Path, minutes: float, seed: int = 3) -> Path:
    sim = StationSim(load_layout("example"), SimConfig(seed=seed))
    SimulatedConsole(sim)  # as `simulate` runs it: the centre table shows the console's warnings
    sim.run(minutes * 60)
    write_run(sim, directory)
    return directory


@pytest.fixture(scope="module")
def sim_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _simulate(tmp_path_factory.mktemp("sim20") / "run", 20)


# ----------------------------------------------------------------------------- golden files


@pytest.mark.parametrize("fmt, name", [("md", "report.md"), ("json", "report.json")])
def test_sample_report_matches_the_golden_file(
    at_root: Path, capsys: pytest.CaptureFixture[str], fmt: str, name: str
) -> None:
    code, out, err = _report(capsys, list(SAMPLE_INPUTS), fmt, layout="example")
    assert (code, err) == (0, "")
    golden = GOLDEN / name
    if os.environ.get("UPDATE_GOLDEN"):
        golden.parent.mkdir(exist_ok=True)
        golden.write_text(out, encoding="utf-8")
    assert out == golden.read_text(encoding="utf-8"), f"regenerate with UPDATE_GOLDEN=1 if the change is meant: {name}"


def test_sample_report_finds_what_the_samples_document(at_root: Path, capsys: pytest.CaptureFixture[str]) -> None:
    doc = json.loads(_report(capsys, list(SAMPLE_INPUTS), layout="example")[1])
    assert doc["schema"] == "trackside.report/1"
    # sample_logs/README.md: B1 and B2 disturbed at 09:04:01 by WS3's missed axle; B1 32 in / 31 out.
    final = {s["section"]: s for s in doc["sections"]["final"]}
    assert final["B1"]["state"] == final["B2"]["state"] == "disturbed"
    assert (final["B1"]["count_in"], final["B1"]["count_out"]) == (32, 31)
    # Sections that end disturbed are failing, not unsafe; sensor 8's 186 mV margin is a warning (seed 000).
    assert doc["verdict"] == "failing"
    subjects = {(i["class"], i["subject"]) for i in doc["safety"]["items"]}
    assert subjects == {("failing", "section B1"), ("failing", "section B2"), ("failing", "sensor 8")}
    # Both trains at both crossings, lead times as `trackside crossing` gives them.
    leads = {(r["crossing"], r["train"]): r["lead_time_s"] for r in doc["crossings"]["timelines"]}
    assert set(leads) == {("11+850", "A"), ("11+850", "B"), ("12+940", "A"), ("12+940", "B")}
    assert doc["crossings"]["violations"] == 0
    # Per-second and whole-train speeds on every train passage.
    trains = [p for p in doc["passages"] if p["kind"] == "train"]
    assert len(trains) == 20 and all(p["speed_kmh_whole_train"] for p in trains)
    assert doc["status_bursts"] > 0 and all(p["kind"] != "status" for p in doc["passages"])


def test_json_is_ascii_and_versioned(at_root: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = _report(capsys, list(SAMPLE_INPUTS), layout="example")[1]
    assert out.isascii() and out.endswith("}\n")
    assert list(json.loads(out))[:3] == ["schema", "trackside_version", "layout"]


# ----------------------------------------------------------------------------- scripting


@pytest.mark.parametrize("fmt", ["md", "html", "json"])
def test_the_same_inputs_give_the_same_bytes(at_root: Path, tmp_path: Path, fmt: str) -> None:
    paths = [Path(p) for p in SAMPLE_INPUTS]
    a, b = tmp_path / f"a.{fmt}", tmp_path / f"b.{fmt}"
    assert run_report(paths, "example", fmt, a, None) == 0
    assert run_report(paths, "example", fmt, b, None) == 0
    assert a.read_bytes() == b.read_bytes()
    assert str(tmp_path) not in a.read_text(encoding="utf-8")  # no temporary path leaks into the report


def test_with_output_nothing_is_printed_and_without_it_only_the_report(
    at_root: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "r.md"
    code, out, err = _report(capsys, list(SAMPLE_INPUTS), "md", "example", output=target)
    assert (code, out, err) == (0, "", "")
    code, out, err = _report(capsys, list(SAMPLE_INPUTS), "md", "example")
    assert (code, err) == (0, "") and out == target.read_text(encoding="utf-8")


def test_a_failed_render_leaves_the_old_report_untouched(
    at_root: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "report.html"
    target.write_text("the old report\n")

    def broken(*args: object) -> str:
        raise RuntimeError("renderer crashed half-way")

    monkeypatch.setattr(html, "render_html", broken)  # the command imports it when asked for HTML
    code, out, err = _report(capsys, list(SAMPLE_INPUTS), "html", "example", output=target)
    assert code == 2 and out == ""
    assert err.startswith("trackside: error: internal error: RuntimeError") and err.count("\n") == 1
    assert target.read_text() == "the old report\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.html"]


def test_a_failed_write_leaves_no_partial_file(
    at_root: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "report.json"
    target.write_text("{}\n")

    def disk_full(src: object, dst: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("console.output_path.os.replace", disk_full)
    code, _, err = _report(capsys, list(SAMPLE_INPUTS), "json", "example", output=target)
    assert code == 2 and "No space left on device" in err
    assert target.read_text() == "{}\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.json"]


def test_an_atomic_write_replaces_the_file_with_an_ordinary_mode(tmp_path: Path) -> None:
    target = tmp_path / "r.md"
    write_atomic(target, b"one\n")
    umask = os.umask(0)
    os.umask(umask)
    assert target.read_bytes() == b"one\n" and (target.stat().st_mode & 0o777) == 0o666 & ~umask
    target.chmod(0o640)
    write_atomic(target, b"two\n")
    assert target.read_bytes() == b"two\n" and (target.stat().st_mode & 0o777) == 0o640


def test_a_killed_writers_temporary_file_goes_at_the_next_write_a_live_ones_stays(tmp_path: Path) -> None:
    """`kill -9` of `report -o r.html` left `.r.html.XXXX.tmp` for ever (the target itself is always whole)."""
    import signal
    import socket
    import sys

    target = tmp_path / "r.html"
    host = socket.gethostname().replace(".", "_")[:32]
    # A writer killed mid-write, with the name the real write gives its temporary file.
    code = (
        "import os, signal, sys; from pathlib import Path; from console.output_path import atomic_file\n"
        "with atomic_file(Path(sys.argv[1])) as f:\n"
        "    f.write(b'half'); f.flush(); print(flush=True); os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    killed = subprocess.run([sys.executable, "-c", code, str(target)], capture_output=True, timeout=60, cwd=ROOT)
    assert killed.returncode == -signal.SIGKILL
    [stale] = tmp_path.glob(f".r.html.{host}-*.tmp")
    live = tmp_path / f".r.html.{host}-{os.getpid()}.abcdefgh.tmp"  # a write of this (running) process
    other_host = tmp_path / ".r.html.elsewhere-1.abcdefgh.tmp"  # another machine's, on a shared folder
    live.write_bytes(b"")
    other_host.write_bytes(b"")
    write_atomic(target, b"whole\n")
    assert target.read_bytes() == b"whole\n"
    assert not stale.exists() and live.exists() and other_host.exists()


# ----------------------------------------------------------------------------- exit codes


@pytest.mark.parametrize(("fail_on", "expected"), [(None, 0), ("info", 1), ("warning", 1), ("CRITICAL", 0)])
def test_fail_on_compares_findings_and_failing_items(
    at_root: Path, capsys: pytest.CaptureFixture[str], fail_on: str | None, expected: int
) -> None:
    # The samples' worst: warnings (sensor 8's margin; B1 and B2 ended disturbed), nothing critical.
    assert _report(capsys, list(SAMPLE_INPUTS), "json", "example", fail_on)[0] == expected


def test_a_crossing_safety_violation_is_unsafe_and_critical() -> None:
    row = TimelineRow(
        "12+940", "B", 0, 60_000_000_000, 90_000_000_000, 80_000_000_000, 60.0, -10.0, "ETA", "EOT", (),
        ("warning off before the tail cleared the crossing",), None, None, None,
    )  # fmt: skip
    data = ReportData(inputs=[], layout=None, settings=SpeedSettings(), crossing=CrossingRun([row], [], []))
    doc = document(data)
    assert doc["verdict"] == "unsafe" and doc["safety"]["unsafe"] == 1
    assert doc["safety"]["items"][0]["message"] == "warning off before the tail cleared the crossing"
    assert command.exit_code(data, Severity.CRITICAL) == 1 and command.exit_code(data, None) == 0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ({"fmt": "pdf"}, "--format: expected md, html or json, found 'pdf'"),
        ({"fail_on": "severe"}, "--fail-on: severity: expected one of info, warning, critical"),
        ({"layout": "nowhere.toml"}, "nowhere.toml: no such layout file"),
        ({"inputs": ["sample_logs/missing.log"]}, "sample_logs/missing.log: no such file or directory"),
        ({"inputs": []}, "give input files or directories"),
    ],
)
def test_usage_errors_are_one_line_and_exit_2(
    at_root: Path, capsys: pytest.CaptureFixture[str], args: dict[str, object], message: str
) -> None:
    kwargs: dict[str, object] = {"inputs": list(SAMPLE_INPUTS), "fmt": "md", "layout": "example", "fail_on": None}
    kwargs.update(args)
    code, out, err = _report(capsys, **kwargs)  # type: ignore[arg-type]
    assert (code, out) == (2, "")
    assert err.startswith("trackside: error: " + message) and err.count("\n") == 1


def test_an_unreadable_file_is_an_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "broken.log.gz"
    bad.write_bytes(b"\x1f\x8b\x08\x00 this is not deflate data at all")
    code, out, err = _report(capsys, [bad])
    assert (code, out) == (2, "") and err.startswith(f"trackside: error: {bad}: ")


def test_inputs_of_which_none_can_be_read_are_an_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "notes.txt").write_text("shopping list\n")
    code, _, err = _report(capsys, [tmp_path])
    assert code == 2 and "no input in a format trackside reads" in err


def test_inputs_that_give_no_record_but_rejected_lines_are_an_error_not_an_ok(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Every line rejected (dates no time can hold): it wrote "Verdict: OK" over nothing, where analyze refuses.
    good = ROOT / "sample_logs/example_station.log"
    bad = tmp_path / "far_future.log"
    bad.write_text(good.read_text("utf-8").replace("Date:2026-", "Date:9999-"), "utf-8")
    for fmt in ("md", "json"):
        code, out, err = _report(capsys, [bad], fmt, "example")
        assert (code, out) == (2, "") and err.count("\n") == 1
        assert err.startswith("trackside: error: nothing readable in the inputs: ")
        assert f"none read; {bad} line 1: Date: date out of range" in err
    # Beside a file that reads, the report is made and shows the rejected one.
    code, out, err = _report(capsys, [bad, good], "json", "example")
    assert (code, err) == (0, "")
    rows = {Path(f["file"]).name: f for f in json.loads(out)["inputs"]["files"]}
    assert rows[bad.name]["records"] == 0 and rows[bad.name]["rejected"] == rows[bad.name]["lines_read"] > 0


# ----------------------------------------------------------------------------- inputs


def test_a_simulated_run_directory_is_read_whole(sim_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _report(capsys, [sim_dir])
    assert (code, err) == (0, "")
    doc = json.loads(out)
    files = {Path(f["file"]).relative_to(sim_dir).as_posix(): f for f in doc["inputs"]["files"]}
    assert files["diagnostic.log"]["format"] == "diagnostic" and files["diagnostic.log"]["read"]
    assert files["layout.toml"]["note"] == "the layout used" and doc["layout"] == str(sim_dir / "layout.toml")
    assert files["truth.json"]["format"] == "truth" and not files["truth.json"]["read"]
    assert files["sensor_frames.txt"]["format"] == "frames" and files["centre.tsv"]["format"] == "centre"
    assert files["gnss_devices.csv"]["format"] == "gnss-csv"
    assert all(f["format"] == "nmea" for name, f in files.items() if name.startswith("nmea/"))
    assert list(files) == sorted(files, key=natural_key)  # a directory's files in (natural) sorted order
    assert doc["sections"]["events_from"] == "diagnostic" and doc["sections"]["initial"] == "unknown"
    assert {s["section"] for s in doc["sections"]["final"]} == {"1G", "B1", "B2", "2G"}
    assert doc["crossings"]["timelines"] and doc["sensors"] and doc["gnss_units"]
    assert any(p["kind"] == "train" and p["speed_kmh_per_axle_mean"] for p in doc["passages"])


def test_a_report_written_into_its_input_directory_is_not_read_back(
    sim_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = sim_dir / "report.json"
    assert run_report([sim_dir], None, "json", target, None) == 0
    first = target.read_bytes()
    assert run_report([sim_dir], None, "json", target, None) == 0
    assert target.read_bytes() == first
    target.unlink()


def test_a_directory_is_read_in_natural_order_and_a_file_given_twice_once(tmp_path: Path) -> None:
    for name in ("T10.nmea", "T2.nmea", "sub/T1.nmea"):
        (tmp_path / name).parent.mkdir(exist_ok=True)
        (tmp_path / name).write_text("$GPTXT,01,01,02,x*00\n")
    files, warnings = expand([tmp_path, tmp_path / "T2.nmea"])
    assert [p.relative_to(tmp_path).as_posix() for p in files] == ["sub/T1.nmea", "T2.nmea", "T10.nmea"]
    assert warnings == [f"{tmp_path / 'T2.nmea'}: given twice, read once"]


def test_unrecognised_and_empty_files_are_listed_as_not_read(
    at_root: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "README.txt").write_text("what this folder holds\n")
    (tmp_path / "empty.log").write_bytes(b"")
    (tmp_path / "photo.bin").write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + bytes(64))
    (tmp_path / ".hidden").write_text("x\n")
    shutil.copy(ROOT / "sample_logs/osong_ws4_0932_detection.log", tmp_path / "ws4.log")
    code, out, err = _report(capsys, [tmp_path])
    assert (code, err) == (0, "")
    doc = json.loads(out)
    files = {Path(f["file"]).name: f for f in doc["inputs"]["files"]}
    assert set(files) == {"README.txt", "empty.log", "photo.bin", "ws4.log"}
    assert files["README.txt"]["note"] == "not read: unrecognised format, first line 'what this folder holds'"
    assert files["empty.log"]["format"] == "empty" and not files["empty.log"]["read"]
    assert "binary" in files["photo.bin"]["note"]
    assert files["ws4.log"]["read"] and files["ws4.log"]["records"] == 34
    assert any("1 hidden entries" in w for w in doc["warnings"])


def test_html_is_self_contained_and_printable(at_root: Path, capsys: pytest.CaptureFixture[str]) -> None:
    page = _report(capsys, list(SAMPLE_INPUTS), "html", "example")[1]
    assert "<script" not in page.lower() and "@media print" in page and "@page{size:A4" in page
    # Nothing to fetch: the only URL is the SVG namespace, and links are in-page anchors.
    assert set(re.findall(r"https?://[^\s\"'<>)]+", page)) == {"http://www.w3.org/2000/svg"}
    assert all(v.startswith(("#", "url(#")) for v in re.findall(r'(?:href|src)="([^"]*)"', page))
    # Speed, sections and crossings plots; the samples have no analog values.
    assert page.count("<svg") == 3
    for title in ("Speed per passage", "Section states over time", "Crossing warnings against head and tail arrival"):
        assert f"<title>{title}</title>" in page


def test_analog_values_are_plotted_per_head(at_root: Path, capsys: pytest.CaptureFixture[str]) -> None:
    page = _report(capsys, ["sample_logs/ws4_health.log"], "html")[1]
    assert "<title>Analog values at WS4</title>" in page and "<title>Analog values at WS5</title>" in page
    doc = json.loads(_report(capsys, ["sample_logs/ws4_health.log"])[1])
    # sample_logs/README.md: Adr 134 reads about 14 above Adr 136 (the paper's 2416 / 2402).
    means = {(a["counting_head"], a["channel"], a["address"]): a["mean"] for a in doc["health"]["analog"]}
    assert means[("WS4", 1, 134)] - means[("WS4", 1, 136)] == pytest.approx(14, abs=2)
    assert doc["verdict"] == "unsafe"  # WS5 Sys2 has drifted out of its band: critical


# ----------------------------------------------------------------------------- injection


def _injection_inputs(directory: Path) -> list[Path]:
    """A diagnostic log whose heads and labels are hostile, a GNSS stream whose device names are,
    and a file name that is."""
    lines = []
    for i, p in enumerate(PAYLOADS):
        head = p.replace("\x1b", "ESC") if i == 2 else p  # an ESC in Trackinfo is rejected: keep it in a label
        t = f"09:3{i}:00"
        lines.append(record(label=p, data="5", time=t).replace("Trackinfo:WS4", f"Trackinfo:{head}"))
        for ch, ms, v in ((1, "000", 1), (2, "026", 1), (1, "200", 0), (2, "226", 0)):
            rec = record(ch=ch, adr="026", label="Radsensor", data=str(v), time=f"09:3{i}:01.{ms}")
            lines.append(rec.replace("Trackinfo:WS4", f"Trackinfo:{head}"))
    lines.append(record(label="x", time="09:40:00").replace("Trackinfo:WS4", "Trackinfo:\x1b[31m"))
    name = "inj_<img src=x onerror=alert(1)>_[b]x_|p|_\x1b[31m.log"
    log = directory / name
    log.write_text("\n".join(lines) + "\n", encoding="utf-8")
    gnss = directory / "units.csv"
    rows = ["time,device,role,lat,lon,speed"]
    for k, p in enumerate(PAYLOADS):
        rows.append(f'2026-01-19T17:00:0{k}Z,"{p}",head,20.75,105.89,10')
    gnss.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return [log, gnss]


def _broken_tables(md: str) -> list[str]:
    """Tables whose lines do not all have the same number of unescaped pipes (cell boundaries)."""
    tables = re.findall(r"(?:^\|.*\n)+", md, flags=re.M)
    assert tables
    return [t for t in tables if len({len(re.findall(r"(?<!\\)\|", ln)) for ln in t.splitlines()}) != 1]


def test_log_content_stays_inert_in_every_format(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    inputs = _injection_inputs(tmp_path)
    outputs = {}
    for fmt in ("md", "html", "json"):
        target = tmp_path / "out" / f"report.{fmt}"
        target.parent.mkdir(exist_ok=True)
        assert run_report(inputs, None, fmt, target, None) == 0
        outputs[fmt] = target.read_bytes()
        # No raw ESC or C1 control byte can reach a terminal that prints the report.
        assert b"\x1b" not in outputs[fmt] and b"\xc2\x9b" not in outputs[fmt], fmt
    page = outputs["html"].decode("utf-8")
    assert "<script" not in page.lower() and "<img" not in page.lower()
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in page  # shown, as text
    assert "[bold red]x[/]" in page and "\\x1b[31m" in page  # Rich markup is plain text in HTML
    md = outputs["md"].decode("utf-8")
    assert "<script" not in md and "<img" not in md and "&lt;script&gt;" in md
    assert "\\[bold red\\]x\\[/\\]" in md and "\\| pipe \\|" in md and "\\# heading" in md
    assert not re.search(r"^# heading", md, flags=re.M)
    assert _broken_tables(md) == []
    doc = json.loads(outputs["json"])
    assert outputs["json"].isascii()
    heads = {h for d in doc["devices"] for h in d["counting_heads"]}
    assert {"<script>alert(1)</script>", "[bold red]x[/]", "| pipe |", "# heading"} <= heads  # data kept as is
    assert {u["device"] for u in doc["gnss_units"]} == set(PAYLOADS)
    # An ESC in a label or a Trackinfo gets the line rejected; the line is shown with the ESC escaped.
    assert doc["inputs"]["totals"]["rejected"] == 2
    assert all("\\x1b[31m" in r["text"] for r in doc["inputs"]["rejections"])


# ----------------------------------------------------------------------------- Chromium


def _png_size(path: Path) -> tuple[int, int]:
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    width, height = struct.unpack(">II", head[16:24])
    return width, height


@pytest.mark.skipif(shutil.which("chromium") is None, reason="Debian's chromium is not installed")
@pytest.mark.parametrize("case", ["simulated-2h", "analog-ws4"])
def test_html_opens_in_headless_chromium_without_console_errors(tmp_path: Path, case: str) -> None:
    if case == "simulated-2h":
        inputs = [_simulate(tmp_path / "run", 120, seed=1)]
        window = (1200, 16000)  # the whole page: every plot is in the screenshot
    else:
        inputs = [ROOT / "sample_logs/ws4_health.log"]
        window = (1200, 3000)
    page = tmp_path / "report.html"
    assert run_report(inputs, None, "html", page, None) in (0, 1)
    shot = tmp_path / "report.png"
    proc = subprocess.run(
        [
            "chromium", "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update", "--disable-sync",
            f"--user-data-dir={tmp_path / 'profile'}", "--enable-logging=stderr", "--v=0",
            f"--screenshot={shot}", f"--window-size={window[0]},{window[1]}", page.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=180,
        check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert shot.exists() and _png_size(shot) == window
    assert shot.stat().st_size > 50_000  # a blank page compresses to a few kB
    console = [ln for ln in proc.stderr.splitlines() if ":CONSOLE" in ln or "Uncaught" in ln]
    assert console == [], "\n".join(console)
