"""The HTML report's plots (matplotlib's SVG, inlined): real date axes, broken axes over gaps, same bytes, bounded."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from console.cli.app import app

runner = CliRunner()
NS = 1_000_000_000


def _figures(page: str) -> dict[str, str]:
    """Each inline SVG of the page by its title."""
    out = {}
    for svg in re.findall(r"<svg\b.*?</svg>", page, re.S):
        m = re.search(r"<title>([^<]*)</title>", svg)
        assert m is not None
        out[m.group(1)] = svg
    return out


def _texts(svg: str) -> list[str]:
    return [t.strip() for t in re.findall(r"<text\b[^>]*>([^<]*)</text>", svg)]


def _report_args(run: Path, out: Path) -> list[str]:
    logs = [str(run / "diagnostic-2015.log"), str(run / "diagnostic.log")]
    return ["report", *logs, "--format", "html", "--layout", str(run / "layout.toml"), "-o", str(out)]


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated run (2026-03-02), and its diagnostic log copied onto 2015-10-31."""
    run = tmp_path_factory.mktemp("eras") / "run"
    assert (
        runner.invoke(app, ["simulate", "-o", str(run), "--duration", "30m", "--trains-per-hour", "8"]).exit_code == 0
    )
    text = (run / "diagnostic.log").read_text(encoding="utf-8")
    assert "Date:2026-03-02" in text
    (run / "diagnostic-2015.log").write_text(text.replace("Date:2026-03-02", "Date:2015-10-31"), encoding="utf-8")
    return run


@pytest.fixture(scope="module")
def two_eras(run: Path) -> str:
    """A report on the two copies of the run's diagnostic log, 2015 and 2026: one page."""
    page = run.parent / "r.html"
    res = runner.invoke(app, _report_args(run, page))
    assert res.exit_code in (0, 1), res.output
    return page.read_text(encoding="utf-8")


def test_speeds_of_2015_and_2026_are_two_panels_with_date_axes(two_eras: str) -> None:
    speed = _figures(two_eras)["Speed per passage"]
    texts = _texts(speed)
    assert not any("time of day" in t for t in texts)
    # One panel per stretch of data, each with its own date axis: its date written once at its end
    # (ConciseDateFormatter's offset), its ticks clock times.
    assert any("2015-Oct-31" in t for t in texts), texts
    assert any("2026-Mar-02" in t for t in texts), texts
    assert len(re.findall(r'id="speeds-axes_\d+"', speed)) == 2
    ticks = [t for t in texts if re.fullmatch(r"\d\d:\d\d(:\d\d)?", t)]
    assert 4 <= len(ticks) <= 16, ticks  # a few per panel, not a bar of overlapping labels


def test_the_page_has_no_script_no_url_and_unique_ids(two_eras: str) -> None:
    assert "<script" not in two_eras.lower()
    assert set(re.findall(r"https?://[^\s\"'<>)]+", two_eras)) == {"http://www.w3.org/2000/svg"}
    ids = re.findall(r' id="([^"]+)"', two_eras)
    assert len(ids) == len(set(ids))
    refs = set(re.findall(r'href="#([^"]+)"', two_eras)) | set(re.findall(r"url\(#([^)]+)\)", two_eras))
    assert refs <= set(ids)
    assert "<!DOCTYPE svg" not in two_eras and "<?xml" not in two_eras


def test_same_inputs_same_bytes(run: Path, two_eras: str, tmp_path: Path) -> None:
    again = tmp_path / "again.html"
    assert runner.invoke(app, _report_args(run, again)).exit_code in (0, 1)
    assert again.read_text(encoding="utf-8") == two_eras
    assert "Speed per passage" in two_eras and "Section states over time" in two_eras


def test_time_panels_split_at_long_gaps_only() -> None:
    from console.sinks.report.plots import spread_of

    day = 86_400 * NS
    t0 = 1_446_284_000 * NS  # 2015-10-31
    one_day = t0 + np.arange(0, day, 600 * NS)
    assert len(spread_of(one_day).panels()) == 1
    two_years = t0 + np.arange(0, 730) * day
    assert len(spread_of(two_years).panels()) == 1
    eras = np.concatenate([t0 + np.arange(10) * 60 * NS, t0 + 3774 * day + np.arange(10) * 60 * NS])
    panels = spread_of(eras).panels()
    assert panels == [(int(eras[0]), int(eras[9])), (int(eras[10]), int(eras[19]))]


def test_ten_years_of_passages_make_a_bounded_plot() -> None:
    from console.sinks.report.plots import SpeedSeries, speed_plot, spread_of

    rng = np.random.default_rng(1)
    t = np.sort(rng.integers(1_420_000_000 * NS, 1_735_000_000 * NS, 200_000))
    speeds = rng.uniform(20, 120, len(t))
    series = [SpeedSeries("WS1", lambda: (t, speeds, speeds * 0.98))]
    svg = speed_plot(series, spread_of(t), 120.0, "Speed per passage")
    assert len(svg) < 1_500_000
    assert "dense: range and mean per time bin" in svg
    texts = _texts(svg)
    assert any(re.fullmatch(r"20\d\d", x) for x in texts), texts  # a ten-year axis is labelled in years


def test_log_text_in_a_plot_is_inert() -> None:
    from console.sinks.report.plots import Line, lines_plot

    name = "$x$ \x1b[31m\u202e<script>"
    t = np.arange(5) * NS + 1_446_284_000 * NS
    svg = lines_plot([Line(name, t, np.arange(5.0))], f"Analog values at {name}", "analog value", None, "a0")
    assert "\x1b" not in svg and "\u202e" not in svg and "<script" not in svg
    assert "$x$ \\x1b[31m\\u202e&lt;script&gt;" in svg
