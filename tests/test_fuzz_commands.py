"""Fuzz every command that takes files, in-process (Typer's CliRunner) and a few real processes.

Properties, for any input: the exit code is 0, 1 or 2; never "internal
error" and never a traceback; ``--json`` output parses whenever the command
ran (0 or 1); text output and error messages carry no raw control, bidi or
non-SGR escape character; no input file changes (nothing writes over an
input).  The inputs are the shipped samples damaged by the seeded mutator
of ``tests/fuzz_mutate.py``, under hostile file names too.

Then the regression tests of the "hostile input" issue, each a class the
fuzz properties above would also catch: UTF-16 / CR-only / NUL-in-a-field
GNSS tables, a FIFO, ``-`` and process substitution as input, truncated and
junk-tailed gzip to ``gnss`` and ``crossing``, a file name that is not
UTF-8, ``report -o`` aimed at an input.

CI runs a small derandomized set; the long run (see tests/test_fuzz_parsers.py)::

    pytest -m fuzz --hypothesis-profile long --hypothesis-show-statistics -p no:cacheprovider
"""

from __future__ import annotations

import gzip
import hashlib
import json
import os
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from typer.testing import CliRunner

from console.cli.app import app
from parsers.sources import release_streams
from tests.fuzz_mutate import TRIED, field_variants, fuzz_settings, mutate, unsafe_in, write_stats

pytestmark = pytest.mark.fuzz


@pytest.fixture(autouse=True)
def _tally() -> Iterator[None]:
    yield
    write_stats()


ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_logs"
runner = CliRunner()


# command -> (sample fuzzed, extra arguments); "{other}" files are passed unchanged.
COMMANDS: dict[str, tuple[str, list[str]]] = {
    "analyze": ("osong_ws4_0932_detection.log", []),
    "analyze-layout": ("example_station.log", ["--layout", "example"]),
    "speeds": ("ws4_subsecond.log", []),
    "sections": ("example_station.log", ["--layout", "example"]),
    "health": ("ws4_health.log", ["--voltages", str(SAMPLES / "am_thuong_2021-06-06_voltages.csv")]),
    "health-voltages": ("am_thuong_2021-06-06_voltages.csv", ["--voltages"]),
    "frames": ("sensor_frames.txt", []),
    "frames-can": ("can_counts.log", []),
    "approach": ("example_station.log", ["--layout", "example"]),
    "gnss": ("gnss_devices.csv", []),
    "gnss-jsonl": ("gnss_devices.jsonl", []),
    "crossing": ("crossing_example.csv", ["--layout", "example"]),
    "report": ("osong_ws4_0932_passage.log", ["--layout", "osong"]),
}
_HEAD_BYTES = 32 << 10


def _argv(key: str, path: Path, json_out: bool, out: Path) -> list[str]:
    command = key.split("-")[0]
    _, extra = COMMANDS[key]
    if key == "health-voltages":
        return ["health", "--voltages", str(path), *(["--json"] if json_out else [])]
    if command == "report":
        return ["report", str(path), *extra, "--format", "json" if json_out else "md", "-o", str(out)]
    return [command, str(path), *extra, *(["--json"] if json_out else [])]


def _digest(paths: list[Path]) -> dict[Path, str]:
    return {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in paths if p.is_file()}


def check_run(argv: list[str], inputs: list[Path], json_out: bool, out: Path | None = None) -> tuple[int, str]:
    """Run one command in-process and assert the properties; (exit code, stdout)."""
    before = _digest(inputs)
    try:
        res = runner.invoke(app, argv)
    finally:
        release_streams()
    assert res.exception is None or isinstance(res.exception, SystemExit), (argv, repr(res.exception))
    stdout, stderr = res.stdout, res.stderr
    assert res.exit_code in (0, 1, 2), (argv, res.exit_code, stderr[-500:])
    assert "internal error" not in stderr, (argv, stderr[-500:])
    assert "Traceback" not in stderr and "Traceback" not in stdout, (argv, stderr[-2000:])
    assert not unsafe_in(stderr), (argv, unsafe_in(stderr), stderr[-300:])
    if res.exit_code == 2:
        assert stderr.strip(), (argv, "exit 2 says why")
    text = out.read_text(encoding="utf-8") if out is not None and out.exists() and res.exit_code != 2 else stdout
    if json_out and res.exit_code in (0, 1):
        json.loads(text)
    assert not unsafe_in(text), (argv, unsafe_in(text))
    assert _digest(inputs) == before, (argv, "an input changed")
    return res.exit_code, text


@pytest.mark.parametrize("key", list(COMMANDS))
def test_every_command_runs_on_its_sample(key: str, tmp_path: Path) -> None:
    sample = SAMPLES / COMMANDS[key][0]
    code, _ = check_run(_argv(key, sample, True, tmp_path / "out.json"), [sample], True, tmp_path / "out.json")
    assert code == 0


