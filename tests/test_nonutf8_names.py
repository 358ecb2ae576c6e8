"""A file name that is not UTF-8 (``T\\xff\\xfe-head.nmea``) names a device: the name is escaped as the
file name is (``T\\xff\\xfe-head``), in tables, JSON and reports, never an internal error."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from console.cli.app import app

DATA = Path(__file__).resolve().parent / "data" / "gnss"
runner = CliRunner()
SHOWN = "T\\xff\\xfe"  # as `ls` shows the name


@pytest.fixture(scope="module")
def odd_names(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[str]]:
    run = tmp_path_factory.mktemp("run")
    result = runner.invoke(app, ["simulate", "-o", str(run / "sim"), "--duration", "5m", "--seed", "1"])
    assert result.exit_code == 0, result.output
    names = []
    for role in ("head", "eot"):
        name = os.fsdecode(b"T\xff\xfe-" + role.encode() + b".nmea")
        shutil.copy(run / "sim" / "nmea" / f"T1-{role}.nmea", run / name)
        names.append(str(run / name))
    # A device export with no device column: its rows are named for the file too.
    csv_name = str(run / os.fsdecode(b"T\xff\xfe-ublox.csv"))
    shutil.copy(DATA / "ublox_export.csv", csv_name)
    names.append(csv_name)
    return run, names


def _ok(args: list[str]) -> str:
    result = runner.invoke(app, args)
    assert "internal error" not in result.output
    assert result.exit_code == 0, result.output
    return result.output


def test_gnss_table_and_json_escape_a_device_named_for_its_file(odd_names: tuple[Path, list[str]]) -> None:
    _, names = odd_names
    assert f"{SHOWN}-head" in _ok(["gnss", *names])
    doc = json.loads(_ok(["gnss", "--json", *names]))
    devices = {f["device"] for f in doc["fixes"]}
    assert {f"{SHOWN}-head", f"{SHOWN}-eot", f"{SHOWN}-ublox"} <= devices


def test_crossing_reads_devices_named_for_odd_files(odd_names: tuple[Path, list[str]]) -> None:
    _, names = odd_names
    train = f"--train=T={SHOWN}-head,{SHOWN}-eot"
    _ok(["crossing", *names[:2], "--layout", "example", train])
    doc = json.loads(_ok(["crossing", *names[:2], "--layout", "example", "--json"]))
    assert doc["schema"].startswith("trackside.crossing/")


@pytest.mark.parametrize("fmt", ["md", "json", "html"])
def test_report_of_odd_files(odd_names: tuple[Path, list[str]], fmt: str) -> None:
    run, names = odd_names
    out = run / f"r.{fmt}"
    _ok(["report", *names, "--layout", "example", "--format", fmt, "-o", str(out)])
    # JSON and Markdown double the backslashes they show literally.
    assert f"{SHOWN}-head" in out.read_text("utf-8").replace("\\\\", "\\")
