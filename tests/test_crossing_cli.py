"""`trackside crossing` and `trackside gnss` on the shipped samples (sample_logs/README.md)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest
from typer.testing import CliRunner

from console.analysis.crossing.controller import CrossingController
from console.analysis.crossing.timeline import timeline
from console.analysis.crossing.values import ControllerSettings, Fix, TrainSpec
from console.cli.app import app
from console.layout import load_layout

runner = CliRunner()
TRAINS = ["--train", "A=A-head,A-eot,120", "--train", "B=B-head,B-eot,300"]


def _crossing(samples: Path, *args: str, path: Path | None = None) -> dict:
    res = runner.invoke(
        app, ["crossing", str(path or samples / "crossing_example.csv"), "--layout", "example", "--json", *args]
    )
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout)


def test_both_trains_at_both_crossings_switch_off_on_eot_evidence(samples: Path) -> None:
    doc = _crossing(samples, *TRAINS)
    assert doc["violations"] == 0
    rows = {(r["crossing"], r["train"]): r for r in doc["timelines"]}
    assert set(rows) == {("11+850", "A"), ("11+850", "B"), ("12+940", "A"), ("12+940", "B")}
    for (code, train), r in rows.items():
        warning = 70 if code == "11+850" else 60
        assert r["lead_time_s"] >= warning
        # Fixes every 5 or 10 s; off needs two EOT fixes past the crossing: about two periods
        # (B's EOT at 12+940 loses its fixes for 40 s just after the first one past).
        assert 0 <= r["excess_warning_s"] <= (60 if (code, train) == ("12+940", "B") else 25)
        assert r["reason_off"].startswith("EOT") and not r["violations"]


def test_fixed_time_baseline_would_open_with_the_tail_on_the_road(samples: Path) -> None:
    # Train B stops with its tail on 12+940: the baseline switches off after length / speed + 10 s.
    r = next(r for r in _crossing(samples, *TRAINS)["timelines"] if (r["crossing"], r["train"]) == ("12+940", "B"))
    assert r["baseline_early_s"] > 60


def test_trains_pair_by_device_name_without_options(samples: Path) -> None:
    doc = _crossing(samples)
    assert [t["train"] for t in doc["trains"]] == ["A", "B"]
    assert doc["violations"] == 0


def test_without_eot_fixes_the_warning_is_held_on_with_an_alarm(samples: Path, tmp_path: Path) -> None:
    lines = (samples / "crossing_example.csv").read_text().splitlines()
    no_eot = tmp_path / "no_eot.csv"
    no_eot.write_text("\n".join(line for line in lines if ",A-eot," not in line) + "\n")
    doc = _crossing(samples, *TRAINS, path=no_eot)
    a = [r for r in doc["timelines"] if r["train"] == "A"]
    assert a and all(r["t_off"] is None and "held on" in r["reason_off"] for r in a)
    assert any(e["kind"] == "alarm" and e["train"] == "A" for e in doc["events"])
    assert doc["violations"] == 0


def test_crossing_usage_errors_are_exit_2(samples: Path) -> None:
    csv = str(samples / "crossing_example.csv")
    assert runner.invoke(app, ["crossing", csv, "--layout", "osong"]).exit_code == 2  # no crossings
    res = runner.invoke(app, ["crossing", csv, "--layout", "example", "--train", "A=onlyhead"])
    assert res.exit_code == 2 and "TRAIN=HEAD_DEVICE,EOT_DEVICE" in res.stderr


def test_a_train_of_misspelt_devices_is_refused_not_an_empty_table(samples: Path) -> None:
    """--train naming devices none of the inputs has (a typo) gave an empty table, a warning that listed the
    devices left over but not the ones misspelt, and exit 0."""
    csv = str(samples / "crossing_example.csv")
    res = runner.invoke(app, ["crossing", csv, "--layout", "example", "--train", "A=a-hed,a-eot"])
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "a-hed, a-eot" in lines[0] and "A-eot, A-head, B-eot, B-head" in lines[0], lines


def test_a_named_device_without_fixes_is_said_and_the_train_still_runs(samples: Path) -> None:
    # An EOT unit silent all day is a case to analyse (its warnings held on): not refused, but said by name.
    csv = str(samples / "crossing_example.csv")
    res = runner.invoke(app, ["crossing", csv, "--layout", "example", "--train", "A=A-head,A-eott", "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert any("A-eott" in w and "no fix" in w for w in doc["warnings"]), doc["warnings"]
    assert {r["train"] for r in doc["timelines"]} == {"A"}


def test_crossing_table_lists_violations_first(samples: Path) -> None:
    res = runner.invoke(app, ["crossing", str(samples / "crossing_example.csv"), "--layout", "example", *TRAINS])
    assert res.exit_code == 0
    assert "SAFETY VIOLATIONS" not in res.output and "120 early" in res.output


def test_timeline_reports_a_late_switch_off_as_a_violation() -> None:
    # A controller that was told the tail passed while its fixes show it still on the road.
    crossing = load_layout("example").crossings[0]
    ctl = CrossingController(crossing, [TrainSpec("T", 100.0)])
    c = crossing.chainage_m
    fixes = [
        Fix(0, 0, "T", "head", c - 3000, 20.0),
        Fix(10**9, 10**9, "T", "head", c - 2980, 20.0),
        Fix(50 * 10**9, 50 * 10**9, "T", "head", c - 1500, 20.0),  # within the warning time: on
    ]
    for f in fixes:
        ctl.step(f)
    fixes += [
        Fix(150 * 10**9, 150 * 10**9, "T", "eot", c - 50, 20.0),
        Fix(160 * 10**9, 160 * 10**9, "T", "eot", c + 150, 20.0),
    ]
    tr = ctl.tracks["T"]
    tr.warned, tr.t_off = False, 151 * 10**9  # switched off before the EOT crossed: must be a violation
    (row,) = timeline(ctl, fixes, ControllerSettings())
    assert "warning off before the tail cleared the crossing" in row.violations


@pytest.mark.parametrize("name", ["co_nhu_van_2026_centre_table.tsv", "gnss_devices.csv", "gnss_devices.jsonl"])
def test_gnss_command_decodes_the_samples(samples: Path, name: str) -> None:
    res = runner.invoke(app, ["gnss", str(samples / name), "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["fixes"] and doc["parse_report"]["rejected"] == 0
    for key in ("time", "lat", "lon", "speed_mps", "course_deg", "valid", "device", "file", "line"):
        assert key in doc["fixes"][0]
    if name == "co_nhu_van_2026_centre_table.tsv":
        assert [round(f["speed_mps"] * 3.6, 1) for f in doc["fixes"]][:2] == [55.6, 55.6]
        assert doc["fixes"][0]["time"].startswith("2026-01-19T17:05:21")


def _run_train(head_until_s: float, until_s: float = 400.0) -> list[str]:
    """A 100 m train at 20 m/s, head and EOT fixes every 10 s; the head unit goes silent at ``head_until_s``."""
    crossing = load_layout("example").crossings[0]
    ctl = CrossingController(crossing, [TrainSpec("T", 100.0)])
    c = crossing.chainage_m
    ns = 10**9
    alarms = []
    for t in range(0, int(until_s), 10):
        head = c - 3000 + 20.0 * t
        if t < head_until_s:
            alarms += [e.reason for e in ctl.step(Fix(t * ns, t * ns, "T", "head", head, 20.0, 1)) if e.kind == "alarm"]
        eot = Fix(t * ns + 1, t * ns + 1, "T", "eot", head - 100.0, 20.0, 1)
        alarms += [e.reason for e in ctl.step(eot) if e.kind == "alarm"]
    return alarms


def test_a_head_unit_lost_on_the_approach_raises_an_alarm() -> None:
    assert any("head unit stale" in a for a in _run_train(head_until_s=60))


def test_a_head_unit_silent_after_the_train_has_cleared_the_crossing_is_not_an_alarm() -> None:
    # The head passes the crossing at 150 s and the EOT clears it at about 160 s; the
    # head unit then runs off the mapped line (it is no longer placed): no alarm here.
    assert _run_train(head_until_s=200) == []


def _no_speed_export(path: Path, start_s: float = 0.0, jump_at_s: float | None = None) -> Path:
    """A 121 km/h, 200 m train past 11+850 (70 s) exported as many devices do: time, lat, lon, no speed.

    Head and EOT at 1 Hz, 2 m of noise; the head reaches the crossing 178.5 s after 08:00:00.
    ``start_s`` cuts the recording's beginning; ``jump_at_s`` displaces that head fix 2 km ahead."""
    import datetime as dt

    import numpy as np

    from console.analysis.geo import TrackProjector

    lay = load_layout("example")
    proj = TrackProjector(lay.track)
    c, v, length = lay.crossings[0].chainage_m, 121 / 3.6, 200.0
    rng = np.random.default_rng(1)
    t0 = dt.datetime(2026, 3, 2, 8, 0, 0, tzinfo=dt.UTC)
    rows = ["time,device,role,lat,lon"]
    for k in range(int(start_s), 260):
        head = c - 6000 + v * k
        for dev, role, ch, ms in (("X-head", "head", head, 0), ("X-eot", "eot", head - length, 200)):
            if role == "head" and k == jump_at_s:
                ch += 2000.0
            lat, lon = proj.position(ch)
            lat = lat[0] + rng.normal(0, 2) / proj.m_per_deg_lat
            lon = lon[0] + rng.normal(0, 2) / proj.m_per_deg_lon
            t = (t0 + dt.timedelta(seconds=k, milliseconds=ms)).isoformat().replace("+00:00", "Z")
            rows.append(f"{t},{dev},{role},{lat:.7f},{lon:.7f}")
    path.write_text("\n".join(rows) + "\n")
    return path