@pytest.mark.parametrize("key", list(COMMANDS))
def test_damaged_inputs_give_exit_0_1_or_2_and_clean_output(
    key: str, tmp_path_factory: pytest.TempPathFactory, request: pytest.FixtureRequest
) -> None:
    sample = SAMPLES / COMMANDS[key][0]
    head = sample.read_bytes()[:_HEAD_BYTES]

    @fuzz_settings(ci_examples=8)
    @given(seed=st.integers(0, 2**32 - 1), json_out=st.booleans())
    def damaged(seed: int, json_out: bool) -> None:
        TRIED[f"command {key}: damaged input"] += 1
        tmp = tmp_path_factory.mktemp(key)
        path = tmp / sample.name
        path.write_bytes(mutate(head, seed))
        out = tmp / ("out.json" if json_out else "out.md")
        check_run(_argv(key, path, json_out, out), [path], json_out, out if key == "report" else None)

    damaged()


@pytest.mark.parametrize("key", list(COMMANDS))
@pytest.mark.parametrize("json_out", [True, False], ids=["json", "text"])
def test_extreme_values_in_every_field_give_exit_0_1_or_2_and_clean_output(
    key: str, json_out: bool, tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    sample = SAMPLES / COMMANDS[key][0]
    path = tmp_path / sample.name
    path.write_bytes(field_variants(sample.read_bytes()[:_HEAD_BYTES]))
    TRIED[f"command {key}: extreme field values"] += 1
    out = tmp_path / ("out.json" if json_out else "out.md")
    check_run(_argv(key, path, json_out, out), [path], json_out, out if key == "report" else None)


HOSTILE_NAMES = {
    "0xff": b"log\xff",
    "newline": b"two\nlines",
    "dash": b"-dash",
    "markup": b"[bold red]x[red]",
    "bidi": "\u202eevil".encode(),
    "escape": b"\x1b]0;title\x07\x1b[31m",
}


@pytest.mark.parametrize("key", ["analyze", "health", "frames", "gnss", "crossing", "report", "health-voltages"])
@pytest.mark.parametrize("name", list(HOSTILE_NAMES))
def test_hostile_file_names_are_analysed_and_shown_escaped(
    key: str, name: str, tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    sample = SAMPLES / COMMANDS[key][0]
    path = Path(os.fsdecode(os.fsencode(tmp_path) + b"/" + HOSTILE_NAMES[name] + sample.suffix.encode()))
    path.write_bytes(sample.read_bytes())
    argv = _argv(key, path, True, tmp_path / "out.json")
    if name == "dash":
        argv = [a if a != str(path) else os.path.relpath(path) for a in argv]
    code, _ = check_run(argv, [path], True, tmp_path / "out.json" if key == "report" else None)
    assert code == 0


# ------------------------------------------------- regressions, one per class


def _gnss_json(path: Path | str, *extra: str) -> dict:
    res = runner.invoke(app, ["gnss", str(path), "--json", *extra])
    release_streams()
    assert res.exit_code in (0, 1) and "internal error" not in res.stderr, res.stderr
    return json.loads(res.stdout)


def _parse_report(doc: dict) -> dict:
    return doc.get("parse_report", doc.get("report", doc))


PLAIN_GNSS = (SAMPLES / "gnss_devices.csv").read_text(encoding="utf-8")


@pytest.mark.parametrize(
    "encode",
    [
        lambda t: t.encode("utf-16"),
        lambda t: t.encode("utf-16-le"),
        lambda t: t.encode("utf-16-be"),
        lambda t: t.replace("\n", "\r").encode(),
        lambda t: t.replace("\n", "\r\n").encode("utf-16-le"),
    ],
    ids=["utf16-bom", "utf16le", "utf16be", "cr-only", "utf16le-crlf"],
)
def test_gnss_tables_in_utf16_or_with_cr_line_ends_read_like_the_plain_one(tmp_path: Path, encode) -> None:  # type: ignore[no-untyped-def]
    plain = _parse_report(_gnss_json(SAMPLES / "gnss_devices.csv"))
    path = tmp_path / "gnss.csv"
    path.write_bytes(encode(PLAIN_GNSS))
    got = _parse_report(_gnss_json(path))
    assert (got["records"], got["rejected"]) == (plain["records"], plain["rejected"])


@pytest.mark.parametrize("damage", ["\x00", "\r"], ids=["nul", "stray-cr"])
def test_a_nul_or_stray_cr_in_a_gnss_field_rejects_that_row_alone(tmp_path: Path, damage: str) -> None:
    plain = _parse_report(_gnss_json(SAMPLES / "gnss_devices.csv"))
    lines = PLAIN_GNSS.split("\n")
    lines[5] = lines[5].replace(",head", f",he{damage}ad", 1).replace(",eot", f",e{damage}ot", 1)
    path = tmp_path / "gnss.csv"
    path.write_text("\n".join(lines), encoding="utf-8")
    got = _parse_report(_gnss_json(path))
    assert got["rejected"] == plain["rejected"] + 1 and got["records"] == plain["records"] - 1


@pytest.mark.parametrize("command", ["gnss", "crossing", "report"])
@pytest.mark.parametrize("damage", ["\x00", "\r"], ids=["nul", "stray-cr"])
def test_a_nul_or_stray_cr_in_a_gnss_header_is_never_an_internal_error(
    tmp_path: Path, command: str, damage: str
) -> None:
    # Found by the long fuzz run: the format recognition read the header with the csv module, which
    # refuses a stray CR ("new-line character seen in unquoted field"): internal error.
    data = (SAMPLES / "crossing_example.csv").read_bytes()
    assert data.startswith(b"time,device,role,lat,lon,speed,course\n")
    path = tmp_path / "gnss.csv"
    path.write_bytes(data.replace(b",course", b",co" + damage.encode() + b"urse", 1))
    code, _ = check_run(_argv(command, path, False, tmp_path / "r.md"), [path], json_out=False)
    assert code in (0, 2)  # read without that column, or no header recognised: never an internal error


@pytest.mark.parametrize("char", ["\x7f", "\u202e", "\x1b[31m"], ids=["del", "bidi", "escape"])
def test_a_device_name_in_the_crossing_warnings_is_shown_escaped(tmp_path: Path, char: str) -> None:
    # Found by the long fuzz run: "devices in no train: A-e\x7ft" reached the terminal as it was.
    data = (SAMPLES / "crossing_example.csv").read_text(encoding="utf-8")
    path = tmp_path / "gnss.csv"
    path.write_text(data.replace(",A-eot,", f",A-e{char}ot,", 1), encoding="utf-8")
    code, stdout = check_run(_argv("crossing", path, False, tmp_path / "r.md"), [path], json_out=False)
    assert code in (0, 1) and "devices in no train" in stdout


@pytest.mark.parametrize("command", ["gnss", "crossing"])
@pytest.mark.parametrize("damage", ["truncated", "junk"])
def test_a_truncated_or_junk_tailed_gzip_keeps_the_lines_before_it(tmp_path: Path, command: str, damage: str) -> None:
    data = gzip.compress((SAMPLES / "crossing_example.csv").read_bytes())
    path = tmp_path / "cut.csv.gz"
    path.write_bytes(data[: len(data) * 2 // 3] if damage == "truncated" else data + b"trailing junk")
    layout = ["--layout", "example"] if command == "crossing" else []
    res = runner.invoke(app, [command, str(path), *layout, "--json"])
    release_streams()
    assert res.exit_code in (0, 1), res.stderr
    doc = json.loads(res.stdout)
    text = json.dumps(doc)
    assert "corrupt gzip" in text and "after " in text and " lines" in text
    if command == "gnss":
        assert _parse_report(doc)["records"] > 0


def _trackside(*args: str, stdin: bytes | None = None, shell: str | None = None) -> subprocess.CompletedProcess[bytes]:
    cmd = ["bash", "-c", shell] if shell is not None else ["trackside", *args]
    # This interpreter's trackside first, whether or not its environment is activated.
    path = os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "")])
    return subprocess.run(
        cmd, input=stdin, capture_output=True, timeout=120, cwd=ROOT, env={**os.environ, "PATH": path}
    )


def test_stdin_dash_and_dev_stdin_are_read_as_streams() -> None:
    data = (SAMPLES / "gnss_devices.csv").read_bytes()
    for arg in ("-", "/dev/stdin"):
        run = _trackside("gnss", arg, "--json", stdin=gzip.compress(data))
        assert run.returncode == 0, run.stderr
        assert _parse_report(json.loads(run.stdout))["records"] > 0 and b"seekable" not in run.stderr


def test_a_fifo_is_read_as_a_stream(tmp_path: Path) -> None:
    fifo = tmp_path / "gnss.fifo"
    os.mkfifo(fifo)
    data = (SAMPLES / "gnss_devices.csv").read_bytes()

    def write() -> None:
        with open(fifo, "wb") as f:
            f.write(data)

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    run = _trackside("gnss", str(fifo), "--json")
    writer.join(10)
    assert run.returncode == 0, run.stderr
    assert _parse_report(json.loads(run.stdout))["records"] > 0


def test_process_substitution_of_a_gzip_log_is_read() -> None:
    log = SAMPLES / "osong_ws4_0932_detection.log"
    run = _trackside(shell=f"gzip -c {log} > /dev/null; trackside analyze --json <(gzip -c {log})")
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["parse_report"]["records"] == 34


def test_a_non_utf8_file_name_in_a_real_process_is_shown_as_ls_does(tmp_path: Path) -> None:
    path = os.fsencode(tmp_path) + b"/log\xff.log"
    Path(os.fsdecode(path)).write_bytes((SAMPLES / "osong_ws4_0932_detection.log").read_bytes())
    trackside = os.fsencode(Path(sys.executable).with_name("trackside"))
    run = subprocess.run([trackside, b"analyze", path], capture_output=True, timeout=120, cwd=ROOT)
    assert run.returncode == 0, run.stderr
    assert b"log\\xff.log" in run.stdout + run.stderr or b"\xff" not in run.stdout


def test_report_refuses_to_write_over_an_input(tmp_path: Path) -> None:
    log = tmp_path / "a.log"
    log.write_bytes((SAMPLES / "osong_ws4_0932_detection.log").read_bytes())
    code, _ = check_run(["report", str(log), "-o", str(log)], [log], False)
    assert code in (0, 2)  # read without that column, or no header recognised: never an internal error
