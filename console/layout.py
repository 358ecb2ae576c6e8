"""Line and station layouts (TOML) → a validated model.

A layout says where the counting heads are, which heads bound which
sections and with which sign, where the level crossings are, the track's
polyline and the train consists.  Every error names the file, the key, what
was expected and what was found, so a maintainer can fix the file.

Direction: *up* is increasing chainage.  ``up`` on a counting head is the
channel order a train running up produces (``sys1_to_sys2`` for two-channel
heads, ``s1_to_s3`` for three-element intelligent sensors).  A section bound
``sign`` is +1 when a train running up past that head *enters* the section
(the head at the section's low-chainage end) and −1 when it leaves it.

Shipped layouts: ``osong`` (the Osong tram test line of seed 003: one head,
WS4, 0.13 m coil spacing) and ``example`` (a station pair with five heads,
four sections, two level crossings and two platforms).
"""

from __future__ import annotations

import itertools
import math
import re
import reprlib
import tomllib
from collections import Counter
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

BUILTIN = {"osong": "osong.toml", "example": "example_station.toml"}

# Bounds on what a layout may say.  They are far beyond any real line; they
# exist so that a typo (1e308, nan, a pole) is refused here with its key,
# instead of overflowing into NaN or an internal error in the analysis.
MAX_CHAINAGE_M = 1e7  # 10 000 km of line, either side of zero
MAX_SPACING_M = 10.0  # coils or elements of one head sit centimetres apart
MAX_TRAIN_LENGTH_M = 5000.0  # the longest freight trains are under 4 km
MAX_SPEED_MPS = 200.0  # 720 km/h
MAX_TIME_S = 86400.0  # a warning time or similar of more than a day is a typo
MAX_LATITUDE_DEG = 85.0  # no railway runs nearer the poles; the local plane degenerates there
MAX_DEVICE_ID = (1 << 31) - 1  # stored as a 32-bit integer downstream
UP_ORDERS = {2: ("sys1_to_sys2", "sys2_to_sys1"), 3: ("s1_to_s3", "s3_to_s1")}
_KP = re.compile(r"^(\d+)\+(\d{3})$")
# What a log's Trackinfo field can carry: its reader strips the field and rejects control
# characters, so a head id with them (or empty) could never match a record of the head.
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")


DEFAULT_SPACING_M = 0.13
# A layout of a whole network is some hundred kB; a bound keeps a device or a pipe from filling memory.
MAX_LAYOUT_BYTES = 16 * 2**20


class LayoutError(ValueError):
    """A layout file that cannot be used, with the place and the fix."""


@dataclass(frozen=True)
class CountingHead:
    id: str  # as in the log's Trackinfo
    chainage_m: float
    spacing_m: float = DEFAULT_SPACING_M  # Sys1–Sys2 (or element) spacing
    channels: int = 2
    up: str = "sys1_to_sys2"
    device_id: int | None = None
    analog_band: tuple[float, float] | None = None

    @property
    def up_is_first_channel_first(self) -> bool:
        """True when a train running up reaches channel 1 first."""
        return self.up in ("sys1_to_sys2", "s1_to_s3")


@dataclass(frozen=True)
class SectionBound:
    head: str
    sign: int  # +1: an up train passing this head enters the section


@dataclass(frozen=True)
class Section:
    id: str
    bounds: tuple[SectionBound, ...]
    name: str = ""

    @property
    def heads(self) -> tuple[str, ...]:
        return tuple(b.head for b in self.bounds)


@dataclass(frozen=True)
class LevelCrossing:
    code: str  # kilometre post, e.g. "11+850"
    chainage_m: float
    lat: float
    lon: float
    warning_time_s: float = 70.0
    d_off_m: float = 30.0  # the end of train must be this far past the crossing
    name: str = ""


@dataclass(frozen=True)
class WorkSite:
    """A track-worker warning point a known distance beyond an approach counting head."""

    id: str
    head: str  # the approach head
    distance_m: float  # from the head to the site along the track: + up the line, − down
    warning_time_s: float = 30.0