X = ["--train", "X=X-head,X-eot,200"]


def test_a_121_kmh_export_without_speed_is_warned_a_full_warning_time_ahead(samples: Path, tmp_path: Path) -> None:
    # "Real data first" §3: a fix without speed was taken for a standstill (the warning came
    # 31 s ahead on this export, no violation shown); the speed now comes from the fixes.
    doc = _crossing(samples, *X, path=_no_speed_export(tmp_path / "x.csv", jump_at_s=120))
    assert doc["violations"] == 0 and doc["late_warnings"] == 0
    row = next(r for r in doc["timelines"] if r["crossing"] == "11+850")
    assert row["lead_time_s"] >= 70 and "estimated from the fixes" in row["reason_on"]
    # The fixed-time baseline takes the mean speed of the fixes around arrival: 200 m / 33.6 m/s + 10 s.
    assert row["baseline_off"] is not None and 0 < row["baseline_excess_s"] < 20
    assert doc["position_jumps"] == 1
    for key in ("t_on", "t_head_arrival", "t_tail_clear", "t_off"):
        assert row[key].endswith("Z"), key  # ISO 8601, UTC
    assert all(e["time"].endswith("Z") for e in doc["events"])


def test_a_late_warning_is_a_violation_listed_first_with_how_late(samples: Path, tmp_path: Path) -> None:
    # The recording begins 40 s before the head reaches 11+850: no unit could warn 70 s ahead.
    path = _no_speed_export(tmp_path / "late.csv", start_s=138)
    doc = _crossing(samples, *X, path=path)
    first = doc["timelines"][0]
    assert doc["late_warnings"] == 1 and first["crossing"] == "11+850"
    assert first["violations"][0].startswith("late warning") and 29 < first["late_by_s"] < 31
    assert "telemetry begins only" in first["late_cause"]
    res = runner.invoke(app, ["crossing", str(path), "--layout", "example", *X, "--strict"])
    assert res.exit_code == 1
    assert res.output.index("SAFETY VIOLATIONS") < res.output.index("Level crossings")
    assert "late warning" in res.output


