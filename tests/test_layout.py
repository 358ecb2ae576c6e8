"""console.layout: TOML layouts, validated with errors a person can act on."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from console.analysis.layout_checks import check_layout, layout_document
from console.layout import LayoutError, format_kilometre_post, load_layout, parse_kilometre_post

MINIMAL = """
[[heads]]
id = "WS1"
chainage_m = 0
[[heads]]
id = "WS2"
chainage_m = 500
[[sections]]
id = "T1"
bounds = [{ head = "WS1", sign = 1 }, { head = "WS2", sign = -1 }]
"""


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "line.toml"
    p.write_text(text, encoding="utf-8")
    return p


def test_shipped_osong_layout() -> None:
    lay = load_layout("osong")
    (head,) = lay.heads
    assert (head.id, head.spacing_m, head.device_id) == ("WS4", 0.13, 4083)
    assert lay.consist() is not None and lay.consist().length_m == 28.6  # type: ignore[union-attr]


def test_shipped_example_station_is_rich_enough() -> None:
    lay = load_layout("example")
    assert len(lay.heads) >= 4 and len(lay.sections) >= 3 and len(lay.crossings) >= 2
    assert len({p.station for p in lay.platforms}) >= 2
    assert len(lay.track) >= 10
    chainages = [p.chainage_m for p in lay.track]
    assert chainages == sorted(chainages)
    # every crossing and head lies on the track's chainage range
    lo, hi = chainages[0], chainages[-1]
    assert all(lo <= c.chainage_m <= hi for c in lay.crossings)
    assert all(lo <= h.chainage_m <= hi for h in lay.heads)
    assert [c.code for c in lay.crossings] == ["11+850", "12+940"]


def test_sections_of_a_head_with_signs() -> None:
    lay = load_layout("example")
    assert [(s.id, sign) for s, sign in lay.sections_of("WS2")] == [("1G", -1), ("B1", 1)]


def test_minimal_layout_loads(tmp_path: Path) -> None:
    lay = load_layout(_write(tmp_path, MINIMAL))
    assert lay.sections[0].heads == ("WS1", "WS2")


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            ('head = "WS2", sign = -1', 'head = "WS9", sign = -1'),
            "sections[0].bounds[1].head: expected one of WS1, WS2, found 'WS9'",
        ),
        (('head = "WS2", sign = -1', 'head = "WS2", sign = 2'), "sections[0].bounds[1].sign: expected 1"),
        (("chainage_m = 500", 'chainage_m = "far"'), "heads[1].chainage_m: expected a number, found 'far'"),
        (('id = "WS2"', 'id = "WS1"'), "heads[1].id: expected a head id not used before, found 'WS1'"),
        (('id = "T1"\n', ""), "sections[0].id: expected a string, found nothing"),
    ],
)
def test_errors_name_file_key_expected_and_found(tmp_path: Path, change: tuple[str, str], message: str) -> None:
    p = _write(tmp_path, MINIMAL.replace(*change))
    with pytest.raises(LayoutError) as err:
        load_layout(p)
    assert str(err.value).startswith(f"{p}: ") and message in str(err.value)


def test_bad_toml_and_missing_file(tmp_path: Path) -> None:
    with pytest.raises(LayoutError, match="not valid TOML"):
        load_layout(_write(tmp_path, "[[heads]\nid="))
    with pytest.raises(LayoutError, match="no such layout file"):
        load_layout(tmp_path / "nope.toml")


def test_kilometre_posts() -> None:
    assert parse_kilometre_post("11+850") == 11850.0
    assert format_kilometre_post(11850.0) == "11+850"
    assert format_kilometre_post(905.4) == "0+905"
    with pytest.raises(ValueError):
        parse_kilometre_post("11.850")


# --- hostile content: only LayoutError, naming the file and the key -------------------------

WITH_EVERYTHING = (
    MINIMAL
    + """