@dataclass(frozen=True)
class TrackPoint:
    chainage_m: float
    lat: float
    lon: float


@dataclass(frozen=True)
class Platform:
    station: str
    from_m: float
    to_m: float


@dataclass(frozen=True)
class Consist:
    id: str
    length_m: float  # first to last wheel
    axles_m: tuple[float, ...]  # from the first wheel
    name: str = ""


@dataclass(frozen=True)
class SpeedLimit:
    from_m: float
    to_m: float
    limit_mps: float


@dataclass(frozen=True)
class Layout:
    name: str
    source: str
    heads: tuple[CountingHead, ...]
    sections: tuple[Section, ...] = ()
    crossings: tuple[LevelCrossing, ...] = ()
    track: tuple[TrackPoint, ...] = ()
    platforms: tuple[Platform, ...] = ()
    consists: tuple[Consist, ...] = ()
    speed_limits: tuple[SpeedLimit, ...] = ()
    work_sites: tuple[WorkSite, ...] = ()
    line_speed_mps: float = 20.0
    # How the line's devices report ([devices]): a head silent this long has lost power or contact (None: not
    # judged); the GNSS units' report period and the radio's delay allowance (None: the analyses' defaults).
    power_gap_s: float | None = None
    gnss_report_period_s: float | None = None
    gnss_latency_s: float | None = None
    _by_id: dict[str, CountingHead] = field(default_factory=dict, compare=False, repr=False)

    def head(self, head_id: str) -> CountingHead:
        return self._by_id[head_id]

    def has_head(self, head_id: str) -> bool:
        return head_id in self._by_id

    def counted_head(self, head_id: str, device_id: int) -> CountingHead | None:
        """The head a log's records of ``head_id`` on device ``device_id`` count for: None when the layout has
        no such head, or gives it another device."""
        spec = self._by_id.get(head_id)
        if spec is None or (spec.device_id is not None and spec.device_id != device_id):
            return None
        return spec

    def sections_of(self, head_id: str) -> list[tuple[Section, int]]:
        """The sections a head bounds, with the sign it contributes to each."""
        return [(s, b.sign) for s in self.sections for b in s.bounds if b.head == head_id]

    def max_speed_mps(self, from_m: float, to_m: float) -> float:
        """The highest speed allowed anywhere between two chainages (limits, else the line speed)."""
        lo, hi = min(from_m, to_m), max(from_m, to_m)
        speeds = []
        covered = []
        for lim in self.speed_limits:
            if lim.to_m > lo and lim.from_m < hi:
                speeds.append(lim.limit_mps)
                covered.append((max(lim.from_m, lo), min(lim.to_m, hi)))
        covered.sort()
        reach = lo
        for a, b in covered:
            if a > reach:
                break
            reach = max(reach, b)
        if reach < hi or not speeds:
            speeds.append(self.line_speed_mps)  # some of the stretch has no limit of its own
        return max(speeds)

    def heads_off_track(self) -> list[str]:
        """Heads outside the [[track]] line's chainages (no simulated train runs past them); none without a track."""
        if len(self.track) < 2:
            return []
        low, high = self.track[0].chainage_m, self.track[-1].chainage_m
        return [h.id for h in self.heads if not low <= h.chainage_m <= high]

    def spacing_m(self) -> float:
        """The line's Sys1–Sys2 spacing: most heads' (the first head's of a tie), for heads the layout does not
        name; a head of another spacing keeps its own (``SpeedSettings.of_layout``)."""
        if not self.heads:
            return DEFAULT_SPACING_M
        return Counter(h.spacing_m for h in self.heads).most_common(1)[0][0]

    def consist(self, consist_id: str | None = None) -> Consist | None:
        if not self.consists:
            return None
        if consist_id is None:
            return self.consists[0]
        return next((c for c in self.consists if c.id == consist_id), None)


def parse_kilometre_post(code: str) -> float:
    """``11+850`` → 11850.0 m."""
    m = _KP.match(code.strip())
    if not m:
        raise ValueError(f"expected a kilometre post like 11+850, found {code!r}")
    return int(m[1]) * 1000.0 + int(m[2])


