"""Many devices: per-device work is vectorized and per-device state flat (issue 16, "Memory from many devices").

The memory and time figures are a benchmark (``benchmarks/bench_many_devices.py``);
these tests pin the behaviour the vectorized code must keep: the same axles
as pairing head by head, and correct results for logs of many thousands of
heads and GNSS devices.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from console.analysis.counting.wheels import SYS1, SYS2, PairingSettings, pair_axle_arrays, stamp_resolution_s
from parsers.units import NS


def _pair_head_by_head(onsets: dict[str, np.ndarray], s: PairingSettings) -> tuple[dict[str, np.ndarray], int]:
    """The pairing rule written head by head (as it was before it was vectorized): the reference."""
    head, channel, time_ns = onsets["head"], onsets["channel"], onsets["time_ns"]
    subsecond, file = onsets["subsecond"], onsets["file"]
    is1, is2 = channel == SYS1, channel == SYS2
    fine_ns, coarse_ns = int(s.pair_window_s * NS), max(int(s.pair_window_s * NS), NS)
    wheel = np.flatnonzero(is1 | is2)
    step_s = np.ones(len(head))
    pairs: list[tuple[int, int, bool]] = []
    for h in np.unique(head[wheel]):
        idx = wheel[head[wheel] == h]
        idx = idx[np.argsort(time_ns[idx], kind="stable")]
        rank = {int(i): k for k, i in enumerate(idx)}
        if subsecond[idx].all():
            step_s[idx] = stamp_resolution_s(time_ns[idx])
            i1, i2 = idx[is1[idx]], idx[is2[idx]]
            claims: dict[int, tuple[int, int]] = {}  # sys2 onset -> (gap, sys1 onset), first nearest wins
            found = []
            for a in i1:
                if not len(i2):
                    break
                pos = int(np.searchsorted(time_ns[i2], time_ns[a]))
                left, right = i2[max(pos - 1, 0)], i2[min(pos, len(i2) - 1)]
                dl, dr = abs(time_ns[a] - time_ns[left]), abs(time_ns[right] - time_ns[a])
                b, gap = (left, dl) if dl <= dr else (right, dr)
                if gap <= fine_ns:
                    found.append((int(a), int(b)))
                    if int(b) not in claims or gap < claims[int(b)][0]:
                        claims[int(b)] = (int(gap), int(a))
            pairs += [(a, b, rank[a] < rank[b]) for a, b in found if claims[b][1] == a]
        else:
            k = 0
            while k + 1 < len(idx):
                p, q = int(idx[k]), int(idx[k + 1])
                if channel[p] != channel[q] and time_ns[q] - time_ns[p] <= coarse_ns:
                    pairs.append((p, q, True) if is1[p] else (q, p, False))
                    k += 2
                else:
                    k += 1
    a = np.array([p[0] for p in pairs], np.int64)
    b = np.array([p[1] for p in pairs], np.int64)
    first1 = np.array([p[2] for p in pairs], bool)
    t1, t2 = time_ns[a], time_ns[b]
    delay = (t2 - t1) / NS
    exact = subsecond[a] & subsecond[b]
    timed = exact & (np.abs(delay) >= s.min_delay_steps * step_s[a])
    with np.errstate(divide="ignore"):
        speed = np.where(timed & (delay != 0), s.spacing_m / np.abs(delay) * 3.6, np.nan)
    known = (t1 != t2) | (file[a] == file[b])
    direction = np.where(known, np.where(first1, 1, 2), 0).astype(np.int8)
    axles = {
        "head": head[a],
        "t_sys1_ns": t1,
        "t_sys2_ns": t2,
        "time_ns": np.minimum(t1, t2),
        "direction": direction,
        "delay_s": np.where(exact, delay, np.nan),
        "speed_kmh": speed,
    }
    return axles, int((is1 | is2).sum()) - 2 * len(a)


def _random_onsets(rng: np.random.Generator) -> dict[str, np.ndarray]:
    n = int(rng.integers(0, 50))
    step = int(rng.choice([1, 1000, 1_000_000, NS]))
    subsecond = rng.random(n) < (0.2 if rng.random() < 0.3 else 1.0)
    return {
        "head": rng.integers(0, int(rng.integers(1, 6)), n) * int(rng.choice([1, 70_000])),
        "channel": rng.integers(0, 4, n),  # 0 and 3: not a wheel system
        # Few distinct times: ties within a head, across heads and across files.
        "time_ns": 1_700_000_000 * NS + rng.integers(0, 30, n) * step * int(rng.choice([1, 37, 300])),
        "subsecond": subsecond,
        "file": rng.integers(0, 2, n),
    }


@pytest.mark.parametrize("seed", range(4))
def test_pairing_all_heads_at_once_equals_pairing_head_by_head(seed: int) -> None:
    rng = np.random.default_rng(seed)
    settings = PairingSettings()
    for _ in range(150):
        onsets = _random_onsets(rng)
        got, got_unpaired = pair_axle_arrays(onsets, settings)
        want, want_unpaired = _pair_head_by_head(onsets, settings)
        assert got_unpaired == want_unpaired
        for column, values in want.items():
            np.testing.assert_array_equal(got[column], values, err_msg=column)


def test_pairing_twenty_thousand_heads_each_pairs_its_own_wheel() -> None:
    heads = 20_000
    t0 = 1_700_000_000 * NS
    # Head h: Sys1 then Sys2 4 ms later (odd heads the other way round), all heads within the same second.
    head = np.repeat(np.arange(heads), 2)
    channel = np.tile([SYS1, SYS2], heads)
    channel[2 * np.arange(1, heads, 2)], channel[2 * np.arange(1, heads, 2) + 1] = SYS2, SYS1
    time_ns = t0 + np.repeat(np.arange(heads) % 500, 2) * 1_000_000 + np.tile([0, 40_000_000], heads)
    onsets = {"head": head, "channel": channel, "time_ns": time_ns, "subsecond": np.ones(2 * heads, bool)}
    axles, unpaired = pair_axle_arrays(onsets, PairingSettings())
    assert unpaired == 0
    np.testing.assert_array_equal(axles["head"], np.arange(heads))
    np.testing.assert_array_equal(axles["direction"], np.where(np.arange(heads) % 2 == 0, 1, 2))
    # 0.13 m in 40 ms: 11.7 km/h.
    np.testing.assert_allclose(axles["speed_kmh"], 0.13 / 0.04 * 3.6)


_RECORD = (
    "Diag_id:00002\tID:{dev}\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:H{head:06d}\tch:{ch}\tAdr:026\t"
    "Label:Radsensor\tData:{data}\tDate:2026-03-02\tTime:10:{mm:02d}:{ss:02d}.{ms:03d}\n"
)
_SERIAL = (
    "Diag_id:00002\tID:{dev}\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:H{head:06d}\tch:1\tAdr:028\t"
    "Label:Seriennummer\tData:{serial}\tDate:2026-03-02\tTime:10:00:00.000\n"
)


_HEADS, _DEVICES = 20_000, 500


@pytest.fixture(scope="module")
def many_heads_job(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """20 k heads on 500 devices, each head a wheel on Sys1 then Sys2 4 ms later, read in 256 KB chunks."""
    from console.analysis.passages.speed_settings import SpeedSettings
    from tests.reads import stream_job

    heads, devices = _HEADS, _DEVICES
    lines = []
    for i in range(heads):
        t_ms = 5 * i  # 100 s of log; each head's two onsets 4 ms apart
        for ch, dt in ((1, 0), (2, 4)):
            s, ms = divmod(t_ms + dt, 1000)
            lines.append(_RECORD.format(dev=1000 + i % devices, head=i, ch=ch, data=1, mm=s // 60, ss=s % 60, ms=ms))
    lines += [_SERIAL.format(dev=1000 + d, head=d, serial=700000 + d) for d in range(0, devices, 7)]
    log = tmp_path_factory.mktemp("many") / "heads.log"
    log.write_text("".join(lines), encoding="utf-8")
    return stream_job([log], SpeedSettings(), chunk_bytes=256 << 10)


def test_twenty_thousand_heads_inventory_per_device(many_heads_job: Any) -> None:
    """Every head, device, record count, span and axle is where the log put it."""
    job, heads, devices = many_heads_job, _HEADS, _DEVICES
    assert job.report.records == 2 * heads + len(range(0, devices, 7))
    inv = job.analysis.devices
    assert [d.device_id for d in inv] == [1000 + d for d in range(devices)]
    for d in (0, 7, 123, 499):
        dev = inv[d]
        mine = range(d, heads, devices)
        assert dev.counting_heads == [f"H{i:06d}" for i in mine]
        assert dev.records == 2 * len(mine) + (d % 7 == 0)
        assert dev.channels == [1, 2]
        assert dev.diag_ids == [2]
        assert dev.serial_number == (str(700000 + d) if d % 7 == 0 else None)
        t0 = int(np.datetime64("2026-03-02T10:00:00", "ns").astype(np.int64))
        first_ms = 0 if d % 7 == 0 else 5 * d  # the serial record is at 10:00:00.000
        assert (dev.first_ns - t0) // 1_000_000 == first_ms
        assert (dev.last_ns - t0) // 1_000_000 == 5 * mine[-1] + 4
    # Every head: one passage of one axle, Sys1 → Sys2 at 0.13 m / 4 ms.
    axles = job.analysis.axle_columns
    assert len(axles["head"]) == heads
    assert (axles["direction"] == 1).all()
    assert job.analysis.unpaired_detections == 0
    assert len(job.analysis.heads) == heads


def test_twenty_thousand_gnss_devices_json_and_device_table(tmp_path: Path) -> None:
    """One fix per device: every fix in the streamed JSON (blocks joined), the device table
    summarised without a table per device and cut to its first rows with a note."""
    import json

    from typer.testing import CliRunner

    from console.cli.app import app
    from console.sinks.tables.gnss_tables import DEVICES_SHOWN, FIX_BLOCK, devices_table, gnss_json
    from parsers.gnss_files import parse_gnss

    devices = 20_000
    assert devices > FIX_BLOCK  # the JSON crosses a block boundary
    rows = [
        f"2026-01-19T10:{(i // 600) % 60:02d}:{(i // 10) % 60:02d}Z,D{i:06d},{'head' if i % 2 == 0 else 'eot'},"
        f"{20.6 + i * 1e-6:.6f},{105.9 + i * 1e-6:.6f},{i % 60}.5\n"
        for i in range(devices)
    ]
    csv = tmp_path / "devices.csv"
    csv.write_text("time,device,role,lat,lon,speed\n" + "".join(rows), encoding="utf-8")

    result = CliRunner().invoke(app, ["gnss", str(csv), "--json"])
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    fixes, report = parse_gnss([csv])[:2]
    assert doc["fixes"] == gnss_json(fixes, report)["fixes"]
    assert len(doc["fixes"]) == devices
    by_device = {f["device"]: f for f in doc["fixes"]}
    assert by_device["D012345"]["role"] == "eot"
    assert by_device["D012345"]["lat"] == pytest.approx(20.6 + 12345e-6)
    assert by_device["D012345"]["speed_mps"] == 45.5  # a bare "speed" column of a device export: m/s

    table = devices_table(fixes)
    assert table.row_count == DEVICES_SHOWN
    assert f"first {DEVICES_SHOWN:,} of {devices:,} devices" in str(table.caption)
    assert [str(c) for c in table.columns[0].cells][:2] == ["D000000", "D000001"]
    assert [str(c) for c in table.columns[1].cells][:2] == ["head", "eot"]


def test_many_devices_text_tables_show_the_first_and_say_how_many(many_heads_job: Any) -> None:
    from console.sinks.tables.diag_tables import DEVICES_SHOWN, inventory_table, passages_table

    inv = inventory_table(many_heads_job.analysis)
    assert len(inv.columns) == 1 + DEVICES_SHOWN
    assert f"first {DEVICES_SHOWN} of {_DEVICES:,} devices" in str(inv.caption)
    table = passages_table(many_heads_job.analysis, limit=200)
    assert table.row_count == 200
    assert f"Passages ({_HEADS})" in str(table.title)
    assert f"first 200 of {_HEADS} passages" in str(table.caption)
    # The rows listed are the first passages of the whole table (by head, then start).
    assert [str(c) for c in table.columns[0].cells][:3] == ["H000000", "H000001", "H000002"]


def test_report_gnss_units_many_devices_in_natural_order(tmp_path: Path) -> None:
    """The report's GNSS units from grouped reductions: each device once, natural order, counts right."""
    from console.sinks.report.document import _gnss_units
    from console.sinks.report.model import ReportData
    from parsers.gnss_files import parse_gnss

    rows = [f"2026-01-19T10:00:{i % 60:02d}Z,U{i},{'head' if i % 3 else 'eot'},20.6,105.9,1.0\n" for i in range(3000)]
    rows += ["2026-01-19T11:00:00Z,U7,head,,,\n"]  # a second fix for U7, no position: not valid
    csv = tmp_path / "devices.csv"
    csv.write_text("time,device,role,lat,lon,speed\n" + "".join(rows), encoding="utf-8")
    fixes = parse_gnss([csv])[0]
    data = ReportData.__new__(ReportData)
    data.fixes = fixes
    units = list(_gnss_units(data))
    assert [u["device"] for u in units[:12]] == [f"U{i}" for i in range(12)]  # U2 before U10
    assert len(units) == 3000
    u7 = units[7]
    assert (u7["fixes"], u7["valid"], u7["role"]) == (2, 1, "head")
    assert (u7["first"], u7["last"]) == ("2026-01-19T10:00:07.000Z", "2026-01-19T11:00:00.000Z")
    assert units[9]["role"] == "eot"
