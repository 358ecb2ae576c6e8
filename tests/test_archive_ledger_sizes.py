"""A new log is read while it is hashed: the sizes that prove it new, and the ledger it leaves, equal the hash's."""

from __future__ import annotations

import gzip
import hashlib
import json
import random
from pathlib import Path

import pytest
from typer.testing import CliRunner

from console.archive import ledger
from console.archive.store import read_current
from console.cli.app import app
from tests.conftest import SAMPLES

runner = CliRunner()
STATION = SAMPLES / "example_station.log"


@pytest.mark.parametrize("seed", range(40))
def test_sizes_agree_with_the_scan_wherever_the_newlines_fall(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, seed: int
) -> None:
    rng = random.Random(seed)
    monkeypatch.setattr(ledger, "BLOCK", rng.choice([1, 2, 3, 7, 64]))  # newlines on and across block edges
    body = bytes(rng.choice(b"ab\n") if rng.random() < 0.8 else rng.choice(b"xyz") for _ in range(rng.randint(0, 300)))
    if rng.random() < 0.3:
        body = body.replace(b"\n", b"")  # no line end at all
    path = tmp_path / "f.log"
    path.write_bytes(body)
    z = ledger.sizes(path)
    s = ledger.scan(path)
    assert (z.size, z.complete_bytes, z.whole_only) == (s.size, s.complete_bytes, s.whole_only)
    assert s.sha256 == hashlib.sha256(body).hexdigest()
    assert s.complete_sha256 == hashlib.sha256(body[: s.complete_bytes]).hexdigest()
    # A scan limited to the planned size ignores what was appended since.
    with path.open("ab") as f:
        f.write(b"more\nlines")
    assert ledger.scan(path, None, len(body)) == s


def test_sizes_of_a_gzip_file_are_the_whole_file(tmp_path: Path) -> None:
    path = tmp_path / "f.log.gz"
    path.write_bytes(gzip.compress(STATION.read_bytes()))
    z = ledger.sizes(path)
    s = ledger.scan(path)
    assert z.whole_only and (z.size, z.complete_bytes) == (s.size, s.complete_bytes) == (path.stat().st_size,) * 2


def test_only_a_file_no_entry_could_hold_is_planned_new_by_its_size() -> None:
    z = ledger.Sizes(size=1000, complete_bytes=990, whole_only=False)
    other = {"path": "a", "bytes": 500, "size_seen": 510, "sha256": "x", "complete_sha256": "y"}
    assert ledger.new_by_size([other], None, z) == ledger.Plan("new", None, 0, 990, 0, "new file")
    # An entry of the same path, or one of a length its whole content or its lines could hash as: the hash decides.
    assert ledger.new_by_size([other], other, z) is None
    for same in ({"bytes": 990, "size_seen": 995}, {"bytes": 1000, "size_seen": 1000}, {"bytes": 10, "size_seen": 990}):
        assert ledger.new_by_size([other, {**other, **same}], None, z) is None
    # An archive whose ledger has no sizes seen (an older trackside's): the hash decides.
    assert ledger.new_by_size([{k: v for k, v in other.items() if k != "size_seen"}], None, z) is None


def test_a_log_read_while_hashed_has_the_ledger_a_scan_gives(tmp_path: Path) -> None:
    arc = tmp_path / "arc"
    log = tmp_path / "a.log"
    text = STATION.read_bytes()
    log.write_bytes(text + b"half a line")  # the unfinished line is left for the next ingest
    res = runner.invoke(app, ["ingest", str(log), "--archive", str(arc)])
    assert res.exit_code == 0, res.output
    (e,) = read_current(arc).files
    assert e["sha256"] == hashlib.sha256(log.read_bytes()).hexdigest()
    assert e["complete_sha256"] == hashlib.sha256(text).hexdigest()
    assert (e["bytes"], e["size_seen"]) == (len(text), len(text) + len(b"half a line"))
    # The same content again, by another name, is recognised by that hash; then the line finished, read as grown.
    copy = tmp_path / "copy.log"
    copy.write_bytes(log.read_bytes())
    assert "already ingested" in runner.invoke(app, ["ingest", str(copy), "--archive", str(arc)]).stdout
    with log.open("ab") as f:
        f.write(b"\n")
    again = runner.invoke(app, ["ingest", str(log), "--archive", str(arc), "--json"])
    assert again.exit_code == 0, again.output
    assert [f["action"] for f in json.loads(again.stdout)["files"]] == ["grown"]