def format_kilometre_post(chainage_m: float) -> str:
    """11850.0 → ``11+850``."""
    metres = round(chainage_m)
    return f"{metres // 1000}+{metres % 1000:03d}"


class _Reader:
    """Typed access to a TOML table, raising LayoutError with the key path."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, key: str, expected: str, found: Any) -> LayoutError:
        shown = "nothing" if found is _MISSING else _SHOW.repr(found)
        return LayoutError(f"{self.source}: {key}: expected {expected}, found {shown}")

    def get(
        self, table: dict[str, Any], key: str, path: str, kind: type | tuple[type, ...], default: Any = None
    ) -> Any:
        value = table.get(key, _MISSING)
        if value is _MISSING:
            if default is not _REQUIRED:
                return default
            raise self.fail(f"{path}.{key}", _describe(kind), _MISSING)
        if kind is float and isinstance(value, int) and not isinstance(value, bool):
            if abs(value) > MAX_CHAINAGE_M * 1e3:  # float() of a 400-digit integer overflows
                raise self.fail(f"{path}.{key}", "a number of sensible size", value)
            return float(value)
        if kind is float and isinstance(value, float) and not math.isfinite(value):
            raise self.fail(f"{path}.{key}", "a finite number", value)
        if isinstance(value, bool) and kind is not bool:
            raise self.fail(f"{path}.{key}", _describe(kind), value)
        if not isinstance(value, kind):
            raise self.fail(f"{path}.{key}", _describe(kind), value)
        return value

    def req(self, table: dict[str, Any], key: str, path: str, kind: type | tuple[type, ...]) -> Any:
        return self.get(table, key, path, kind, _REQUIRED)

    def tables(self, doc: dict[str, Any], key: str) -> list[dict[str, Any]]:
        value = doc.get(key, [])
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self.fail(key, f"an array of tables ([[{key}]])", value)
        return value


_MISSING = object()
_REQUIRED = object()
# What a message shows of a bad value: cut short and shallow (a value may be a deeply nested array).
_SHOW = reprlib.Repr()  # keyword arguments only from Python 3.12
_SHOW.maxlevel, _SHOW.maxstring, _SHOW.maxother, _SHOW.maxlist, _SHOW.maxdict = 3, 60, 60, 8, 4


def _describe(kind: type | tuple[type, ...]) -> str:
    names = {str: "a string", float: "a number", int: "an integer", list: "an array", bool: "true or false"}
    if isinstance(kind, tuple):
        return " or ".join(names.get(k, k.__name__) for k in kind)
    return names.get(kind, kind.__name__)


def _positive(r: _Reader, value: float, key: str, limit: float = math.inf) -> float:
    if not 0 < value <= limit:
        expected = "a positive number" if limit == math.inf else f"a positive number up to {limit:g}"
        raise r.fail(key, expected, value)
    return value


def _within(r: _Reader, value: float, key: str, limit: float, what: str = "a number") -> float:
    """``value`` unless |value| > limit (NaN and infinities are refused by the reader already)."""
    if not -limit <= value <= limit:
        raise r.fail(key, f"{what} within ±{limit:g}", value)
    return value


def _chainage(r: _Reader, table: dict[str, Any], key: str, path: str, default: Any = _REQUIRED) -> float:
    value = r.get(table, key, path, float, default)
    return _within(r, value, f"{path}.{key}", MAX_CHAINAGE_M, "a chainage in m")


def _lat_lon(r: _Reader, table: dict[str, Any], path: str) -> tuple[float, float]:
    lat, lon = r.req(table, "lat", path, float), r.req(table, "lon", path, float)
    if not -MAX_LATITUDE_DEG <= lat <= MAX_LATITUDE_DEG:
        expected = f"a latitude in degrees within ±{MAX_LATITUDE_DEG:g} (no line runs nearer a pole)"
        raise r.fail(f"{path}.lat", expected, lat)
    if not -180 <= lon <= 180:
        raise r.fail(f"{path}.lon", "a longitude in degrees (-180..180)", lon)
    return lat, lon


def _head_id(r: _Reader, table: dict[str, Any], path: str) -> str:
    head_id: str = r.req(table, "id", path, str)
    if not head_id or head_id != head_id.strip() or _CONTROL.search(head_id):
        raise r.fail(
            f"{path}.id", "a head id as logs write it (not empty, no control characters or edge spaces)", head_id
        )
    return head_id


def _device_id(r: _Reader, table: dict[str, Any], path: str) -> int | None:
    device_id: int | None = r.get(table, "device_id", path, int, None)
    if device_id is not None and not 0 <= device_id <= MAX_DEVICE_ID:
        raise r.fail(f"{path}.device_id", f"a device number 0..{MAX_DEVICE_ID}", device_id)
    return device_id


def layout_from_dict(doc: dict[str, Any], source: str = "<layout>") -> Layout:
    """Validate a parsed TOML document into a :class:`Layout`."""
    r = _Reader(source)
    line = doc.get("line", {})
    if not isinstance(line, dict):
        raise r.fail("line", "a table [line]", line)
    name = r.get(line, "name", "line", str, Path(source).stem)
    line_speed = _positive(r, r.get(line, "speed_mps", "line", float, 20.0), "line.speed_mps", MAX_SPEED_MPS)

    heads: list[CountingHead] = []
    for i, t in enumerate(r.tables(doc, "heads")):
        p = f"heads[{i}]"
        channels = r.get(t, "channels", p, int, 2)
        if channels not in UP_ORDERS:
            raise r.fail(f"{p}.channels", "2 (Sys1, Sys2) or 3 (S1..S3)", channels)
        up = r.get(t, "up", p, str, UP_ORDERS[channels][0])
        if up not in UP_ORDERS[channels]:
            raise r.fail(f"{p}.up", " or ".join(UP_ORDERS[channels]), up)
        band = t.get("analog_band")
        if band is not None:
            ok = isinstance(band, list) and len(band) == 2
            ok = ok and all(isinstance(v, int | float) and not isinstance(v, bool) and abs(v) < 1e9 for v in band)
            if not ok or band[0] >= band[1]:
                raise r.fail(f"{p}.analog_band", "[low, high] with low < high", band)
            band = (float(band[0]), float(band[1]))
        heads.append(
            CountingHead(
                id=_head_id(r, t, p),
                chainage_m=_chainage(r, t, "chainage_m", p),
                spacing_m=_positive(
                    r, r.get(t, "spacing_m", p, float, DEFAULT_SPACING_M), f"{p}.spacing_m", MAX_SPACING_M
                ),
                channels=channels,
                up=up,
                device_id=_device_id(r, t, p),
                analog_band=band,
            )
        )
    if not heads:
        raise r.fail("heads", "at least one [[heads]] table", _MISSING)
    by_id: dict[str, CountingHead] = {}
    for i, h in enumerate(heads):
        if h.id in by_id:
            raise r.fail(f"heads[{i}].id", "a head id not used before", h.id)
        by_id[h.id] = h

    sections: list[Section] = []
    seen_sections: set[str] = set()
    for i, t in enumerate(r.tables(doc, "sections")):
        p = f"sections[{i}]"
        sid = r.req(t, "id", p, str)
        if sid in seen_sections:
            raise r.fail(f"{p}.id", "a section id not used before", sid)
        seen_sections.add(sid)
        raw_bounds = r.req(t, "bounds", p, list)
        bounds = []
        for j, b in enumerate(raw_bounds):
            bp = f"{p}.bounds[{j}]"
            if not isinstance(b, dict):
                raise r.fail(bp, '{ head = "WS1", sign = 1 }', b)
            head = r.req(b, "head", bp, str)
            if head not in by_id:
                raise r.fail(f"{bp}.head", "one of " + ", ".join(sorted(by_id)), head)
            sign = r.req(b, "sign", bp, int)
            if sign not in (1, -1):
                raise r.fail(f"{bp}.sign", "1 (an up train enters here) or -1 (it leaves here)", sign)
            bounds.append(SectionBound(head, sign))
        if not bounds:
            raise r.fail(f"{p}.bounds", "at least one bounding head", raw_bounds)
        if len({b.head for b in bounds}) != len(bounds):
            raise r.fail(f"{p}.bounds", "each head once", [b.head for b in bounds])
        sections.append(Section(sid, tuple(bounds), r.get(t, "name", p, str, "")))

    crossings = []
    for i, t in enumerate(r.tables(doc, "crossings")):
        p = f"crossings[{i}]"
        code = r.req(t, "code", p, str)
        try:
            kp = parse_kilometre_post(code)
        except ValueError:
            raise r.fail(f"{p}.code", "a kilometre post like 11+850", code) from None
        chainage = _chainage(r, t, "chainage_m", p, kp)
        lat, lon = _lat_lon(r, t, p)
        crossings.append(
            LevelCrossing(
                code=code,
                chainage_m=chainage,
                lat=lat,
                lon=lon,
                warning_time_s=_positive(
                    r, r.get(t, "warning_time_s", p, float, 70.0), f"{p}.warning_time_s", MAX_TIME_S
                ),
                d_off_m=_positive(r, r.get(t, "d_off_m", p, float, 30.0), f"{p}.d_off_m", MAX_TRAIN_LENGTH_M),
                name=r.get(t, "name", p, str, ""),
            )
        )

    track: list[TrackPoint] = []
    for i, t in enumerate(r.tables(doc, "track")):
        p = f"track[{i}]"
        pt = TrackPoint(_chainage(r, t, "chainage_m", p), *_lat_lon(r, t, p))
        if track and pt.chainage_m <= track[-1].chainage_m:
            raise r.fail(f"{p}.chainage_m", f"more than the previous point's {track[-1].chainage_m}", pt.chainage_m)
        if track and (pt.lat, pt.lon) == (track[-1].lat, track[-1].lon):
            # A segment of no length: every position would project onto it as 0 / 0.
            raise r.fail(f"{p}.lat", f"a place other than track[{i - 1}]'s (the same lat and lon)", pt.lat)
        track.append(pt)

    platforms = []
    for i, t in enumerate(r.tables(doc, "platforms")):
        p = f"platforms[{i}]"
        pl = Platform(r.req(t, "station", p, str), _chainage(r, t, "from_m", p), _chainage(r, t, "to_m", p))
        if pl.to_m <= pl.from_m:
            raise r.fail(f"{p}.to_m", f"more than from_m ({pl.from_m})", pl.to_m)
        platforms.append(pl)

    consists = []
    for i, t in enumerate(r.tables(doc, "consists")):
        p = f"consists[{i}]"
        axles = r.req(t, "axles_m", p, list)
        plausible = all(
            isinstance(a, int | float) and not isinstance(a, bool) and 0 <= a <= MAX_TRAIN_LENGTH_M for a in axles
        )  # NaN fails the comparison too
        if not axles or not plausible:
            expected = f"a list of axle positions in m from the first wheel (0..{MAX_TRAIN_LENGTH_M:g})"
            raise r.fail(f"{p}.axles_m", expected, axles)
        if any(b < a for a, b in itertools.pairwise(axles)) or axles[0] != 0:
            raise r.fail(f"{p}.axles_m", "increasing positions starting at 0", axles)
        length = r.get(t, "length_m", p, float, float(axles[-1]))
        if abs(length - axles[-1]) > 1e-6:
            raise r.fail(f"{p}.length_m", f"the last axle position ({axles[-1]})", length)
        consists.append(
            Consist(r.req(t, "id", p, str), length, tuple(float(a) for a in axles), r.get(t, "name", p, str, ""))
        )

    limits = []
    for i, t in enumerate(r.tables(doc, "speed_limits")):
        p = f"speed_limits[{i}]"
        lim = SpeedLimit(_chainage(r, t, "from_m", p), _chainage(r, t, "to_m", p), r.req(t, "limit_mps", p, float))
        _positive(r, lim.limit_mps, f"{p}.limit_mps", MAX_SPEED_MPS)
        limits.append(lim)

    sites = []
    for i, t in enumerate(r.tables(doc, "work_sites")):
        p = f"work_sites[{i}]"
        head = r.req(t, "head", p, str)
        if head not in by_id:
            raise r.fail(f"{p}.head", "one of " + ", ".join(sorted(by_id)), head)
        distance = _within(r, r.req(t, "distance_m", p, float), f"{p}.distance_m", MAX_CHAINAGE_M, "a distance in m")
        if distance == 0:
            raise r.fail(f"{p}.distance_m", "a non-zero distance from the head (+ up the line, − down)", distance)
        sites.append(
            WorkSite(
                r.req(t, "id", p, str),
                head,
                distance,
                _positive(r, r.get(t, "warning_time_s", p, float, 30.0), f"{p}.warning_time_s", MAX_TIME_S),
            )
        )

    devices = doc.get("devices", {})
    if not isinstance(devices, dict):
        raise r.fail("devices", "a table [devices]", devices)

    def device_time(key: str) -> float | None:
        value = r.get(devices, key, "devices", float, None)
        return None if value is None else _positive(r, value, f"devices.{key}", MAX_TIME_S)

    return Layout(
        name=name,
        source=source,
        heads=tuple(heads),
        sections=tuple(sections),
        crossings=tuple(crossings),
        track=tuple(track),
        platforms=tuple(platforms),
        consists=tuple(consists),
        speed_limits=tuple(limits),
        work_sites=tuple(sites),
        line_speed_mps=line_speed,
        power_gap_s=device_time("power_gap_s"),
        gnss_report_period_s=device_time("gnss_report_period_s"),
        gnss_latency_s=device_time("gnss_latency_s"),
        _by_id=by_id,
    )


def load_layout(spec: str | Path) -> Layout:
    """A layout from a file path, or a shipped one by name (``osong``, ``example``)."""
    name = str(spec)
    if name in BUILTIN:
        text = resources.files("console.layouts").joinpath(BUILTIN[name]).read_text(encoding="utf-8")
        source = f"{name} (shipped layout {BUILTIN[name]})"
    else:
        path = Path(spec)
        if not path.exists():
            raise LayoutError(f"{path}: no such layout file (or use a shipped one: {', '.join(BUILTIN)})")
        if path.is_dir():
            raise LayoutError(f"{path}: is a directory, expected a layout .toml file")
        try:
            # Read up to a bound: a device or a pipe (--layout /dev/zero) must not fill memory.
            with path.open("rb") as f:
                raw = f.read(MAX_LAYOUT_BYTES + 1)
            if len(raw) > MAX_LAYOUT_BYTES:
                raise LayoutError(f"{path}: over {MAX_LAYOUT_BYTES // 2**20} MiB, not a layout file")
            text = raw.decode("utf-8-sig")  # an editor's byte-order mark is no TOML
        except (OSError, UnicodeDecodeError) as exc:
            raise LayoutError(f"{path}: cannot read ({exc})") from None
        source = str(path)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise LayoutError(f"{source}: not valid TOML ({exc})") from None
    except RecursionError:
        # tomllib parses nested arrays and inline tables recursively
        raise LayoutError(f"{source}: not valid TOML (arrays or tables nested too deeply)") from None
    except ValueError as exc:
        # tomllib turns a too-long integer literal into int() and lets Python's
        # digit limit raise ValueError, not TOMLDecodeError.
        raise LayoutError(f"{source}: not valid TOML ({str(exc)[:120]})") from None
    return layout_from_dict(doc, source)


def layout_from_heads(head_ids: list[str], source: str = "the log's counting heads") -> Layout:
    """A minimal layout naming only heads (no sections): for analyses that need
    head facts but were given no layout.  Defaults: 0.13 m, two channels, Sys1 first is up."""
    heads = tuple(CountingHead(id=h, chainage_m=float(i)) for i, h in enumerate(head_ids))
    return Layout(name=source, source=source, heads=heads, _by_id={h.id: h for h in heads})