[[crossings]]
code = "0+250"
lat = 20.7
lon = 105.9
[[track]]
chainage_m = 0
lat = 20.70
lon = 105.90
[[track]]
chainage_m = 600
lat = 20.705
lon = 105.90
[[consists]]
id = "tram"
axles_m = [0, 2, 10, 12]
[[speed_limits]]
from_m = 0
to_m = 100
limit_mps = 10
[[work_sites]]
id = "W1"
head = "WS1"
distance_m = 50
"""
)


@pytest.mark.parametrize(
    ("change", "key"),
    [
        (("chainage_m = 500", "chainage_m = nan"), "heads[1].chainage_m: expected a finite number"),
        (("chainage_m = 500", "chainage_m = -inf"), "heads[1].chainage_m: expected a finite number"),
        (("chainage_m = 500", "chainage_m = 1e308"), "heads[1].chainage_m: expected a chainage in m within"),
        (("chainage_m = 500", "chainage_m = 1" + "0" * 400), "heads[1].chainage_m: expected a number of sensible"),
        (("chainage_m = 500", "chainage_m = 500\nspacing_m = 1e308"), "heads[1].spacing_m: expected a positive"),
        (("chainage_m = 500", "chainage_m = 500\nspacing_m = nan"), "heads[1].spacing_m: expected a finite"),
        (("chainage_m = 500", "chainage_m = 500\ndevice_id = " + "9" * 30), "heads[1].device_id: expected a dev"),
        (("lat = 20.70\n", "lat = 90\n"), "track[0].lat: expected a latitude in degrees within ±85"),
        (("lat = 20.705", "lat = -89.99"), "track[1].lat: expected a latitude"),
        (("lat = 20.705", "lat = nan"), "track[1].lat: expected a finite number"),
        (("lon = 105.90\n[[consists]]", "lon = inf\n[[consists]]"), "track[1].lon: expected a finite number"),
        (("lat = 20.7\n", "lat = 90.0\n"), "crossings[0].lat: expected a latitude"),
        (("axles_m = [0, 2, 10, 12]", "axles_m = [0, 2, nan, 12]"), "consists[0].axles_m: expected a list"),
        (("axles_m = [0, 2, 10, 12]", "axles_m = [0, 1e308]"), "consists[0].axles_m: expected a list"),
        (("limit_mps = 10", "limit_mps = 1e308"), "speed_limits[0].limit_mps: expected a positive number up to"),
        (("distance_m = 50", "distance_m = -1e300"), "work_sites[0].distance_m: expected a distance in m"),
        (('id = "T1"', 'id = "T1"\nname = [[[[[1]]]]]'), "sections[0].name: expected a string, found [[[[...]]]]"),
    ],
)
def test_absurd_numbers_are_refused_with_file_and_key(tmp_path: Path, change: tuple[str, str], key: str) -> None:
    assert change[0] in WITH_EVERYTHING
    p = _write(tmp_path, WITH_EVERYTHING.replace(*change, 1))
    with pytest.raises(LayoutError) as err:
        load_layout(p)
    assert str(err.value).startswith(f"{p}: ") and key in str(err.value)
    assert "\n" not in str(err.value)


def test_the_full_example_loads(tmp_path: Path) -> None:
    lay = load_layout(_write(tmp_path, WITH_EVERYTHING))
    assert len(lay.track) == 2 and lay.consists[0].length_m == 12.0


@pytest.mark.parametrize("depth", [200, 5000])
def test_deeply_nested_arrays_are_a_layout_error(tmp_path: Path, depth: int) -> None:
    # tomllib recurses once per level: 5000 levels raise RecursionError inside it
    p = _write(tmp_path, MINIMAL + "\n[line]\nname = " + "[" * depth + "]" * depth + "\n")
    with pytest.raises(LayoutError) as err:
        load_layout(p)
    assert str(err.value).startswith(f"{p}: ") and len(str(err.value)) < 300


# Random and mutated layouts: whatever the content, load_layout returns a Layout or raises
# LayoutError; nothing else escapes.  50 examples keep this under a few seconds; set
# LAYOUT_FUZZ_EXAMPLES=2000 to search longer.
_TOKENS = [
    "nan", "inf", "-inf", "1e308", "-1e308", "0", "-0.0", "1" + "0" * 30, "90", "-90", "true",
    '"x"', "[]", "[[1]]", "{}", "{ head = \"WS1\" }", "\"\\u0000\"", "1979-05-27", "0x7f", "[" * 50 + "]" * 50,
]  # fmt: skip


@st.composite
def _mutated_layouts(draw: st.DrawFn) -> str:
    text = WITH_EVERYTHING
    lines = text.splitlines()
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.integers(0, len(lines) - 1))
        if "=" in lines[i]:
            key = lines[i].split("=")[0]
            value = draw(st.sampled_from(_TOKENS) | st.floats(allow_nan=True).map(repr) | st.integers().map(str))
            lines[i] = f"{key}= {value}"
        elif draw(st.booleans()):
            del lines[i]
    return "\n".join(lines) + "\n"


@settings(
    max_examples=int(os.environ.get("LAYOUT_FUZZ_EXAMPLES", "50")),
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(text=_mutated_layouts() | st.text(max_size=200))
def test_any_layout_content_gives_a_layout_or_a_layout_error(tmp_path: Path, text: str) -> None:
    p = tmp_path / "fuzz.toml"
    p.write_text(text, encoding="utf-8", errors="surrogatepass")
    try:
        lay = load_layout(p)
    except LayoutError as exc:
        assert str(exc).startswith(f"{p}: ")
        return
    assert lay.heads  # a layout that loads has its heads
    # What loads, `trackside layout` reads and checks: any track, crossings and signs; never a NaN in its JSON.
    json.dumps(layout_document(lay, check_layout(lay)), allow_nan=False)


def test_simulate_with_a_bad_layout_exits_2_with_one_line(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from console.cli.app import app

    p = _write(tmp_path, WITH_EVERYTHING.replace("lat = 20.70\n", "lat = 90\n"))
    res = CliRunner().invoke(app, ["simulate", "--layout", str(p), "-o", str(tmp_path / "out"), "--duration", "1m"])
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and "track[0].lat" in lines[0] and str(p) in lines[0]
    assert "internal error" not in res.output


def _with_head_id(head_id: str) -> str:
    quoted = json.dumps(head_id)  # a JSON string is a TOML basic string (\\uXXXX escapes and all)
    return WITH_EVERYTHING.replace('id = "WS2"', f"id = {quoted}").replace('head = "WS2"', f"head = {quoted}")


@pytest.mark.parametrize("head_id", ["", " WS2", "WS2\t", "WS2\n", "WS\x1b[2J", "WS\x00", "WS\x85"])
def test_a_head_id_no_log_can_carry_is_refused(tmp_path: Path, head_id: str) -> None:
    # A log's reader strips Trackinfo and rejects control characters, so such a head matches no record:
    # simulate wrote it into logs whose records of it were then all rejected (exit 0, half the run lost).
    from typer.testing import CliRunner

    from console.cli.app import app

    p = _write(tmp_path, _with_head_id(head_id))
    res = CliRunner().invoke(app, ["simulate", "--layout", str(p), "-o", str(tmp_path / "out"), "--duration", "1m"])
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and f"{p}: heads[1].id: expected a head id" in lines[0]
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("head_id", ["W S", "WS:2", "Ω2", "WS-2/a"])
def test_a_head_id_a_log_carries_loads(tmp_path: Path, head_id: str) -> None:
    lay = load_layout(_write(tmp_path, _with_head_id(head_id)))
    assert lay.heads[1].id == head_id and lay.sections[0].heads == ("WS1", head_id)


def test_each_head_keeps_its_own_spacing_in_the_speeds(tmp_path: Path) -> None:
    """A line whose heads differ in Sys1-Sys2 spacing (WS1 0.2 m, the others 0.13 m): each head's axle and
    whole-train speeds use its own spacing, in batch and from the archive, and match the simulator's truth;
    ``--spacing`` sets one for every head (WS1 then reads 35 % slow)."""
    import json
    from collections import defaultdict

    from typer.testing import CliRunner

    from console.cli.app import app
    from console.layouts import __file__ as layouts_init

    text = Path(layouts_init).with_name("example_station.toml").read_text(encoding="utf-8")
    assert text.count("spacing_m = 0.13") >= 2
    mixed = tmp_path / "mixed.toml"
    mixed.write_text(text.replace("spacing_m = 0.13", "spacing_m = 0.2", 1), encoding="utf-8")
    assert load_layout(mixed).heads[0].id == "WS1" and load_layout(mixed).spacing_m() == 0.13
    runner = CliRunner()
    run = tmp_path / "run"
    res = runner.invoke(app, ["simulate", "--layout", str(mixed), "-o", str(run), "--duration", "8m", "--seed", "3"])
    assert res.exit_code == 0, res.output
    truth: dict[str, list[float]] = defaultdict(list)
    for axle in json.loads((run / "truth.json").read_text())["axles"]:
        truth[axle["head"]].append(axle["speed_mps"] * 3.6)
    assert set(truth) == {"WS1", "WS2", "WS3", "WS4", "WS5"}

    def mean_axle_kmh(passages: list[dict[str, object]]) -> dict[str, float]:
        got: dict[str, list[float]] = defaultdict(list)
        for p in passages:
            got[str(p["counting_head"])] += [float(v) for v in p["speed_kmh_per_axle"] if v is not None]  # type: ignore[attr-defined]
        return {h: sum(v) / len(v) for h, v in got.items() if v}

    log = str(run / "diagnostic.log")
    res = runner.invoke(app, ["analyze", log, "--layout", str(mixed), "--json"])
    assert res.exit_code == 0, res.output
    assert "warning" not in res.stderr
    doc = json.loads(res.stdout)
    assert doc["settings"]["spacing_m"] == 0.13 and doc["settings"]["head_spacing_m"] == {"WS1": 0.2}
    batch = mean_axle_kmh(doc["passages"])
    for head, speeds in truth.items():
        assert batch[head] == pytest.approx(sum(speeds) / len(speeds), rel=0.01), head
    whole = {p["counting_head"]: p["speed_kmh_whole_train"] for p in doc["passages"] if p["kind"] == "train"}
    assert whole["WS1"] == pytest.approx(batch["WS1"], rel=0.05)

    archive = tmp_path / "archive"
    assert runner.invoke(app, ["ingest", "--archive", str(archive), "--layout", str(mixed), log]).exit_code == 0
    res = runner.invoke(app, ["report", "--archive", str(archive), "--format", "json", "-o", str(tmp_path / "r.json")])
    assert res.exit_code == 0, res.output
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["settings"]["head_spacing_m"] == {"WS1": 0.2}
    assert mean_axle_kmh(report["passages"]) == pytest.approx(batch)

    res = runner.invoke(app, ["analyze", log, "--layout", str(mixed), "--json", "--spacing", "0.13"])
    one = json.loads(res.stdout)
    assert one["settings"]["head_spacing_m"] == {}
    assert mean_axle_kmh(one["passages"])["WS1"] == pytest.approx(batch["WS1"] * 0.13 / 0.2, rel=1e-3)
    assert mean_axle_kmh(one["passages"])["WS2"] == pytest.approx(batch["WS2"], rel=1e-3)


def test_a_layout_from_a_device_is_bounded_and_a_byte_order_mark_is_read(tmp_path: Path) -> None:
    from console.layouts import __file__ as layouts_init

    with pytest.raises(LayoutError, match="over 16 MiB, not a layout file"):
        load_layout("/dev/zero")  # read without end: refused at the bound, memory stays small
    text = Path(layouts_init).with_name("example_station.toml").read_bytes()
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbf" + text)  # as some editors save
    assert [h.id for h in load_layout(bom).heads] == [h.id for h in load_layout("example").heads]


def test_a_track_point_at_the_place_of_the_one_before_is_refused(tmp_path: Path) -> None:
    # Every position would project onto that segment as 0 / 0: NaN chainages in `crossing` and `layout`.
    text = '[[heads]]\nid = "A"\nchainage_m = 100\n' + "".join(
        f"[[track]]\nchainage_m = {c}\nlat = 20.0\nlon = 105.0\n" for c in (0, 1000)
    )
    with pytest.raises(LayoutError, match=r"track\[1\]\.lat: expected a place other than track\[0\]'s"):
        load_layout(_write(tmp_path, text))
