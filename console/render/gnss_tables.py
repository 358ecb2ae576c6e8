"""GNSS fixes for people and for machines: Rich tables (80 columns) and a JSON document.

Times in the fix table are UTC (``parsers.nmea``); they are shown as UTC and
written as ISO 8601 with ``Z``.  Everything that came from a log (device
ids, file names) goes through :func:`console.safe_text.inert`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import pandas as pd
from rich import box
from rich.table import Table
from rich.text import Text

from console.analysis.timefmt import display, iso, iso_array
from console.jsonout import JSONParts, encode
from console.safe_text import inert
from parsers.report import ParseReport

FIXES_SHOWN = 200
DEVICES_SHOWN = 200
_MPS_TO_KMH = 3.6
_DAY_NS = 86_400 * 1_000_000_000


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


def _ns(value: Any) -> int | None:
    return None if value is None or pd.isna(value) else int(pd.Timestamp(value).value)


def iso_utc(value: Any) -> str | None:
    """A UTC timestamp → ``2026-01-19T10:05:00.600Z``; NaT → None."""
    return iso(_ns(value))


def _utc_ns(times: pd.Series) -> np.ndarray:
    """Times (UTC, or naive read as UTC) as int64 ns; NaT as int64 min."""
    if getattr(times.dt, "tz", None) is not None:
        times = times.dt.tz_convert(None)
    return np.asarray(times.to_numpy(dtype="datetime64[ns]")).view(np.int64)


def _float(value: Any) -> float | None:
    return None if value is None or pd.isna(value) else float(value)


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


def _floats(values: pd.Series) -> list[float | None]:
    out = values.to_numpy(dtype=float).astype(object)
    out[pd.isna(values).to_numpy()] = None
    return list(out.tolist())


def _fix_rows(fixes: pd.DataFrame) -> list[dict[str, Any]]:
    """The fixes as JSON rows (NaN and NaT → null), column by column."""
    times = fixes["time"]
    ns = _utc_ns(times) if len(fixes) else np.zeros(0, np.int64)
    iso_times = iso_array(ns)
    iso_times[pd.isna(times).to_numpy()] = None
    columns = (
        iso_times.tolist(),
        _floats(fixes["lat"]),
        _floats(fixes["lon"]),
        _floats(fixes["speed_mps"]),
        _floats(fixes["course_deg"]),
        fixes["valid"].to_numpy(dtype=bool).tolist(),
        *([str(v) for v in fixes[c].tolist()] for c in ("device", "role", "sentence", "file")),
        fixes["line"].to_numpy(dtype=np.int64).tolist(),
        [str(v) for v in fixes["fix_quality"].tolist()],
    )
    return [dict(zip(_FIX_KEYS, row, strict=True)) for row in zip(*columns, strict=True)]


def gnss_json(fixes: pd.DataFrame, report: ParseReport) -> dict[str, Any]:
    """The fixes and the parse report as plain JSON values (NaN and NaT → null)."""
    return {"fixes": _fix_rows(fixes), "parse_report": report.to_dict()}


def gnss_json_parts(fixes: pd.DataFrame, report: ParseReport) -> dict[str, Any]:
    """:func:`gnss_json` for :func:`console.jsonout.write`: the fixes as JSON text, block by block."""

    def blocks() -> Iterator[str]:
        yield "["
        for start in range(0, len(fixes), FIX_BLOCK):
            text = encode(_fix_rows(fixes.iloc[start : start + FIX_BLOCK]))
            yield ("," if start else "") + text[1:-1]
        yield "]"

    return {"fixes": JSONParts(blocks()), "parse_report": report.to_dict()}


class _Clock:
    """Times for a table: the date goes in the title when every time shares it."""

    def __init__(self, times: pd.Series) -> None:
        # Days from the ns, formatted once per distinct day (not per fix).
        known = times[times.notna()]
        ns = _utc_ns(known) if len(known) else np.zeros(0, np.int64)
        days = [display(int(d) * _DAY_NS)[:10] for d in np.unique(ns // _DAY_NS)]
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
    if value is None or pd.isna(value) or not math.isfinite(float(value)):
        return Text("–", style="dim")
    return Text(fmt.format(float(value) * scale))


def fixes_table(fixes: pd.DataFrame, limit: int = FIXES_SHOWN) -> Table:
    """One row per fix: time, device, position, speed (km/h), fix or not, what it came from.

    Course is left to the JSON (``gnss_json``) to keep the table within 80
    columns.

    Times are UTC; a row with the date opens each day when the table spans
    several.  Lines are ``file number:line`` when there are several files
    (the caption names them).
    """
    clock = _Clock(fixes["time"])
    # Object, not Arrow, strings: a file name that is not UTF-8 cannot become an Arrow string.
    files = [str(f) for f in pd.unique(fixes["file"].to_numpy(dtype=object))] if len(fixes) else []
    title = f"GNSS fixes ({len(fixes):,}"
    title += f", {int(fixes['valid'].sum()):,} valid" if len(fixes) else ""
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
    last_day: str | None = None
    r: Any
    for r in fixes.head(limit).itertuples(index=False):
        day = clock.day(r.time)
        if not clock.one_day and day is not None and day != last_day:
            t.add_row(Text(day, style="bold"))
            last_day = day
        line = f"{file_no[str(r.file)]}:{r.line}" if len(files) > 1 else str(r.line)
        t.add_row(
            clock.text(r.time, with_day=False),
            inert(r.device),
            _num(r.lat, "{:.5f}"),
            _num(r.lon, "{:.5f}"),
            _num(r.speed_mps, "{:.1f}", _MPS_TO_KMH),
            _fix_text(bool(r.valid), str(getattr(r, "fix_quality", ""))),
            inert(r.sentence or r.source),
            Text(line),
        )
    notes = []
    if len(fixes) > limit:
        notes.append(f"first {limit:,} of {len(fixes):,} fixes; --json has all")
    if len(files) == 1:
        notes.append(f"file {files[0]}")
    elif files:
        notes.append("files " + ", ".join(f"{i} = {name}" for name, i in file_no.items()))
    if notes:
        t.caption = inert("; ".join(notes))  # file names are log text: never markup
        t.caption_justify = "left"
    return t


def devices_table(fixes: pd.DataFrame, limit: int = DEVICES_SHOWN) -> Table:
    """Per device: role, fixes, valid fixes, first and last time (UTC, to the second), mean speed of valid fixes."""
    clock = _Clock(fixes["time"])
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
    if fixes.empty:
        return t
    # Devices in the grouping's order (the categories'), counted on the codes; the figures are grouped
    # reductions over the rows of the devices shown only (a file may hold a million devices).
    codes = fixes["device"].cat.codes.to_numpy()
    per_device = np.bincount(codes[codes >= 0], minlength=len(fixes["device"].cat.categories))
    observed = np.flatnonzero(per_device)
    in_shown = np.isin(codes, observed[:limit])
    rows = fixes[in_shown]
    by = rows.groupby("device", observed=True, sort=True)
    count = by.size()
    shown = count.index
    valid = rows["valid"].astype(bool)
    n_valid = valid.groupby(rows["device"], observed=True, sort=True).sum()
    first, last = by["time"].min(), by["time"].max()
    speed = rows["speed_mps"].where(valid).groupby(rows["device"], observed=True, sort=True).mean()
    pairs = pd.DataFrame(
        {"device": rows["device"].to_numpy(), "role": [str(x) for x in rows["role"].to_numpy()]}
    ).drop_duplicates()
    roles_of: dict[Any, set[str]] = {}
    for device, role in zip(pairs["device"].tolist(), pairs["role"].tolist(), strict=True):
        roles_of.setdefault(device, set()).add(role)
    for device in shown:
        roles = sorted(roles_of.get(device, set()) - {""})
        nv = int(n_valid[device])
        t.add_row(
            inert(device),
            inert("/".join(roles) or "–", style="" if roles else "dim"),
            Text(f"{int(count[device]):,}"),
            Text(f"{nv:,}", style="" if nv else "yellow"),
            clock.text(first[device], seconds=True),
            clock.text(last[device], seconds=True),
            _num(speed[device], "{:.1f}", _MPS_TO_KMH),
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
