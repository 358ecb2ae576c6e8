"""`trackside layout`: a layout as the analyses read it, and the checks loading cannot make.

The truths come from the TOML itself, read here with tomllib (signs, chainages, the crossings' places), and
from the layout changed the way a hand editing it goes wrong: two signs swapped, both ends given +1, a
crossing's chainage mistyped, a head put beyond the track, the polyline left out.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from console.analysis.layout_checks import WARNING, check_layout
from console.cli.app import app
from console.layout import layout_from_dict

runner = CliRunner()
TRACKSIDE = str(Path(sys.executable).parent / "trackside")
EXAMPLE = resources.files("console.layouts").joinpath("example_station.toml").read_text("utf-8")


def _doc(args: list[str]) -> dict[str, Any]:
    r = runner.invoke(app, ["layout", *args, "--json"])
    assert r.exit_code == 0, r.output
    return json.loads(r.stdout)


def _write(tmp_path: Path, text: str, name: str = "line.toml") -> Path:
    p = tmp_path / name
    p.write_text(text, "utf-8")
    return p


def test_the_shipped_example_reads_as_its_toml_says_and_warns_of_nothing() -> None:
    toml = tomllib.loads(EXAMPLE)
    doc = _doc(["example"])
    assert doc["schema"] == "trackside.layout/1"
    assert doc["findings"] == []
    chainage = {h["id"]: h["chainage_m"] for h in toml["heads"]}
    assert [h["id"] for h in doc["heads"]] == sorted(chainage, key=chainage.__getitem__)
    for want, got in zip(toml["sections"], doc["sections"], strict=True):
        assert got["enter"] == [b["head"] for b in want["bounds"] if b["sign"] == 1]
        assert got["leave"] == [b["head"] for b in want["bounds"] if b["sign"] == -1]
        at = [chainage[b["head"]] for b in want["bounds"]]
        assert (got["from_m"], got["to_m"], got["length_m"]) == (min(at), max(at), max(at) - min(at))
        inside = [c["code"] for c in toml["crossings"] if min(at) <= c["chainage_m"] <= max(at)]
        assert got["crossings"] == inside
    # The example's crossings were placed on its polyline: coordinates and chainage agree to a metre.
    for c in doc["crossings"]:
        assert c["track_offset_m"] < 1.0
        assert abs(c["track_chainage_m"] - c["chainage_m"]) < 1.0
    assert {c["code"]: c["section"] for c in doc["crossings"]} == {"11+850": "B1", "12+940": "B2"}


def test_a_layout_of_heads_alone_has_no_note_about_sections() -> None:
    doc = _doc(["osong"])
    assert doc["findings"] == [] and doc["sections"] == [] and [h["id"] for h in doc["heads"]] == ["WS4"]


def _edited(**swaps: str) -> str:
    text = EXAMPLE
    for old, new in swaps.values():  # type: ignore[misc]
        assert old in text
        text = text.replace(old, new, 1)
    return text


SWAP_B1 = (
    '{ head = "WS2", sign = 1 }, { head = "WS3", sign = -1 }',
    '{ head = "WS2", sign = -1 }, { head = "WS3", sign = 1 }',
)
ONE_SIGN_2G = (
    '{ head = "WS4", sign = 1 }, { head = "WS5", sign = -1 }',
    '{ head = "WS4", sign = 1 }, { head = "WS5", sign = 1 }',
)
MOVED_12940 = ("\nchainage_m = 12940\n", "\nchainage_m = 12490\n")


def test_each_hand_made_mistake_is_named_once_and_strict_exits_1(tmp_path: Path) -> None:
    text = _edited(a=SWAP_B1, b=ONE_SIGN_2G, c=MOVED_12940)  # type: ignore[arg-type]
    text += '\n[[heads]]\nid = "WS9"\nchainage_m = 15000\n'
    path = _write(tmp_path, text)
    doc = _doc([str(path)])
    got = sorted((f["level"], f["check"], f["subject"]) for f in doc["findings"])
    assert got == [
        ("note", "head_unused", "WS9"),
        ("warning", "crossing_position", "12+940"),
        ("warning", "head_off_track", "WS9"),
        ("warning", "section_one_way", "2G"),
        ("warning", "section_signs", "B1"),
    ]
    moved = next(f for f in doc["findings"] if f["check"] == "crossing_position")
    # Its coordinates still say 12+940: 450 m up the line from the chainage typed.
    assert "450 m up the line" in moved["message"] and "12+490" in moved["message"]
    assert runner.invoke(app, ["layout", str(path)]).exit_code == 0
    strict = runner.invoke(app, ["layout", str(path), "--strict"])
    assert strict.exit_code == 1
    assert "4 warnings, 1 note" in strict.stdout
    for line in (
        "section B1: an up train enters at WS3 (12+400) but leaves at WS2 (10+650)",
        "section 2G: every bound has sign +1",
    ):
        assert line in " ".join(strict.stdout.split())


def test_crossings_without_a_track_are_warned_of(tmp_path: Path) -> None:
    text = re.sub(r"\[\[track\]\]\n(?:[a-z_]+ = [^\n]+\n)+", "", EXAMPLE)
    assert "[[track]]" not in text
    doc = _doc([str(_write(tmp_path, text))])
    assert doc["track"] is None
    assert sorted((f["check"], f["subject"]) for f in doc["findings"]) == [
        ("crossing_no_track", "11+850"),
        ("crossing_no_track", "12+940"),
    ]


def test_names_from_the_file_are_shown_as_data(tmp_path: Path) -> None:
    text = EXAMPLE.replace('name = "Phú Xuyên platform track"', 'name = "[bold red]X[/] \\u001b[31m"')
    r = runner.invoke(app, ["layout", str(_write(tmp_path, text))], env={"COLUMNS": "250"})
    assert r.exit_code == 0, r.output
    assert "[bold red]X[/] \\x1b[31m" in r.stdout
    assert "\x1b" not in r.stdout


def test_the_plot_is_drawn_in_the_format_asked_and_never_over_the_layout(tmp_path: Path) -> None:
    for name, magic in (("line.png", b"\x89PNG\r\n\x1a\n"), ("line.svg", b"<?xml")):
        r = runner.invoke(app, ["layout", "example", "--plot", str(tmp_path / name)])
        assert r.exit_code == 0, r.output
        assert (tmp_path / name).read_bytes().startswith(magic)
    svg = (tmp_path / "line.svg").read_text("utf-8")
    for label in ("WS1", "WS5", "1G", "2G", "11+850", "12+940", "Phú Xuyên"):
        assert f">{label}<" in svg or label in svg
    assert "check its signs" not in svg
    bad = _write(tmp_path, _edited(a=SWAP_B1))  # type: ignore[arg-type]
    runner.invoke(app, ["layout", str(bad), "--plot", str(tmp_path / "bad.svg")])
    assert "B1 (check its signs)" in (tmp_path / "bad.svg").read_text("utf-8")
    before = bad.read_bytes()
    link = tmp_path / "plot.png"
    link.symlink_to(bad)  # a name that looks like a plot, and is the layout
    for target, why in ((link, "input"), (bad, ".png or .svg"), (tmp_path / "x.pdf", ".png or .svg")):
        r = runner.invoke(app, ["layout", str(bad), "--plot", str(target)])
        assert r.exit_code == 2, (target, r.output)
        assert why in r.output and len(r.output.strip().splitlines()) == 1
    assert bad.read_bytes() == before
    folder = tmp_path / "dir.png"
    folder.mkdir()
    r = runner.invoke(app, ["layout", str(bad), "--plot", str(folder)])
    assert r.exit_code == 2 and "is a directory" in r.output


def test_a_missing_or_broken_layout_is_one_line_and_exit_2(tmp_path: Path) -> None:
    for args, said in (
        (["nowhere.toml"], "no such layout file"),
        ([str(_write(tmp_path, "[[heads]]\nid = 3\n"))], "heads[0].id"),
    ):
        p = subprocess.run([TRACKSIDE, "layout", *args], capture_output=True, text=True, cwd=tmp_path)
        assert p.returncode == 2, p.stderr
        assert said in p.stderr and len(p.stderr.strip().splitlines()) == 1 and "Traceback" not in p.stderr


@st.composite
def _line(draw: st.DrawFn) -> tuple[dict[str, Any], int | None]:
    """A line of heads at increasing chainage, a section between each pair of neighbours with the signs right,
    and maybe one section's signs swapped (its index)."""
    n = draw(st.integers(2, 8))
    gaps = draw(st.lists(st.integers(1, 5000), min_size=n - 1, max_size=n - 1))
    at = [10_000 + sum(gaps[:i]) for i in range(n)]
    heads = [{"id": f"H{i}", "chainage_m": at[i]} for i in range(n)]
    sections = [
        {"id": f"S{i}", "bounds": [{"head": f"H{i}", "sign": 1}, {"head": f"H{i + 1}", "sign": -1}]}
        for i in range(n - 1)
    ]
    swapped = draw(st.none() | st.integers(0, n - 2))
    if swapped is not None:
        for b in sections[swapped]["bounds"]:
            b["sign"] = -b["sign"]
    order = draw(st.permutations(range(n)))  # a file may list heads in any order
    return {"heads": [heads[i] for i in order], "sections": sections}, swapped