def _decimal_commas(samples: Path, tmp_path: Path) -> Path:
    """The sample's first rows as a spreadsheet in a comma locale writes them: decimal commas, unquoted."""
    lines = (samples / "crossing_example.csv").read_text().splitlines()
    path = tmp_path / "commas.csv"
    path.write_text("\n".join([lines[0], *(line.replace(".", ",") for line in lines[1:6])]) + "\n")
    return path


def _points_without_lat(samples: Path, tmp_path: Path) -> Path:
    path = tmp_path / "A-head.gpx"
    points = [f'<trkpt lon="105.89{k}"><time>2026-01-19T17:00:0{k}Z</time></trkpt>' for k in range(3)]
    path.write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<gpx version="1.1" creator="t" xmlns="http://www.topografix.com/GPX/1/1">\n'
        "<trk><name>A-head</name><trkseg>\n" + "\n".join(points) + "\n</trkseg></trk></gpx>\n"
    )
    return path


@pytest.mark.parametrize(
    ("make", "line", "reason"),
    [
        (_decimal_commas, 2, "expected 7 fields, found"),
        (_points_without_lat, 4, "lat and lon attributes are required"),
    ],
    ids=["csv-decimal-commas", "gpx-points-without-lat"],
)
@pytest.mark.parametrize("form", [[], ["--json"]], ids=["table", "json"])
def test_crossing_refuses_a_file_of_which_every_line_is_rejected(
    samples: Path, tmp_path: Path, make: Callable[[Path, Path], Path], line: int, reason: str, form: list[str]
) -> None:
    bad = make(samples, tmp_path)
    # Alone or beside a readable file: gnss refuses it too (exit 2), rather than an empty table and exit 0.
    for files in ([bad], [samples / "crossing_example.csv", bad]):
        res = runner.invoke(app, ["crossing", *map(str, files), "--layout", "example", *form])
        assert res.exit_code == 2, res.output
        assert res.stdout == ""
        (message,) = res.stderr.strip().splitlines()
        assert f"{bad.name}: nothing readable as GNSS:" in message and "none read" in message
        assert f"; line {line}: " in message and reason in message


