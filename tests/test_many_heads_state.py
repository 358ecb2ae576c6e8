"""Per-head and per-device state held as columns gives what the lists of objects gave (issue "Memory from
many devices").

The heads are a :class:`HeadTable`, the inventory a :class:`DeviceTable`
(objects built when read), ``status_passages`` and ``devices`` are written to
JSON a block at a time, and the text face keeps only the first passages it
shows (:class:`FirstPassages`).  These tests hold each to the whole-table or
whole-list answer.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from benchmarks.gen_realistic_diag import generate
from console.analysis.head_table import HeadTable, heads_at
from console.analysis.passages.speed_settings import SpeedSettings
from console.analysis.passages.status import STATUS_KIND
from console.analysis.passages.stream import take_passages
from console.jsonout import array_parts, dumps
from console.sinks.tables.diag_stream import status_json
from console.sinks.tables.passage_spool import FirstPassages
from parsers.dictionary import StringDictionary
from tests.reads import stream_job

CASE = settings(
    max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow]
)
_RECORD = (
    "Diag_id:00002\tID:{dev}\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:H{head:05d}\tch:{ch}\tAdr:026\t"
    "Label:Radsensor\tData:{data}\tDate:2026-03-02\tTime:10:{mm:02d}:{ss:02d}.{ms:03d}\n"
)


def _heads_log(path: Path, heads: int) -> Path:
    """Every record its own counting head (the adversarial log of bench_many_devices), 30 devices."""
    lines = []
    for i in range(heads):
        s, ms = divmod(7 * i, 1000)
        lines.append(_RECORD.format(dev=4000 + i % 30, head=i, ch=1 + i % 2, data=i % 2, mm=s // 60, ss=s % 60, ms=ms))
    path.write_text("".join(lines), encoding="utf-8")
    return path


@CASE
@given(
    records=st.integers(300, 2500),
    seed=st.integers(1, 10_000),
    chunk_bytes=st.integers(200, 20_000),
    limit=st.sampled_from([1, 7, 200]),
)
def test_first_passages_are_the_first_rows_of_the_whole_table(
    tmp_path: Path, records: int, seed: int, chunk_bytes: int, limit: int
) -> None:
    log = tmp_path / "real.log"
    generate(records, log, boards=4, seed=seed, corrupt_every=50, block_s=60)
    first = FirstPassages(limit)
    job = stream_job([log], SpeedSettings(), chunk_bytes=chunk_bytes, sink=first)
    cols = job.analysis.passage_columns  # the whole table, by head and start
    assert cols is not None
    status = cols["kind"] == STATUS_KIND
    listed = np.flatnonzero(~status)
    want = take_passages(cols, listed[:limit])
    assert first.cols is not None
    assert first.listed == len(listed) and first.status == int(status.sum())
    assert sorted(first.cols) == sorted(want)
    for c, values in want.items():
        np.testing.assert_array_equal(first.cols[c], values, err_msg=c)


def test_heads_devices_and_status_json_as_lists_gave_them(tmp_path: Path) -> None:
    """A log of 3,000 heads read in small chunks: the columnar heads, inventory and streamed JSON
    equal the list forms (what the code built before they were held as columns)."""
    log = _heads_log(tmp_path / "heads.log", 3000)
    job = stream_job([log], SpeedSettings(), chunk_bytes=16 << 10, include_status=False)
    heads = job.analysis.heads
    assert isinstance(heads, HeadTable) and len(heads) == 3000
    as_list = list(heads)
    assert as_list[:2] == [(4000, "H00000"), (4001, "H00001")] and as_list[-1] == (4000 + 2999 % 30, "H02999")
    assert heads == as_list and heads[5] == as_list[5] and heads[-1] == as_list[-1] and heads[10:13] == as_list[10:13]
    keys = np.array([7, 2, 7, 2999])
    dev, names = heads_at(heads, keys)
    assert dev.tolist() == [as_list[k][0] for k in keys] and names == [as_list[k][1] for k in keys]
    assert (dev.tolist(), names) == (heads_at(as_list, keys)[0].tolist(), heads_at(as_list, keys)[1])

    devices = job.analysis.devices
    objects = list(devices)
    assert len(objects) == 30
    assert [d.to_dict() for d in objects] == [devices[i].to_dict() for i in range(30)]
    assert [d.to_dict() for d in devices[3:9]] == [d.to_dict() for d in objects[3:9]]
    assert devices[-1].to_dict() == objects[-1].to_dict()
    assert objects[4].counting_heads == [f"H{i:05d}" for i in range(4, 3000, 30)]

    # Streamed JSON text: byte for byte the text of the lists.
    streamed = dumps({"devices": array_parts((d.to_dict() for d in devices), block=7)})
    assert streamed == dumps({"devices": [d.to_dict() for d in objects]})
    assert job.status is not None and int(job.status.passages.sum()) == 1500  # the Radsensor 0 records
    assert dumps({"s": status_json(job.status, heads)}) == dumps({"s": job.status.to_dict(as_list)})
    assert json.loads(dumps({"s": status_json(job.status, heads)}))["s"]["by_head"][0] == {
        "device_id": 4000,
        "counting_head": "H00000",
        "passages": 1,
        "records": 1,
    }


def test_array_parts_of_nothing_and_of_one_block() -> None:
    assert dumps({"a": array_parts([])}) == '{"a":[]}'
    assert dumps({"a": array_parts(iter(range(5)), block=2)}) == '{"a":[0,1,2,3,4]}'
    assert dumps({"a": {"b": array_parts(["x"]), "c": 1}}) == '{"a":{"b":["x"],"c":1}}'


def test_string_dictionary_take_reads_many_or_few_the_same() -> None:
    d = StringDictionary()
    names = [f"H{i}" for i in range(5000)] + ["Zähler", "Ω"]
    d.codes(names)
    codes = np.array([5001, 0, 5000, 5, 5])
    assert d.take(codes) == [names[c] for c in codes]
    assert d.take(np.arange(len(names))) == names  # many: made by Arrow
    odd = StringDictionary()
    odd.codes([*names, "file\udcff"])  # not valid Unicode: never through Arrow
    assert odd.take(np.arange(len(names) + 1)) == [*names, "file\udcff"]


def test_analyze_json_of_many_heads_never_loads_pandas(tmp_path: Path) -> None:
    """The JSON faces are pandas-free (it costs some 40 MB): many heads take the Arrow path for names,
    which must not pull pandas in either."""
    import subprocess
    import sys

    log = _heads_log(tmp_path / "heads.log", 9000)
    code = (
        "import contextlib, os, sys; from console.cli.app import app\n"
        "with open(os.devnull, 'w') as f, contextlib.redirect_stdout(f), contextlib.suppress(SystemExit):\n"
        f"    app(['analyze', {str(log)!r}, '--json'], standalone_mode=False)\n"
        "print('pandas' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", out.stderr[-2000:]