@settings(max_examples=150, deadline=None)
@given(_line())
def test_only_a_section_with_swapped_signs_is_warned_of(case: tuple[dict[str, Any], int | None]) -> None:
    doc, swapped = case
    warned = [(f.check, f.subject) for f in check_layout(layout_from_dict(doc, "random")) if f.level == WARNING]
    assert warned == ([] if swapped is None else [("section_signs", f"S{swapped}")])


def test_a_track_point_mistyped_is_named_by_its_segments(tmp_path: Path) -> None:
    # 20.745657 → 20.754657: a digit slipped, the point moved about 1 km north of the line.
    text = EXAMPLE.replace("lat = 20.745657", "lat = 20.754657", 1)
    doc = _doc([str(_write(tmp_path, text))])
    scale = [(f["subject"], f["message"]) for f in doc["findings"] if f["check"] == "track_scale"]
    assert [s for s, _ in scale] == ["track[1]", "track[2]"]
    assert all("the chainage says 250 m" in m for _, m in scale)


def test_commands_reading_a_doubtful_layout_say_so_in_one_line_and_go_on(tmp_path: Path) -> None:
    log = Path(__file__).resolve().parent.parent / "sample_logs" / "example_station.log"
    bad = _write(tmp_path, _edited(a=SWAP_B1))  # type: ignore[arg-type]
    for spec, said in ((str(bad), True), ("example", False)):
        p = subprocess.run(
            [TRACKSIDE, "sections", str(log), "--layout", spec, "--json"], capture_output=True, text=True, cwd=tmp_path
        )
        assert p.returncode == 0, p.stderr
        assert json.loads(p.stdout)["schema"] == "trackside.sections/1"
        warned = [line for line in p.stderr.splitlines() if "layout warning" in line]
        if said:
            named = f"{bad}: 1 layout warning (section_signs B1); `trackside layout {bad}` explains them"
            assert warned == [f"trackside: warning: {named}"]
        else:
            assert warned == []
