"""Fuzz every parser with damaged copies of the shipped samples and with random bytes.

Properties, for any input: the parser returns (or raises only
:class:`parsers.sources.InputError`, one line, for a file it cannot read at
all); every line is accounted for (``lines_read == records + blank +
rejected``, per file); every rejection has a line number and a reason; no
rejection shows a raw control, bidi or undecodable character; the parse
report serialises to UTF-8 JSON.  Layout files: a Layout or a LayoutError.

Inputs come from the seeded mutator in ``tests/fuzz_mutate.py`` (bit flips,
inserted/deleted bytes, truncation, repeated lines, extreme numbers and
dates and hostile strings in fields, UTF-16/Latin-1, CRLF/CR, gzip whole,
truncated or junk-tailed); Hypothesis picks the sample and the seed and
shrinks a failure to the smallest seed it can.

CI runs a small fixed set (derandomized, under ~20 s here).  The long run,
randomized, with the number of inputs tried per test::

    pytest -m fuzz --hypothesis-profile long --hypothesis-show-statistics -p no:cacheprovider

(``long`` is registered in tests/conftest.py: 2,000 examples per test.)
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from parsers.report import ParseReport
from parsers.sources import InputError, release_streams
from tests.fuzz_mutate import TRIED, field_variants, fuzz_settings, mutate, unsafe_in, write_stats

pytestmark = pytest.mark.fuzz


@pytest.fixture(autouse=True)
def _tally() -> Iterator[None]:
    yield
    write_stats()


ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_logs"
NMEA_DATA = ROOT.parent / "shared" / "data" / "nmea"
LAYOUTS = ROOT / "console" / "layouts"


def _diag(paths: list[Path]) -> ParseReport:
    from parsers.diag.read import read_diag

    return read_diag(paths)[1]


def _nmea(paths: list[Path]) -> ParseReport:
    try:
        from parsers.gnss.stream import parse_nmea
    except ImportError:  # before the GNSS stream split
        from parsers.gnss.nmea import parse_nmea  # type: ignore[attr-defined,no-redef]

    return parse_nmea(paths)[1]


def _gnss(paths: list[Path]) -> ParseReport:
    from parsers.gnss_files import parse_gnss

    return parse_gnss(paths)[1]


def _frames(paths: list[Path]) -> ParseReport:
    from parsers.frames.sensor import parse_frames

    return parse_frames(paths)[1]


def _can(paths: list[Path]) -> ParseReport:
    from parsers.frames.can import parse_can

    return parse_can(paths)[1]


def _voltages(paths: list[Path]) -> ParseReport:
    from parsers.voltages import read_voltages

    return read_voltages(paths)[1]


def _samples(*names: str) -> list[Path]:
    return [SAMPLES / n for n in names if (SAMPLES / n).exists()]


_NMEA_CAPTURES = sorted(p for p in NMEA_DATA.glob("*.log")) if NMEA_DATA.is_dir() else []

PARSERS: dict[str, tuple[Callable[[list[Path]], ParseReport], list[Path]]] = {
    "diag": (
        _diag,
        _samples("osong_ws4_0932_detection.log", "osong_ws4_0932_passage.log", "ws4_subsecond.log", "ws4_health.log"),
    ),
    "nmea": (_nmea, _NMEA_CAPTURES[:6]),
    "gnss": (
        _gnss,
        _samples("gnss_devices.csv", "gnss_devices.jsonl", "crossing_example.csv", "co_nhu_van_2026_centre_table.tsv"),
    ),
    "frames": (_frames, _samples("sensor_frames.txt")),
    "can": (_can, _samples("can_counts.log", "can_counts.asc", "can_counts.trc")),
    "voltages": (_voltages, _samples("am_thuong_2021-06-06_voltages.csv")),
}

_HEAD_BYTES = 64 << 10
# fuzz the first 64 KiB of a big capture: the damage matters, not the size


def check_report(report: ParseReport) -> None:
    """The properties every parse report keeps, whatever the input."""
    report.check()
    for f in report.files:
        assert f.lines_read == f.records + f.blank + f.rejected, f.to_dict()
    assert report.rejected == sum(report.rejected_by_reason.values())
    for r in report.rejections:
        assert r.line >= 1 and r.reason, r
        assert not unsafe_in(r.reason), (r.reason, unsafe_in(r.reason))
        assert not unsafe_in(r.text), (r.text, unsafe_in(r.text))
    json.dumps(report.to_dict(), ensure_ascii=False, allow_nan=False, default=str).encode("utf-8")


def run_parser(name: str, paths: list[Path]) -> ParseReport | None:
    parse, _ = PARSERS[name]
    try:
        report = parse(paths)
    except InputError as exc:
        assert "\n" not in str(exc).strip(), str(exc)
        return None
    finally:
        release_streams()
    check_report(report)
    return report


def _write(tmp: Path, sample: Path, data: bytes) -> Path:
    path = tmp / sample.name  # the name keeps its suffix: CAN formats are told by it
    path.write_bytes(data)
    return path


@pytest.mark.parametrize("name", list(PARSERS))
def test_every_parser_reads_its_samples_with_nothing_lost(name: str) -> None:
    _, samples = PARSERS[name]
    if not samples:
        pytest.skip(f"no samples for {name}")
    report = run_parser(name, samples)
    assert report is not None and report.records > 0


@pytest.mark.parametrize("name", list(PARSERS))
def test_damaged_samples_are_parsed_or_rejected_line_by_line(
    name: str, tmp_path_factory: pytest.TempPathFactory
) -> None:
    _, samples = PARSERS[name]
    if not samples:
        pytest.skip(f"no samples for {name}")
    heads = [s.read_bytes()[:_HEAD_BYTES] for s in samples]

    @fuzz_settings(ci_examples=25)
    @given(index=st.integers(0, len(samples) - 1), seed=st.integers(0, 2**32 - 1))
    def damaged(index: int, seed: int) -> None:
        TRIED[f"parser {name}: damaged samples"] += 1
        data = mutate(heads[index], seed)
        run_parser(name, [_write(tmp, samples[index], data)])

    tmp = tmp_path_factory.mktemp(name)

    damaged()


@pytest.mark.parametrize("name", list(PARSERS))
def test_extreme_numbers_dates_and_hostile_strings_in_every_field(name: str, tmp_path: Path) -> None:
    """Each field of the first records, in turn, holding each extreme value (2**64, 5000 digits, nan,
    0001-01-01, 2262-04-12, 9999-12-31, markup, ESC, bidi, NUL, a lone surrogate ...): one line each."""
    _, samples = PARSERS[name]
    if not samples:
        pytest.skip(f"no samples for {name}")
    for sample in samples:
        variants = field_variants(sample.read_bytes()[:_HEAD_BYTES])
        TRIED[f"parser {name}: extreme field values (lines)"] += variants.count(b"\n")
        run_parser(name, [_write(tmp_path, sample, variants)])


@pytest.mark.parametrize("name", list(PARSERS))
def test_random_bytes_are_parsed_or_rejected_line_by_line(name: str, tmp_path_factory: pytest.TempPathFactory) -> None:
    _, samples = PARSERS[name]
    if not samples:
        pytest.skip(f"no samples for {name}")

    @fuzz_settings(ci_examples=10)
    @given(data=st.binary(max_size=4000), index=st.integers(0, len(samples) - 1))
    def random_bytes(data: bytes, index: int) -> None:
        TRIED[f"parser {name}: random bytes"] += 1
        run_parser(name, [_write(tmp, samples[index], data)])

    tmp = tmp_path_factory.mktemp(name)

    random_bytes()


@pytest.mark.parametrize("name", list(PARSERS))
@pytest.mark.parametrize(
    "file_name",
    [b"log\xff.txt", b"new\nline.log", b"-dash.log", b"[bold]x[red]", b"\xe2\x80\xaeevil.log", b"\x1b[31m.log"],
    ids=["0xff", "newline", "dash", "markup", "bidi", "escape"],
)
def test_hostile_file_names_are_read_and_shown_escaped(
    name: str, file_name: bytes, tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    import os

    _, samples = PARSERS[name]
    if not samples:
        pytest.skip(f"no samples for {name}")
    suffix = samples[0].suffix.encode()
    path = Path(os.fsdecode(os.fsencode(tmp_path) + b"/" + file_name + suffix))
    path.write_bytes(samples[0].read_bytes()[:_HEAD_BYTES])
    report = run_parser(name, [path])
    assert report is not None
    shown = json.dumps(report.to_dict(), ensure_ascii=False)
    assert not unsafe_in(shown.replace("\\n", "")), unsafe_in(shown)


# --------------------------------------------------------------- layouts


def _layout(path: Path) -> Any:
    from console.layout import LayoutError, load_layout

    try:
        return load_layout(str(path))
    except LayoutError as exc:
        assert str(exc).strip(), "a LayoutError says why"
        return None


@pytest.mark.parametrize("sample", sorted(LAYOUTS.glob("*.toml")), ids=lambda p: p.name)
def test_damaged_layouts_load_or_fail_with_a_layout_error(
    sample: Path, tmp_path_factory: pytest.TempPathFactory
) -> None:
    text = sample.read_bytes()

    @fuzz_settings(ci_examples=30)
    @given(seed=st.integers(0, 2**32 - 1))
    def damaged(seed: int) -> None:
        TRIED[f"layout {sample.name}: damaged"] += 1
        path = tmp_path_factory.mktemp("layout") / "layout.toml"
        path.write_bytes(mutate(text, seed))
        _layout(path)

    assert _layout(sample) is not None
    damaged()


def test_a_layout_with_a_5000_digit_number_is_a_layout_error(tmp_path: Path) -> None:
    # Found by the long fuzz run (seed 29083619): Python refuses ints over 4300 digits with a ValueError.
    from console.layout import LayoutError, load_layout

    path = tmp_path / "layout.toml"
    path.write_text((LAYOUTS / "example_station.toml").read_text(encoding="utf-8") + f"\nextra = {'9' * 5000}\n")
    with pytest.raises(LayoutError):
        load_layout(str(path))