def test_crossing_reads_a_file_with_one_rejected_line_and_counts_it(samples: Path, tmp_path: Path) -> None:
    lines = (samples / "crossing_example.csv").read_text().splitlines()
    one_bad = tmp_path / "one_bad.csv"
    one_bad.write_text("\n".join([*lines[:10], lines[10].replace(".", ","), *lines[11:]]) + "\n")
    doc = _crossing(samples, *TRAINS, path=one_bad)
    report = doc["parse_report"]
    assert report["rejected"] == 1 and [r["line"] for r in report["rejections"]] == [11]
    assert report["records"] == len(lines) - 2 and report["records"] + report["blank"] + 1 == report["lines_read"]
    assert doc["timelines"] and doc["violations"] == 0


def test_the_spare_parts_shown_add_up_to_the_spare_shown() -> None:
    import re

    from typer.testing import CliRunner

    from console.cli.app import app
    from tests.conftest import SAMPLES

    res = CliRunner().invoke(app, ["crossing", str(SAMPLES / "crossing_example.csv"), "--layout", "example"])
    assert res.exit_code == 0, res.output
    text = " ".join(res.stdout.split())  # the table may wrap a line
    found = re.findall(r"spare (\d+) s = physics (\d+) s \+ doubt (-?\d+) s", text)
    assert len(found) >= 2
    for spare, physics, doubt in found:
        assert int(spare) == int(physics) + int(doubt)


