"""console.layout: TOML layouts, validated with errors a person can act on."""

from __future__ import annotations

from pathlib import Path

import pytest

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
