"""GNSS fixes for people and for machines: Rich tables (80 columns) and a JSON document.

Times in the fix table are UTC (``parsers.gnss.nmea``); they are shown as UTC and
written as ISO 8601 with ``Z``.  Everything that came from a log (device
ids, file names) goes through :func:`console.safe_text.inert`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from rich import box
from rich.table import Table
from rich.text import Text

from console.analysis.timefmt import display, iso, iso_array
from console.jsonout import JSONParts, encode
from console.safe_text import inert
from parsers.gnss.fix_table import FIX_QUALITIES, NAT_NS, ROLES, SOURCES, FixColumns, NameTable, sentence_name
from parsers.report import ParseReport
from parsers.units import NS_PER_DAY

if TYPE_CHECKING:
    import pandas as pd

FIXES_SHOWN = 200
DEVICES_SHOWN = 200
DEGREE_DECIMALS = 5  # 1e-5 degree: about a metre, finer than a GNSS fix is good for
_MPS_TO_KMH = 3.6


def _table(title: str) -> Table:
    # One space of padding, on the right only: two-character gaps keep nine columns within 80.
    return Table(
        title=title,
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
        show_edge=False,
        padding=(0, 1, 0, 0),
        title_style="bold",
    )


def _columns(fixes: pd.DataFrame | FixColumns) -> FixColumns:
    """The fixes as numpy columns: the tables and the JSON read those (no pandas on a small input)."""
    return fixes if isinstance(fixes, FixColumns) else FixColumns.from_frame(fixes)


def _ns(value: Any) -> int | None:
    """A time as int ns (numpy int64 ns with NaT as NAT_NS, or a pandas Timestamp); None when unknown."""
    if value is None:
        return None
    if isinstance(value, int | np.integer):
        return None if int(value) == NAT_NS else int(value)
    import pandas as pd

    return None if pd.isna(value) else int(pd.Timestamp(value).value)


def iso_utc(value: Any) -> str | None:
    """A UTC timestamp → ``2026-01-19T10:05:00.600Z``; NaT → None."""
    return iso(_ns(value))


def _utc_ns(times: pd.Series) -> np.ndarray:
    """Times (UTC, or naive read as UTC) as int64 ns; NaT as int64 min."""
    if getattr(times.dt, "tz", None) is not None:
        times = times.dt.tz_convert(None)
    return np.asarray(times.to_numpy(dtype="datetime64[ns]")).view(np.int64)


def _float(value: Any) -> float | None:
    if value is None:
        return None
    f = float(value)
    return None if math.isnan(f) else f


_FIX_KEYS = (
    "time",
    "lat",
    "lon",
    "speed_mps",
    "course_deg",
    "valid",
    "device",
    "role",
    "sentence",
    "file",
    "line",
    "fix_quality",
)
# Fixes encoded per block: a million fixes never become a million dicts at once.
FIX_BLOCK = 10_000


def _floats(values: np.ndarray) -> list[float | None]:
    out = np.asarray(values, np.float64).astype(object)
    out[np.isnan(np.asarray(values, np.float64))] = None
    return list(out.tolist())


def _names(codes: np.ndarray, names: Sequence[str]) -> list[str]:
    if not len(codes):
        return []
    if isinstance(names, NameTable):
        return names.take(codes)  # only this block's names become strings (a file may name a million devices)
    table = np.empty(len(names), dtype=object)
    table[:] = [str(n) for n in names]
    return list(table[codes].tolist())


def _sentence_names(masks: np.ndarray) -> list[str]:
    """Sentence bit masks as their names ("RMC+GGA"): one name per distinct mask."""
    used, inverse = np.unique(masks, return_inverse=True)
    return _names(inverse.reshape(-1), [sentence_name(int(m)) for m in used]) if len(masks) else []


def _fix_rows(fixes: FixColumns) -> list[dict[str, Any]]:
    """The fixes as JSON rows (NaN and NaT → null), column by column."""
    iso_times = iso_array(fixes.time_ns)
    iso_times[fixes.time_ns == NAT_NS] = None
    columns = (
        iso_times.tolist(),
        _floats(fixes.lat),
        _floats(fixes.lon),
        _floats(fixes.speed_mps),
        _floats(fixes.course_deg),
        fixes.valid.astype(bool).tolist(),
        _names(fixes.device_codes, fixes.device_names),
        _names(fixes.role, ROLES),
        _sentence_names(fixes.sentence),
        _names(fixes.file_codes, fixes.file_names),
        fixes.line.astype(np.int64).tolist(),
        _names(fixes.fix_quality, FIX_QUALITIES),
    )
    return [dict(zip(_FIX_KEYS, row, strict=True)) for row in zip(*columns, strict=True)]


def gnss_json(fixes: pd.DataFrame | FixColumns, report: ParseReport) -> dict[str, Any]:
    """The fixes and the parse report as plain JSON values (NaN and NaT → null)."""
    return {"fixes": _fix_rows(_columns(fixes)), "parse_report": report.to_dict()}


def fix_rows(fixes: pd.DataFrame | FixColumns) -> Iterator[dict[str, Any]]:
    """The fixes of :func:`gnss_json`, one object each, made block by block."""
    cols = _columns(fixes)
    for start in range(0, len(cols), FIX_BLOCK):
        block = FixColumns(
            **{k: v if k.endswith("_names") else v[start : start + FIX_BLOCK] for k, v in vars(cols).items()}
        )
        yield from _fix_rows(block)


def gnss_json_parts(fixes: pd.DataFrame | FixColumns, report: ParseReport) -> dict[str, Any]:
    """:func:`gnss_json` for :func:`console.jsonout.write`: the fixes as JSON text, block by block."""
    cols = _columns(fixes)

    def blocks() -> Iterator[str]:
        yield "["
        for start in range(0, len(cols), FIX_BLOCK):
            block = FixColumns(
                **{k: v if k.endswith("_names") else v[start : start + FIX_BLOCK] for k, v in vars(cols).items()}
            )
            text = encode(_fix_rows(block))
            yield ("," if start else "") + text[1:-1]
        yield "]"

    return {"fixes": JSONParts(blocks()), "parse_report": report.to_dict()}


class _Clock:
    """Times for a table: the date goes in the title when every time shares it."""

    def __init__(self, times: Any) -> None:
        # Days from the ns, formatted once per distinct day (not per fix).
        ns = np.asarray(times, np.int64) if isinstance(times, np.ndarray) else _utc_ns(times)
        ns = ns[ns != NAT_NS]
        days = [display(int(d) * NS_PER_DAY)[:10] for d in np.unique(ns // NS_PER_DAY)]
        self.one_day = len(days) == 1
        self.note = f"{days[0]}, UTC" if self.one_day else "UTC" if days else ""

    @staticmethod
    def day(value: Any) -> str | None:
        ns = _ns(value)
        return None if ns is None else display(ns)[:10]

    def text(self, value: Any, *, seconds: bool = False, with_day: bool | None = None) -> Text:
        """The time of day (and the date unless one day or ``with_day`` False); ``seconds``: no fraction."""
        ns = _ns(value)
        if ns is None:
            return Text("–", style="dim")
        shown = display(ns)
        if seconds:
            shown = shown[:19]
        show_day = not self.one_day if with_day is None else with_day
        return Text(shown if show_day else shown[11:])


def _num(value: Any, fmt: str, scale: float = 1.0) -> Text:
    f = _float(value)
    if f is None or not math.isfinite(f):
        return Text("–", style="dim")
    return Text(fmt.format(f * scale))


def _degrees_format(values: np.ndarray, most: int = DEGREE_DECIMALS) -> str:
    """Degrees with as many decimals as the values carry, up to ``most`` (about a metre): a monitoring-centre
    table that gives 20.7 is shown 20.7, not 20.70000, a precision it never had."""
    finite = values[np.isfinite(values)]
    for decimals in range(most):
        if np.all(np.abs(np.round(finite, decimals) - finite) < 1e-9):
            return f"{{:.{decimals}f}}"
    return f"{{:.{most}f}}"


def fixes_table(fixes: pd.DataFrame | FixColumns, limit: int = FIXES_SHOWN) -> Table:
    """One row per fix: time, device, position, speed (km/h), fix or not, what it came from.

    Course is left to the JSON (``gnss_json``) to keep the table within 80
    columns.

    Times are UTC; a row with the date opens each day when the table spans
    several.  Lines are ``file number:line`` when there are several files
    (the caption names them).
    """
    cols = _columns(fixes)
    clock = _Clock(cols.time_ns)
    # Files in order of appearance in the rows (as shown), numbered from 1.
    used, first = np.unique(cols.file_codes, return_index=True)
    files = [cols.file_names[int(c)] for c in used[np.argsort(first, kind="stable")]]
    n = len(cols)
    title = f"GNSS fixes ({n:,}"
    title += f", {int(np.count_nonzero(cols.valid)):,} valid" if n else ""
    t = _table(title + (f"; {clock.note})" if clock.note else ")"))
    t.add_column("Time", no_wrap=True)
    t.add_column("Device", no_wrap=True, max_width=14)
    t.add_column("Lat °", justify="right", no_wrap=True)
    t.add_column("Lon °", justify="right", no_wrap=True)
    t.add_column("km/h", justify="right", no_wrap=True)
    t.add_column("Fix", no_wrap=True)
    t.add_column("From", no_wrap=True)
    t.add_column("Line", justify="right", no_wrap=True)
    file_no = {name: i for i, name in enumerate(files, start=1)}
    shown = min(limit, n)
    lat_fmt, lon_fmt = (_degrees_format(np.asarray(v[:shown], float)) for v in (cols.lat, cols.lon))
    last_day: str | None = None
    for i in range(shown):
        time_ns = cols.time_ns[i]
        day = clock.day(time_ns)
        if not clock.one_day and day is not None and day != last_day:
            t.add_row(Text(day, style="bold"))
            last_day = day
        file = cols.file_names[int(cols.file_codes[i])]
        line = f"{file_no[file]}:{int(cols.line[i])}" if len(files) > 1 else str(int(cols.line[i]))
        t.add_row(
            clock.text(time_ns, with_day=False),
            inert(cols.device_names[int(cols.device_codes[i])]),
            _num(cols.lat[i], lat_fmt),
            _num(cols.lon[i], lon_fmt),
            _num(cols.speed_mps[i], "{:.1f}", _MPS_TO_KMH),
            _fix_text(bool(cols.valid[i]), FIX_QUALITIES[int(cols.fix_quality[i])]),
            inert(sentence_name(int(cols.sentence[i])) or SOURCES[int(cols.source[i])]),
            Text(line),
        )
    notes = []
    if n > limit:
        notes.append(f"first {limit:,} of {n:,} fixes; --json has all")
    if len(files) == 1:
        notes.append(f"Line: the line of {files[0]}")
    elif files:
        notes.append("Line: file:line, files " + ", ".join(f"{i} = {name}" for name, i in file_no.items()))
    if notes:
        t.caption = inert("; ".join(notes))  # file names are log text: never markup
        t.caption_justify = "left"
    return t


def devices_table(fixes: pd.DataFrame | FixColumns, limit: int = DEVICES_SHOWN) -> Table:
    """Per device: role, fixes, valid fixes, first and last time (UTC, to the second), mean speed of valid fixes."""
    cols = _columns(fixes)
    clock = _Clock(cols.time_ns)
    t = _table("GNSS devices" + (f" ({clock.note})" if clock.note else ""))
    t.add_column("Device", no_wrap=True, min_width=6, max_width=12)
    t.add_column("Role", no_wrap=True)
    t.add_column("Fixes", justify="right", no_wrap=True)
    t.add_column("Valid", justify="right", no_wrap=True)
    t.add_column("First", no_wrap=True)
    t.add_column("Last", no_wrap=True)
    t.add_column("km/h", justify="right", no_wrap=True)
    t.caption = Text("km/h: mean speed of the valid fixes", style="dim")
    t.caption_justify = "left"
    if not len(cols):
        return t
    # Devices in the order of their names (first appearance), each figure one reduction over the codes:
    # no Python per fix, and only the devices shown are looked at (a file may hold a million devices).
    n_names = len(cols.device_names)
    per_device = np.bincount(cols.device_codes, minlength=n_names)
    observed = np.flatnonzero(per_device)
    shown = observed[:limit]
    # The other figures over the rows of the devices shown only, numbered 0 … len(shown) - 1 in that order.
    local = np.full(n_names, -1, np.int64)
    local[shown] = np.arange(len(shown))
    at = local[cols.device_codes]
    rows = np.flatnonzero(at >= 0)
    codes = at[rows]
    del local, at
    n_shown = len(shown)
    valid = cols.valid[rows].astype(bool)
    times = cols.time_ns[rows]
    n_valid = np.bincount(codes, weights=valid, minlength=n_shown)
    timed = times != NAT_NS
    first = np.full(n_shown, np.iinfo(np.int64).max)
    last = np.full(n_shown, NAT_NS)
    np.minimum.at(first, codes[timed], times[timed])
    np.maximum.at(last, codes[timed], times[timed])
    speed = cols.speed_mps[rows]
    moving = valid & ~np.isnan(speed)
    speed_sum = np.bincount(codes[moving], weights=speed[moving], minlength=n_shown)
    speed_n = np.bincount(codes[moving], minlength=n_shown)
    has_role = np.zeros((n_shown, len(ROLES)), bool)
    has_role[codes, cols.role[rows].astype(np.int64)] = True
    for d, device in enumerate(shown.tolist()):  # d: the figures' index; device: the name's
        roles = sorted(ROLES[r] for r in np.flatnonzero(has_role[d]) if ROLES[r])
        nv = int(n_valid[d])
        t.add_row(
            inert(cols.device_names[device]),
            inert("/".join(roles) or "–", style="" if roles else "dim"),
            Text(f"{int(per_device[device]):,}"),
            Text(f"{nv:,}", style="" if nv else "yellow"),
            clock.text(first[d] if last[d] != NAT_NS else NAT_NS, seconds=True),
            clock.text(last[d], seconds=True),
            _num(speed_sum[d] / speed_n[d] if speed_n[d] else math.nan, "{:.1f}", _MPS_TO_KMH),
        )
    if len(observed) > limit:
        t.caption = Text(
            f"first {limit:,} of {len(observed):,} devices; km/h: mean speed of the valid fixes", style="dim"
        )
    return t


def _fix_text(valid: bool, quality: str) -> Text:
    """``yes``, ``DR`` (a dead-reckoned fix: valid, but not from satellites) or ``no``."""
    if not valid:
        return Text("no", style="dim")
    return Text("DR", style="yellow") if quality == "dead_reckoning" else Text("yes", style="green")


def skipped_table(report: ParseReport) -> Table | None:
    """What was recognised and passed over on purpose (binary packets, extra columns …), by kind; None if nothing."""
    if not report.skipped:
        return None
    t = _table("Skipped, not read")
    t.add_column("What", overflow="fold")
    t.add_column("Count", justify="right")
    for kind, count in sorted(report.skipped.items()):
        t.add_row(inert(kind), f"{count:,}")
    return t