def test_gga_only_captures_say_their_undated_fixes_were_set_aside(samples: Path, tmp_path: Path) -> None:
    """A receiver set to GGA alone: positions with a time of day but no date (no RMC or ZDA), so no fix can
    be placed in time; the run says so instead of an unexplained empty table."""
    import csv
    from functools import reduce

    def sentence(body: str) -> str:
        return f"${body}*{reduce(lambda a, b: a ^ b, body.encode(), 0):02X}"

    def dm(value: float, width: int) -> str:
        whole = int(abs(value))
        return f"{whole:0{width}d}{(abs(value) - whole) * 60:07.4f}"

    per_device: dict[str, list[str]] = {}
    with (samples / "crossing_example.csv").open(newline="") as f:
        for r in csv.DictReader(f):
            hhmmss = r["time"][11:23].replace(":", "")
            lat, lon = float(r["lat"]), float(r["lon"])
            gga = f"GPGGA,{hhmmss},{dm(lat, 2)},N,{dm(lon, 3)},E,1,08,0.9,10.0,M,0.0,M,,"
            per_device.setdefault(r["device"], []).append(sentence(gga))
    paths = []
    for device in ("A-head", "A-eot"):
        path = tmp_path / f"{device}.nmea"
        path.write_text("\n".join(per_device[device]) + "\n")
        paths.append(str(path))
    res = runner.invoke(app, ["crossing", *paths, "--layout", "example", "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    n = len(per_device["A-head"]) + len(per_device["A-eot"])
    assert doc["timelines"] == []
    assert f"{n} fixes without a date and time set aside (GGA with no RMC or ZDA to date it)" in doc["warnings"]


def test_units_not_paired_by_name_read_as_one_train_are_said(samples: Path, tmp_path: Path) -> None:
    """Units named by their IMEI (a role column, no <train>-head names): the two trains were read as one,
    silently, with a false parting and a 610 s stale EOT, and no word of it."""
    imei = {"A-head": "860001", "A-eot": "860002", "B-head": "860003", "B-eot": "860004"}
    text = (samples / "crossing_example.csv").read_text("utf-8")
    for name, number in imei.items():
        text = text.replace(f",{name},", f",{number},")
    path = tmp_path / "imei.csv"
    path.write_text(text, "utf-8")
    said = "2 head and 2 EOT devices, not named <train>-head / <train>-eot, read as one train: give --train"
    doc = _crossing(samples, path=path)
    assert [t["train"] for t in doc["trains"]] == ["train"] and any(w.startswith(said) for w in doc["warnings"])
    plain = runner.invoke(app, ["crossing", str(path), "--layout", "example"])
    # The table's warnings wrap at the terminal's width (a worker's may be narrow): compared as words.
    assert plain.exit_code == 0 and f"warning: {said}" in " ".join(plain.stdout.split())
    paired = _crossing(samples, "--train", "A=860001,860002,120", "--train", "B=860003,860004,300", path=path)
    assert [t["train"] for t in paired["trains"]] == ["A", "B"] and paired["warnings"] == []
    # One head and one EOT unit however named are one train: nothing to say.
    one = tmp_path / "one.csv"
    one.write_text(
        "\n".join(ln for ln in text.splitlines() if ",86000" not in ln or ",860001," in ln or ",860002," in ln)
    )
    assert _crossing(samples, path=one)["warnings"] == []


@pytest.mark.parametrize(
    ("trains", "said"),
    [
        (["A=A-head,A-eot", "A=B-head,B-eot"], "--train A: given twice (one --train per train)"),
        (["A=A-head,A-eot", "B=A-head,B-eot"], "--train B: A-head is already A's head"),
        (["A=A-head,A-head"], "--train A: A-head is already A's head"),
    ],
)
def test_a_train_or_a_device_named_twice_is_refused(samples: Path, trains: list[str], said: str) -> None:
    """Two --train A merged both trains' units under A; a device in two trains gave its fixes to the last
    (train A then ran on its EOT alone): both unsaid, exit 0."""
    args = [a for t in trains for a in ("--train", t)]
    res = runner.invoke(app, ["crossing", str(samples / "crossing_example.csv"), "--layout", "example", *args])
    assert res.exit_code == 2 and res.stdout == ""
    assert res.stderr.startswith(f"trackside: error: {said}") and res.stderr.count("\n") == 1, res.stderr


def test_times_on_a_later_day_are_marked_in_the_tables(samples: Path, tmp_path: Path) -> None:
    """Train B's run moved past midnight: its times of day were shown under train A's date, unmarked, in the
    timelines, and the integrity table had no date at all."""
    import datetime as dt

    lines = (samples / "crossing_example.csv").read_text("utf-8").splitlines()
    out = [lines[0]]
    for line in lines[1:]:
        t, rest = line.split(",", 1)
        if ",B-" in f",{rest}":
            when = dt.datetime.fromisoformat(t.replace("Z", "+00:00")) + dt.timedelta(hours=6, minutes=50)
            t = when.strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"
        out.append(f"{t},{rest}")
    path = tmp_path / "midnight.csv"
    path.write_text("\n".join(out) + "\n", "utf-8")
    res = runner.invoke(app, ["crossing", str(path), "--layout", "example"])
    assert res.exit_code == 0, res.output
    text = res.stdout
    assert "Level crossings (LC) 2026-01-19: times of day (+N: N days later)" in " ".join(text.split())
    rows = [ln.split() for ln in text.splitlines() if ln.strip().startswith(("11+850", "12+940"))][:4]
    assert {r[1]: r[2] for r in rows if r[0] == "11+850"} == {"A": "17:01:02", "B": "00:07:41+1"}
    assert "Train integrity (2026-01-19, +N: N days later)" in text and "00:05:18+1" in text
    # One day: no marks.
    plain = runner.invoke(app, ["crossing", str(samples / "crossing_example.csv"), "--layout", "example"]).stdout
    assert "+N" not in plain and "+1 " not in plain and "Train integrity (2026-01-19):" in plain


def test_units_named_in_capitals_pair_by_name(samples: Path, tmp_path: Path) -> None:
    """A-HEAD / A-EOT (an export in capitals) paired by no name: both trains were read as one."""
    text = (samples / "crossing_example.csv").read_text("utf-8")
    path = tmp_path / "upper.csv"
    path.write_text(text.replace("-head,head", "-HEAD,HEAD").replace("-eot,eot", "-EOT,EOT"), "utf-8")
    doc = _crossing(samples, path=path)
    assert [(t["train"], t["head"], t["eot"]) for t in doc["trains"]] == [
        ("A", ["A-HEAD"], ["A-EOT"]),
        ("B", ["B-HEAD"], ["B-EOT"]),
    ]
    assert doc["warnings"] == [] and doc["violations"] == 0
    # Without a role column (NMEA has none) the name says the role too.
    lines = [ln.split(",") for ln in path.read_text("utf-8").splitlines()]
    no_role = tmp_path / "no_role.csv"
    no_role.write_text("\n".join(",".join(c[:2] + c[3:]) for c in lines) + "\n", "utf-8")
    assert [t["train"] for t in _crossing(samples, path=no_role)["trains"]] == ["A", "B"]


def test_units_whose_every_fix_is_invalid_are_named(samples: Path, tmp_path: Path) -> None:
    """An export whose valid column says false throughout (no position fix): an empty table, no word why."""
    lines = (samples / "crossing_example.csv").read_text("utf-8").splitlines()
    path = tmp_path / "invalid.csv"
    path.write_text(
        "\n".join([lines[0] + ",valid"] + [ln + (",true" if ",B-" in ln else ",false") for ln in lines[1:]]) + "\n",
        "utf-8",
    )
    doc = _crossing(samples, path=path)
    assert doc["warnings"] == ["no valid fix from A-head, A-eot: every one marked invalid (no position fix)"]
    assert {r["train"] for r in doc["timelines"]} == {"B"}


def test_a_device_written_twice_differently_is_said(samples: Path, tmp_path: Path) -> None:
    """Each row of the sample written again 1.1 km north (the same device and instant): one row of each was kept
    unsaid, and the run read as held warnings and late ones.  Now each device's conflicting instants are said;
    an RMC and a GGA of one epoch (the same position) are not a conflict."""
    lines = (samples / "crossing_example.csv").read_text("utf-8").splitlines()
    header = lines[0].split(",")
    lat = header.index("lat")
    out = [lines[0]]
    for line in lines[1:]:
        out.append(line)
        cells = line.split(",")
        if len(cells) == len(header):
            cells[lat] = f"{float(cells[lat]) + 0.01:.6f}"
            out.append(",".join(cells))
    twice = tmp_path / "twice.csv"
    twice.write_text("\n".join(out) + "\n", "utf-8")
    doc = _crossing(samples, path=twice)
    said = {w.split(":")[0]: w for w in doc["warnings"] if "two positions" in w}
    assert sorted(said) == ["A-eot", "A-head", "B-eot", "B-head"]
    per_device = sum(1 for line in lines[1:] if ",A-head," in line)
    assert said["A-head"].startswith(f"A-head: {per_device} instants with two positions up to 1,1")
    assert not [w for w in _crossing(samples)["warnings"] if "two positions" in w]


def _doctored(samples: Path, tmp_path: Path, how: str) -> Path:
    """The sample as other hands write it: a third of its rows written again 1.1 km north, its units named by
    IMEI, or A's fixes all marked invalid."""
    lines = (samples / "crossing_example.csv").read_text("utf-8").splitlines()
    lat = lines[0].split(",").index("lat")
    out = [lines[0] + (",valid" if how == "invalid" else "")]
    for i, line in enumerate(lines[1:]):
        if how == "invalid":
            out.append(line + (",true" if ",B-" in line else ",false"))
            continue
        if how == "imei":
            for n, name in enumerate(("A-head", "A-eot", "B-head", "B-eot")):
                line = line.replace(f",{name},", f",86000{n},")
        out.append(line)
        if how == "twice" and i % 3 == 0:
            cells = line.split(",")
            cells[lat] = f"{float(cells[lat]) + 0.01:.6f}"
            out.append(",".join(cells))
    path = tmp_path / f"{how}.csv"
    path.write_text("\n".join(out) + "\n", "utf-8")
    return path


@pytest.mark.parametrize("how", ["twice", "imei", "invalid"])
def test_the_report_says_what_the_crossing_command_says_of_its_inputs(samples: Path, tmp_path: Path, how: str) -> None:
    """The two faces composed their input warnings apart: the report left out the conflicting instants, the
    position jumps, the invalid units and the merged trains that `trackside crossing` said of the same file."""
    path = _doctored(samples, tmp_path, how)
    said = _crossing(samples, path=path)["warnings"]
    assert said  # each doctored file has something to say
    res = runner.invoke(app, ["report", str(path), "--layout", "example", "--format", "json"])
    assert res.exit_code in (0, 1), res.output
    reported = [w.removeprefix("GNSS: ") for w in json.loads(res.stdout)["warnings"] if w.startswith("GNSS: ")]
    # Each face's advice on pairing devices is its own (the report has no --train).
    advice = ("give --train TRAIN=HEAD,EOT for each train", "name them <train>-head / <train>-eot")
    assert [w.replace(*advice) for w in said] == reported
