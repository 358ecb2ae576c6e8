"""The command line as a user runs it: CliRunner and subprocesses; help, completion, standard input."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import typer
from hypothesis import given
from hypothesis import strategies as st
from typer.testing import CliRunner

from console.cli.app import app
from tests.conftest import ROOT, SAMPLES, record

runner = CliRunner()


def test_analyze_prints_inventory_passages_and_parse_report(samples: Path) -> None:
    res = runner.invoke(app, ["analyze", *map(str, sorted(samples.glob("osong_*.log")))], env={"COLUMNS": "120"})
    assert res.exit_code == 0, res.output
    for needle in ("Devices", "TMC", "4803", "Passages (3)", "15.9(34)", "14.5(31)", "17.24", "Parse report"):
        assert needle in res.output


def test_analyze_json_document(samples: Path) -> None:
    res = runner.invoke(app, ["analyze", str(samples / "ws4_subsecond.log"), "--json"])
    assert res.exit_code == 0
    doc = json.loads(res.stdout)
    assert doc["schema"] == "trackside.analyze/1"
    assert doc["files"] == [str(samples / "ws4_subsecond.log")]
    pr = doc["parse_report"]
    assert (pr["lines_read"], pr["records"], pr["rejected"], pr["rejections"]) == (100, 100, 0, [])
    assert [d["device_id"] for d in doc["devices"]] == [4083]
    p = doc["passages"][0]
    for key in (
        "counting_head",
        "start",
        "end",
        "records",
        "axles",
        "direction",
        "speed_kmh_per_second_method",
        "speed_kmh_whole_train",
        "speed_kmh_per_axle",
    ):
        assert key in p
    assert p["counting_head"] == "WS4" and p["axles"] == 8 and p["direction"] == "sys1_to_sys2"
    assert doc["passages"][1]["speed_kmh_whole_train"] is None  # null where unknown


def test_speeds_is_the_passages_table_alone(samples: Path) -> None:
    res = runner.invoke(app, ["speeds", str(samples / "osong_ws4_1732_passage.log")], env={"COLUMNS": "120"})
    assert res.exit_code == 0
    assert "17.24" in res.output and "Devices" not in res.output and "Parse report" not in res.output
    doc = json.loads(runner.invoke(app, ["speeds", str(samples / "osong_ws4_1732_passage.log"), "--json"]).stdout)
    assert round(doc["passages"][0]["speed_kmh_whole_train"], 2) == 17.24


def test_speeds_and_approach_say_a_line_was_rejected(tmp_path: Path, samples: Path) -> None:
    # A whole-second log with one line cut mid-field: the per-second count of its second lacks that record,
    # so the table's speed is not the paper's; the text output says a line was rejected, as analyze does.
    lines = (samples / "osong_ws4_0932_detection.log").read_bytes().splitlines(keepends=True)
    cut = tmp_path / "cut.log"
    cut.write_bytes(b"".join([*lines[:3], lines[3][:50] + b"\n", *lines[4:]]))
    for args in (["speeds", str(cut)], ["approach", str(cut), "--layout", "osong"]):
        res = runner.invoke(app, args, env={"COLUMNS": "120"})
        assert res.exit_code == 0, res.output
        assert "1 input line rejected (trackside analyze lists them)" in res.stdout


def test_speeds_of_status_records_alone_says_so(tmp_path: Path, samples: Path) -> None:
    wheel = (b"Label:Diagnose\t", b"Label:Radsensor\t")
    lines = (samples / "ws4_subsecond.log").read_bytes().splitlines(keepends=True)
    status = tmp_path / "status.log"
    status.write_bytes(b"".join(line for line in lines[:40] if not any(w in line for w in wheel)))
    res = runner.invoke(app, ["speeds", str(status)], env={"COLUMNS": "120"})
    assert res.exit_code == 0, res.output
    assert "Passages (0)" in res.stdout
    assert "1 status-only record burst (no wheel onset) not listed; --include-status lists them" in res.stdout


def test_missing_file_is_exit_2_with_one_line(tmp_path: Path) -> None:
    res = runner.invoke(app, ["analyze", str(tmp_path / "nope.log")])
    assert res.exit_code == 2
    assert res.stderr.strip() == f"trackside: error: {tmp_path / 'nope.log'}: no such file"
    assert "Traceback" not in res.output


def test_directory_is_exit_2(tmp_path: Path) -> None:
    res = runner.invoke(app, ["analyze", str(tmp_path)])
    assert res.exit_code == 2 and "is a directory" in res.stderr


def test_bad_option_is_exit_2(samples: Path) -> None:
    res = runner.invoke(app, ["analyze", str(samples / "ws4_subsecond.log"), "--idle-gap", "0.5"])
    assert res.exit_code == 2


def test_empty_file_is_not_an_error(tmp_path: Path) -> None:
    p = tmp_path / "empty.log"
    p.write_bytes(b"")
    res = runner.invoke(app, ["analyze", str(p), "--json"])
    assert res.exit_code == 0
    doc = json.loads(res.stdout)
    assert doc["parse_report"]["records"] == 0 and doc["passages"] == [] and doc["devices"] == []


def test_strict_makes_rejections_exit_1(tmp_path: Path) -> None:
    p = tmp_path / "bad.log"
    p.write_text(record() + "\n" + record(ch="x") + "\n", encoding="utf-8")
    assert runner.invoke(app, ["analyze", str(p)]).exit_code == 0
    res = runner.invoke(app, ["analyze", str(p), "--strict", "--json"])
    assert res.exit_code == 1
    (rej,) = json.loads(res.stdout)["parse_report"]["rejections"]
    assert (rej["file"], rej["line"]) == (str(p), 2) and "ch" in rej["reason"]


def test_corrupt_gzip_keeps_the_lines_before_it_and_is_a_finding(tmp_path: Path) -> None:
    import gzip

    data = gzip.compress(("\n".join([record()] * 2000) + "\n").encode())
    p = tmp_path / "cut.log.gz"
    p.write_bytes(data[: len(data) // 2])
    res = runner.invoke(app, ["analyze", str(p), "--json", "--strict"])
    assert res.exit_code == 1, res.stderr
    report = json.loads(res.stdout)["parse_report"]
    (rej,) = report["rejections"]
    assert 0 < report["records"] < 2000 and "corrupt gzip (truncated" in rej["reason"]


def test_log_content_never_becomes_markup_or_escapes(tmp_path: Path) -> None:
    p = tmp_path / "evil.log"
    lines = [
        record(label="[bold red]PWNED[/]"),
        record(label="Sum\x1b]0;title\x07"),  # rejected: shown escaped
        record().replace("Trackinfo:WS4", "Trackinfo:[link=http://x]WS4[/link]"),
        "\x1b[2J\x1b[31mjunk line\x9b31m",
    ]
    p.write_bytes(("\n".join(lines) + "\n").encode("utf-8"))
    res = runner.invoke(app, ["analyze", str(p)], env={"COLUMNS": "200"})
    assert res.exit_code == 0
    assert "\x1b" not in res.output and "\x9b" not in res.output and "\x07" not in res.output
    assert "[bold red]PWNED[/]" in res.output or "[bold red]PWNED[/]" in res.output.replace("\n", "")
    assert "[link=http://x]WS4[/link]" in res.output
    assert "\\x1b" in res.output  # the rejected junk is shown, escaped
    js = runner.invoke(app, ["analyze", str(p), "--json"]).stdout
    assert "\x1b" not in js and "\x9b" not in js
    json.loads(js)


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    exe = Path(sys.executable).with_name("trackside")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-c", "from console.cli.app import app; app()"]
    return subprocess.run([*cmd, *args], capture_output=True, text=True, cwd=ROOT, timeout=120)


def test_subprocess_quick_start_command() -> None:
    res = _run("analyze", *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "sample_logs").glob("osong_*.log")))
    assert res.returncode == 0, res.stderr
    assert "15.9" in res.stdout and "17.24" in res.stdout
    assert res.stderr == ""  # no progress bar when stderr is not a terminal


def test_piped_tables_keep_each_row_on_one_line() -> None:
    """Piped (no terminal, no COLUMNS), a file name is not cut at 80 columns: a script or grep gets it whole."""
    names = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "sample_logs").glob("osong_*.log"))
    env = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "LINES")}
    exe = Path(sys.executable).with_name("trackside")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-c", "from console.cli.app import app; app()"]
    piped = subprocess.run([*cmd, "analyze", *names], capture_output=True, text=True, cwd=ROOT, env=env, timeout=120)
    assert piped.returncode == 0, piped.stderr
    rows = [line for line in piped.stdout.splitlines() if "osong_ws4_" in line]
    assert [next(n for n in names if n in row) for row in rows] == names
    assert not [line for line in piped.stdout.splitlines() if line.endswith(" ")]  # no cell padding
    # A width asked for is still kept.
    narrow = subprocess.run(
        [*cmd, "analyze", *names], capture_output=True, text=True, cwd=ROOT, env={**env, "COLUMNS": "60"}, timeout=120
    )
    assert max(map(len, narrow.stdout.splitlines())) <= 60 and names[0] not in narrow.stdout


def test_speeds_takes_each_heads_spacing_from_a_layout(tmp_path: Path, samples: Path) -> None:
    from console.layouts import __file__ as layouts_init

    text = Path(layouts_init).with_name("example_station.toml").read_text(encoding="utf-8")
    mixed = tmp_path / "mixed.toml"
    mixed.write_text(text.replace("spacing_m = 0.13", "spacing_m = 0.2", 1), encoding="utf-8")  # WS1 only
    log = str(samples / "example_station.log")

    def axle_speeds(*extra: str) -> dict[str, list[float]]:
        res = runner.invoke(app, ["speeds", log, "--json", *extra])
        assert res.exit_code == 0, res.output
        got: dict[str, list[float]] = {}
        for p in json.loads(res.stdout)["passages"]:
            got.setdefault(p["counting_head"], []).extend(v for v in p["speed_kmh_per_axle"] or [] if v is not None)
        return got

    plain, per_head = axle_speeds(), axle_speeds("--layout", str(mixed))
    assert plain.keys() == per_head.keys() and plain["WS1"] and plain["WS2"]
    assert per_head["WS1"] == pytest.approx([v * 0.2 / 0.13 for v in plain["WS1"]], rel=1e-3)
    assert per_head["WS2"] == pytest.approx(plain["WS2"])
    assert axle_speeds("--layout", str(mixed), "--spacing", "0.13") == plain


def test_subprocess_json_and_exit_codes(tmp_path: Path) -> None:
    res = _run("analyze", "sample_logs/ws4_subsecond.log", "--json")
    assert res.returncode == 0 and json.loads(res.stdout)["parse_report"]["records"] == 100
    missing = _run("analyze", str(tmp_path / "missing.log"))
    assert missing.returncode == 2 and missing.stderr.count("\n") == 1 and "Traceback" not in missing.stderr


@pytest.mark.parametrize("cmd", [["--help"], ["analyze", "--help"], ["--version"]])
def test_help_and_version(cmd: list[str]) -> None:
    assert runner.invoke(app, cmd).exit_code == 0


@pytest.mark.parametrize("cmd", [["-h"], ["analyze", "-h"], ["report", "-h"]])
def test_h_is_help_as_in_most_tools(cmd: list[str]) -> None:
    # -h said "No such option: -h" (exit 2).
    res = runner.invoke(app, cmd)
    assert res.exit_code == 0 and res.stdout.startswith("Usage: trackside"), res.output


def test_help_as_a_command_points_to_the_help_not_to_health() -> None:
    # `trackside help` said "No such command 'help'. Did you mean 'health'?".
    for cmd in (["help"], ["help", "analyze"]):
        res = runner.invoke(app, cmd)
        assert res.exit_code == 2, res.output
        (line,) = res.stderr.strip().splitlines()
        assert "health" not in line and "trackside --help" in line and "trackside COMMAND --help" in line, line


def test_a_reader_that_stops_early_is_not_an_error() -> None:
    """`trackside analyze ... | head -1`: quiet, exit 0 (Rich alone would exit 1)."""
    exe = Path(sys.executable).with_name("trackside")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-c", "from console.cli.app import app; app()"]
    logs = sorted(str(p) for p in (ROOT / "sample_logs").glob("osong_*.log"))
    proc = subprocess.Popen([*cmd, "analyze", *logs], stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT)
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.read(10)
    proc.stdout.close()
    assert proc.wait(timeout=120) == 0
    assert proc.stderr.read() == b""


# --- help, completion, standard input ------------------------------------------------------

HELP_ENV = {"COLUMNS": "200", "TERM": "dumb"}


def _commands() -> list[tuple[str, Any]]:
    # Typer 0.29 carries its own copy of click: the group is duck-typed, not a click.Group.
    return sorted(typer.main.get_command(app).commands.items())  # type: ignore[attr-defined]


def _texts(cmd: Any) -> list[str]:
    texts = [cmd.help or "", cmd.epilog or ""]
    texts += [getattr(p, "help", None) or "" for p in cmd.params]
    return texts


def test_every_help_shows_its_bracketed_examples_literally() -> None:
    """Rich markup would eat `[[crossings]]` or `[:END[:CHANNEL]]`: help is plain text."""
    checked = 0
    for name, cmd in [("", typer.main.get_command(app)), *_commands()]:
        res = runner.invoke(app, [name, "--help"] if name else ["--help"], env=HELP_ENV)
        assert res.exit_code == 0, (name, res.output)
        shown = "".join(res.output.split())  # wrapping may split lines anywhere between words
        for text in _texts(cmd):
            for token in text.split():
                if "[" in token or "]" in token:
                    assert token in shown, (name, token)
                    checked += 1
    assert checked >= 8  # [[crossings]], [[track]], [[work_sites]], [,LENGTH_M], [:END[:CHANNEL]], ...


def test_help_cites_papers_by_author_never_by_seed_number() -> None:
    for name, _ in _commands():
        out = runner.invoke(app, [name, "--help"], env=HELP_ENV).output
        assert re.search(r"\bseed\s*0\d\d|\bseed's\b", out, re.IGNORECASE) is None, name


def test_shell_completion_is_offered(monkeypatch: pytest.MonkeyPatch) -> None:
    res = runner.invoke(app, ["--help"], env=HELP_ENV)
    assert "--install-completion" in res.output and "Exit codes: 0 ok" in res.output
    # The shell named, not guessed from the processes above the test (which differ between runners).
    monkeypatch.setenv("_TYPER_COMPLETE_TEST_DISABLE_SHELL_DETECTION", "1")
    script = runner.invoke(app, ["--show-completion", "bash"])
    assert script.exit_code == 0 and "_TRACKSIDE_COMPLETE" in script.output


# Every command that takes files, with a sample it reads from standard input and what shows it was read.
STDIN_CASES = [
    (["analyze", "-", "--json"], "ws4_subsecond.log", '"records":100'),
    (["speeds", "-", "--json"], "osong_ws4_1732_passage.log", '"passages"'),
    (["sections", "-", "--layout", "example", "--json"], "example_station.log", '"sections"'),
    (["health", "-", "--json"], "ws4_health.log", '"findings"'),
    (["health", "--voltages", "-", "--json"], "am_thuong_2021-06-06_voltages.csv", '"findings"'),
    (["frames", "-", "--json"], "sensor_frames.txt", '"frames"'),
    (["approach", "-", "--layout", "osong", "--json"], "osong_ws4_1732_passage.log", '"schema"'),
    (["gnss", "-", "--json"], "gnss_devices.csv", '"fixes"'),
    (["crossing", "-", "--layout", "example", "--json"], "crossing_example.csv", '"violations"'),
    (["report", "-", "--layout", "example", "--format", "json"], "example_station.log", '"diagnostic"'),
]


@pytest.mark.parametrize(("args", "sample", "needle"), STDIN_CASES, ids=lambda v: v[0] if isinstance(v, list) else "")
def test_dash_reads_standard_input(args: list[str], sample: str, needle: str, samples: Path) -> None:
    data = (samples / sample).read_bytes()
    res = runner.invoke(app, args, input=data)
    assert res.exit_code == 0, res.output
    assert needle in res.stdout
    json.loads(res.stdout)


# A real process costs 1-6 s on a loaded machine: `analyze` by default, every command with
# TRACKSIDE_SLOW_TESTS=1 (CliRunner covers each command's `-` in any case).
PIPE_CASES = STDIN_CASES if os.environ.get("TRACKSIDE_SLOW_TESTS") else STDIN_CASES[:1]


@pytest.mark.parametrize(("args", "sample", "needle"), PIPE_CASES, ids=lambda v: v[0] if isinstance(v, list) else "")
def test_dash_reads_a_real_pipe(args: list[str], sample: str, needle: str, samples: Path) -> None:
    """`zcat x.log.gz | trackside analyze -`: a pipe, not a file (no seek, no size)."""
    exe = Path(sys.executable).with_name("trackside")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-c", "from console.cli.app import app; app()"]
    cat = subprocess.Popen(["cat", str(samples / sample)], stdout=subprocess.PIPE)
    res = subprocess.run([*cmd, *args], stdin=cat.stdout, capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert cat.stdout is not None
    cat.stdout.close()
    cat.wait()
    assert res.returncode == 0, res.stderr
    assert needle in res.stdout
    json.loads(res.stdout)


def test_standard_input_twice_is_a_usage_error() -> None:
    res = runner.invoke(app, ["analyze", "-", "-"], input=b"")
    assert res.exit_code == 2 and res.stderr == "trackside: error: -: standard input given twice\n"


def test_bidi_controls_from_a_log_are_shown_escaped(tmp_path: Path) -> None:
    """U+202E in a field or a file name would display the rest of the line reversed."""
    p = tmp_path / "evil\u202egol.log"
    p.write_text(record() + "\n" + "junk \u2066spoof\u2069 \u202etxt.exe\n", encoding="utf-8")
    res = runner.invoke(app, ["analyze", str(p)], env={"COLUMNS": "250"})
    assert res.exit_code == 0, res.output
    assert not set("\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069\u200e\u200f\u061c") & set(res.output)
    assert "\\u202e" in res.output and "\\u2066" in res.output


def test_a_head_name_with_an_invisible_character_does_not_show_as_another_head(tmp_path: Path) -> None:
    """A head "WS4" and a head "WS4" + U+200B (zero-width space) showed as two identical "WS4" columns."""
    log = (SAMPLES / "osong_ws4_0932_detection.log").read_text(encoding="utf-8")
    twin = log.replace("ID:4083", "ID:4099").replace("Trackinfo:WS4", "Trackinfo:WS4\u200b")
    p = tmp_path / "two.log"
    p.write_text(log + twin, encoding="utf-8")
    res = runner.invoke(app, ["analyze", str(p)], env={"COLUMNS": "250"})
    assert res.exit_code == 0, res.output
    assert "\u200b" not in res.output and "WS4\\u200b" in res.output


# --- what reaches a terminal or a JSON reader, for any text ----------------------------------

_DANGEROUS = re.compile(
    r"[\x00-\x1f\x7f-\x9f\u061c\u180e\u200b-\u200f\u2028-\u202e\u2060-\u206f\ufeff\ud800-\udfff\U000e0000-\U000e007f]"
)


@given(st.text(alphabet=st.characters(codec=None, categories=None)))
def test_clean_leaves_no_control_bidi_or_surrogate_and_always_encodes(text: str) -> None:
    from console.safe_text import clean

    shown = clean(text)
    assert _DANGEROUS.search(shown) is None
    shown.encode("utf-8")  # never a UnicodeEncodeError on a terminal
    if _DANGEROUS.search(text) is None:
        assert shown == text  # ordinary text, any script, passes unchanged


@given(st.lists(st.text(alphabet=st.characters(codec=None, categories=None)), max_size=5))
def test_json_output_is_strict_utf8_json_for_any_strings(values: list[str]) -> None:
    from console.jsonout import dumps

    text = dumps({"files": values})
    doc = json.loads(text.encode("utf-8"))  # strict: no lone surrogate escapes
    for given_value, read in zip(values, doc["files"], strict=True):
        if not re.search(r"[\ud800-\udfff]", given_value):
            assert read == given_value  # everything else round-trips exactly
        else:
            read.encode("utf-8")
