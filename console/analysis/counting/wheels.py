"""Wheel detections → axles, for one counting head's two systems.

A counting head has two receiver systems (Sys1 = channel 1, Sys2 = channel
2) a coil spacing apart.  In the diagnostic log a wheel shows as the
``Radsensor`` register (Adr 026) turning 1 on one channel and then on the
other; the ``Diagnose`` register (Adr 024) mirrors it as a status bit, so we
count onsets from Radsensor only and never count one wheel twice.

An axle is a Sys1 onset paired with the nearest Sys2 onset of the same head
within ``pair_window_s``.  The default window is the time a wheel needs to
cross the coil spacing at 1 km/h (0.13 m → 0.47 s; seed 002's "about half a
second"): a partner further away is not the same wheel.  The pairing is one
to one.  The order of the two onsets gives the direction.  An onset with no
partner (a single system damped, e.g. by a maintenance trolley's metal) is
not an axle; it is counted as an unpaired detection.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from console.analysis.counting.speed import MPS_TO_KMH
from console.analysis.events.detection import DetectionEvent, EventKind
from console.analysis.head_table import by_head_then_time
from parsers.units import NS

try:
    from console.analysis.counting import compiled_pairs
except ImportError:  # built without a C compiler: the numpy pairing
    compiled_pairs = None  # type: ignore[assignment]

if TYPE_CHECKING:
    import pandas as pd

WHEEL_SENSOR_ADDRESS = 26
SYS1, SYS2 = 1, 2
DIRECTION_12 = "sys1_to_sys2"
DIRECTION_21 = "sys2_to_sys1"
DIRECTIONS = (None, DIRECTION_12, DIRECTION_21)  # axle direction codes 0, 1, 2
# The detail of the doubt raised when an axle's second system is freed while its first is still damped.
REVERSED_RELEASE = "freed before the system damped first: direction doubtful"


@dataclass(frozen=True)
class PairingSettings:
    spacing_m: float = 0.13
    # spacing / (1 km/h): a slower wheel is not a train wheel (seed 002).
    pair_window_s: float = 0.13 / (1 / 3.6)
    # A per-axle speed only where the stamps time the delay to within 10 %:
    # the delay is at least this many steps of the log's resolution.
    min_delay_steps: int = 10


def stamp_resolution_s(time_ns: np.ndarray) -> float:
    """The finest step sub-second stamps show: 1 ms when every one is a whole
    millisecond, 1 µs when every one is a whole microsecond, else 1 ns."""
    if len(time_ns) == 0 or bool((time_ns % 1_000_000 == 0).all()):
        return 1e-3
    return 1e-6 if bool((time_ns % 1_000 == 0).all()) else 1e-9


def _group_starts(keys: np.ndarray) -> np.ndarray:
    """Start positions of the runs of equal values in ``keys``."""
    return np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]]) if len(keys) else np.zeros(0, np.int64)


def _fine_pairs(
    gh: np.ndarray, t: np.ndarray, on1: np.ndarray, on2: np.ndarray, window_ns: int
) -> tuple[np.ndarray, np.ndarray]:
    """Nearest-partner pairs of sub-second heads, all heads at once: positions (a, b) of onsets sorted by
    head, then time (ties in read order); ``gh`` is each position's head.  Each Sys1 onset takes the
    nearest Sys2 onset of its head within the window (one ``np.searchsorted``
    over a (head, time) rank stands for one per head), then a Sys2 onset
    claimed twice goes to the nearer Sys1 onset.
    """
    n = len(gh)
    # Dense rank of (head, time): one sorted key that compares as the pair does.
    new = np.r_[True, (gh[1:] != gh[:-1]) | (t[1:] != t[:-1])] if n else np.zeros(0, bool)
    key = np.cumsum(new)
    p1, p2 = np.flatnonzero(on1), np.flatnonzero(on2)
    if not len(p1) or not len(p2):
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    pos = np.searchsorted(key[p2], key[p1])
    right = np.minimum(pos, len(p2) - 1)
    left = np.maximum(pos - 1, 0)
    h1 = gh[p1]
    has_right = (pos < len(p2)) & (gh[p2[right]] == h1)
    has_left = (pos > 0) & (gh[p2[left]] == h1)
    # One side missing: the other side stands for both (as a per-head search clips to its ends).
    right = np.where(has_right, right, left)
    left = np.where(has_left, left, right)
    any_partner = has_left | has_right
    t1 = t[p1]
    d_right = np.abs(t[p2[right]] - t1)
    d_left = np.abs(t1 - t[p2[left]])
    pick = np.where(d_left <= d_right, left, right)
    ok = any_partner & (np.minimum(d_left, d_right) <= window_ns)
    a, b = p1[ok], p2[pick[ok]]
    # One to one: a Sys2 onset claimed twice goes to the nearer Sys1 onset (the earlier on a tie).
    if len(b) > 1 and bool((b[1:] == b[:-1]).any()):
        by_gap = np.argsort(np.abs(t[b] - t[a]), kind="stable")
        _, first = np.unique(b[by_gap], return_index=True)
        keep = np.sort(by_gap[first])
        a, b = a[keep], b[keep]
    return a, b


def _coarse_pairs(gh: np.ndarray, ch: np.ndarray, t: np.ndarray, window_ns: int) -> np.ndarray:
    """Positions i whose onset pairs with onset i + 1, in heads' onsets ordered by head and time.

    Whole-second stamps cannot say which onsets are nearest, but the order of
    the records can: a wheel writes one system's onset, then the other's.  So
    neighbours of one head on different systems, at most ``window_ns``
    apart, pair greedily from the start (in a run of pairable neighbours,
    every other one), one to one.
    """
    if len(ch) < 2:
        return np.zeros(0, np.int64)
    link = (gh[1:] == gh[:-1]) & (ch[1:] != ch[:-1]) & (t[1:] - t[:-1] <= window_ns)
    k = np.arange(len(link))
    run_start = link & ~np.r_[False, link[:-1]]
    offset = k - np.maximum.accumulate(np.where(run_start, k, 0))
    return np.flatnonzero(link & (offset % 2 == 0))


def pair_axle_arrays(
    onsets: Mapping[str, Any], settings: PairingSettings, head_step_s: np.ndarray | None = None
) -> tuple[dict[str, np.ndarray], int]:
    """:func:`pair_axles` as columns of arrays, ``direction`` as a code into :data:`DIRECTIONS`
    (:func:`pair_onsets` without the onsets' rows)."""
    axles, unpaired, _ = pair_onsets(onsets, settings, head_step_s)
    return axles, unpaired


def pair_onsets(
    onsets: Mapping[str, Any],
    settings: PairingSettings,
    head_step_s: np.ndarray | None = None,
    head_spacing_m: np.ndarray | None = None,
) -> tuple[dict[str, np.ndarray], int, np.ndarray]:
    """The axles and unpaired onsets of :func:`pair_axle_arrays`, and per axle the row of ``onsets`` holding its
    earlier onset (the one its ``time_ns`` is; a tie: the Sys1 onset).

    ``head_step_s``: per head key, its stamps' resolution over the whole log (1.0: whole seconds), when the
    caller knows it (a part of a log then pairs as the whole log does); else judged from these onsets.

    The onsets' order is evidence: equal times keep the order they come in
    (file order), never re-sorted.  Per head, sub-second onsets pair with the
    nearest partner within ``pair_window_s``; a head with whole-second
    stamps pairs by order (:func:`_coarse_pairs`) within one second.
    Every head is paired at once, over one sort by (head, time): a log of a
    million heads costs what a log of one head with as many onsets does.
    """
    head = np.asarray(onsets["head"], np.int64)
    channel = np.asarray(onsets["channel"], np.int64)
    time_ns = np.asarray(onsets["time_ns"], np.int64)
    subsecond = np.asarray(onsets["subsecond"], bool)
    file = np.asarray(onsets["file"], np.int64) if "file" in onsets else np.zeros(len(head), np.int64)
    is1, is2 = channel == SYS1, channel == SYS2
    fine_window_ns = int(settings.pair_window_s * NS)
    coarse_window_ns = max(fine_window_ns, NS)  # stamps a second apart may be 1 ms apart

    wheel = np.flatnonzero(is1 | is2)
    # Positions by head, then time; stable: ties keep file order.
    if len(wheel) == len(head):
        order, pa, pb, step_a = pair_positions(
            head, time_ns, channel, subsecond, head_step_s, fine_window_ns, coarse_window_ns
        )
    else:
        order, pa, pb, step_a = pair_positions(
            head[wheel], time_ns[wheel], channel[wheel], subsecond[wheel], head_step_s, fine_window_ns, coarse_window_ns
        )
        order = wheel[order]
    sys1_first = pa < pb  # positions in time order, ties in file order
    a, b = order[pa], order[pb]
    t1, t2 = time_ns[a], time_ns[b]
    delay_s = (t2 - t1) / NS
    exact = subsecond[a] & subsecond[b]
    # Millisecond stamps time a 4 ms delay (0.13 m at 120 km/h) to ±25 %: no figure then.
    timed = exact & (np.abs(delay_s) >= settings.min_delay_steps * step_a)
    with np.errstate(divide="ignore"):
        spacing_m = head_spacing_m[head[a]] if head_spacing_m is not None else settings.spacing_m
        speed = np.where(timed & (delay_s != 0), spacing_m / np.abs(delay_s) * MPS_TO_KMH, np.nan)
    # The order of two onsets is known from their times, or, for equal
    # stamps, from their order in one file; two files' equal stamps say nothing.
    known = (t1 != t2) | (file[a] == file[b])
    # Direction as a code into DIRECTIONS: 0 unknown, 1 Sys1→Sys2, 2 Sys2→Sys1.
    direction = np.zeros(len(t1), np.int8)
    direction[known & sys1_first] = 1
    direction[known & ~sys1_first] = 2
    axles = {
        "head": head[a],
        "t_sys1_ns": t1,
        "t_sys2_ns": t2,
        "time_ns": np.minimum(t1, t2),
        "direction": direction,
        "delay_s": np.where(exact, delay_s, np.nan),
        "speed_kmh": speed,
    }
    unpaired = int((is1 | is2).sum()) - 2 * len(a)
    return axles, unpaired, np.where(t1 <= t2, a, b)


def _pair_positions_numpy(
    head: np.ndarray,
    t: np.ndarray,
    ch: np.ndarray,
    subsecond: np.ndarray,
    head_step_s: np.ndarray | None,
    fine_window_ns: int,
    coarse_window_ns: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Wheel onsets in read order: the order sorting them by head, then time (ties in read order); the positions
    (into that order) of each pair's Sys1 and Sys2 onset, by head, each head's in its own order; and each pair's
    stamp step (its head's resolution, 1.0: whole seconds).  (:data:`pair_positions`: this, or the compiled pass
    alike.)"""
    order = by_head_then_time(head, t)[0]
    gh, t, ch, subsecond = head[order], t[order], ch[order], subsecond[order]
    starts = _group_starts(gh)
    size = np.diff(np.r_[starts, len(gh)])
    # Per head: all its stamps sub-second (pairs by nearest time), and their resolution.
    fine_head = np.logical_and.reduceat(subsecond, starts) if len(gh) else np.zeros(0, bool)
    fine = np.repeat(fine_head, size)
    ms = np.repeat(np.logical_and.reduceat(t % 1_000_000 == 0, starts), size) if len(gh) else fine
    us = np.repeat(np.logical_and.reduceat(t % 1_000 == 0, starts), size) if len(gh) else fine
    step_s = np.where(fine, np.where(ms, 1e-3, np.where(us, 1e-6, 1e-9)), 1.0)  # per position
    if head_step_s is not None and len(gh):
        known = gh < len(head_step_s)
        given = np.where(known, head_step_s[np.minimum(gh, len(head_step_s) - 1)], np.nan)
        fine = np.where(known, given < 1.0, fine)
        step_s[known] = given[known]
    fa, fb = _fine_pairs(gh, t, fine & (ch == SYS1), fine & (ch == SYS2), fine_window_ns)
    coarse = np.flatnonzero(~fine)
    at = coarse[_coarse_pairs(gh[coarse], ch[coarse], t[coarse], coarse_window_ns)]
    nxt = coarse[np.searchsorted(coarse, at) + 1]
    c_first1 = ch[at] == SYS1
    ca, cb = np.where(c_first1, at, nxt), np.where(c_first1, nxt, at)
    # Pairs in head order, each head's in its own order (sub-second and whole-second heads are apart).
    pa, pb = np.r_[fa, ca], np.r_[fb, cb]
    by_head = np.argsort(gh[pa], kind="stable")
    pa, pb = pa[by_head], pb[by_head]
    return order, pa, pb, step_s[pa]


def _pair_positions_compiled(
    head: np.ndarray,
    t: np.ndarray,
    ch: np.ndarray,
    subsecond: np.ndarray,
    head_step_s: np.ndarray | None,
    fine_window_ns: int,
    coarse_window_ns: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_pair_positions_numpy`'s order and pairs in one compiled pass without the GIL
    (``compiled_pairs.c``); its counting sort of the head keys, or numpy's where that cannot serve."""
    assert compiled_pairs is not None
    cols = (
        np.ascontiguousarray(head, np.int64),
        np.ascontiguousarray(t, np.int64),
        np.ascontiguousarray(ch, np.int64),
        np.ascontiguousarray(subsecond, np.bool_),
    )
    steps = None if head_step_s is None else np.ascontiguousarray(head_step_s, np.float64)
    windows = (fine_window_ns, coarse_window_ns, SYS1, SYS2)
    out = compiled_pairs.pair_positions(*cols, None, steps, *windows)
    if out is None:  # keys too sparse for a counting sort, or a head's times going back
        out = compiled_pairs.pair_positions(*cols, by_head_then_time(cols[0], cols[1])[0], steps, *windows)
        assert out is not None
    m, order, pa, pb, step = out
    n = len(cols[0])
    pa_, pb_ = np.frombuffer(pa, np.int64)[:m], np.frombuffer(pb, np.int64)[:m]
    return np.frombuffer(order, np.int64)[:n], pa_, pb_, np.frombuffer(step, np.float64)[pa_]


# The compiled pass where it was built, unless TRACKSIDE_PURE=1 asks for numpy (tests/test_pairs_compiled.py).
_COMPILED = compiled_pairs is not None and not os.environ.get("TRACKSIDE_PURE")
pair_positions = _pair_positions_compiled if _COMPILED else _pair_positions_numpy


def axles_frame(axles: Mapping[str, np.ndarray]) -> pd.DataFrame:
    """The axle table of :func:`pair_axles` from :func:`pair_axle_arrays`' columns."""
    import pandas as pd

    cols = dict(axles)
    cols["direction"] = np.array(DIRECTIONS, dtype=object)[axles["direction"]]
    return pd.DataFrame(cols)


def pair_axles(onsets: Mapping[str, Any], settings: PairingSettings) -> tuple[pd.DataFrame, int]:
    """Pair Sys1 and Sys2 onsets into axles.

    ``onsets`` (a DataFrame or a dict of arrays) has columns ``head`` (int key), ``channel``, ``time_ns``,
    ``subsecond``.  Returns (axles, number of unpaired onsets); axles have
    ``head``, ``t_sys1_ns``, ``t_sys2_ns``, ``time_ns`` (the earlier onset),
    ``direction``, ``delay_s`` and ``speed_kmh`` (NaN unless both onsets
    carry sub-second times).
    """
    axles, unpaired = pair_axle_arrays(onsets, settings)
    return axles_frame(axles), unpaired


# --- the two-channel overlap rule (seed 003) → detection events --------------


@dataclass(frozen=True)
class CountingSettings:
    """Timing of the counting rules (seconds)."""

    # Without release records (whole-second logs) onsets pair within this window.
    pair_window_s: float = 0.13 / (1 / 3.6)
    # Seed 002's soft timing calls a pulse "isolated" when nothing else comes
    # for much longer than the half second a wheel needs to cross the elements
    # at 1 km/h.  But a wheel one system missed is also alone among its
    # train's other axles, which at low speed are tens of seconds apart (15 m
    # at 1 km/h is 54 s).  So a pulse counts as isolated, and can be confirmed
    # accidental, only with this much quiet at the head before *and* after it.
    # The fail-safe property test found the shorter windows unsafe.
    isolation_s: float = 60.0


def soft_timing(
    head: str, lone: list[tuple[int, int]], all_onsets: np.ndarray, s: CountingSettings, source: str
) -> list[DetectionEvent]:
    """Seed 002's soft timing for pulses that are not (part of) an axle.

    A lone pulse with nothing at the head for ``isolation_s`` before it holds
    the section occupied (INTERFERENCE).  If nothing follows for
    ``isolation_s`` it is accidental (ACCIDENTAL lifts the hold); if anything
    does, it may have been a wheel one system missed (SINGLE_CHANNEL, at the
    moment that activity comes, which disturbs the section).  A lone pulse
    amid other activity is SINGLE_CHANNEL at once.
    """
    iso = confirm = int(s.isolation_s * NS)
    out = []
    for t, ch in lone:  # per unpaired pulse: rare
        before = np.searchsorted(all_onsets, t, side="left") - np.searchsorted(all_onsets, t - iso, side="left")
        if before > 0:
            out.append(DetectionEvent(t, EventKind.SINGLE_CHANNEL, head, 0, ch, source, "one system damped"))
            continue
        out.append(DetectionEvent(t, EventKind.INTERFERENCE, head, 0, ch, source, "isolated pulse: held"))
        nxt = np.searchsorted(all_onsets, t, side="right")
        t_next = int(all_onsets[nxt]) if nxt < len(all_onsets) else None
        if t_next is not None and t_next - t <= confirm:
            detail = f"more activity {(t_next - t) / NS:.1f} s after an isolated pulse: possibly a missed axle"
            out.append(DetectionEvent(t_next, EventKind.SINGLE_CHANNEL, head, 0, ch, source, detail))
        else:
            detail = f"nothing else within {s.isolation_s:g} s: accidental"
            out.append(DetectionEvent(t + confirm, EventKind.ACCIDENTAL, head, 0, ch, source, detail))
    return out


class HeadCounter:
    """Seed 003's two-channel overlap rule for one counting head, as a stream.

    Feed the head's wheel-sensor records in time order with :meth:`feed`
    (channel, time, 1 = damped / 0 = free) and let time pass with
    :meth:`advance`; both return the detection events they settle.  It runs
    inside the simulator and the live engine, a record at a time; over a
    parsed log the same rules run as array operations, many heads at once
    (:class:`console.analysis.counting.bank.CounterBank`, held to give exactly
    this class's events by ``tests/test_counting_bank.py``):

    * an axle counts when one system's damping starts while the other's is
      still on (they overlap); the order of the two onsets gives the
      direction.  Without release records (``point_mode``: the paper's
      whole-second exports) onsets pair within ``pair_window_s`` instead;
    * ``whole_second``: the stamps are whole seconds, so two onsets in one
      second are ordered by the order they come in (the log's line order,
      the only timing evidence there), and point-mode onsets pair within a
      second, not the sub-second window;
    * an axle's system damped second must not be freed while the first is
      still damped (a wheel crossing one way frees the first system first):
      where it is, the direction is in doubt (SINGLE_CHANNEL), as when a
      pulse on one system overlaps a wheel and came before it;
    * a damping of one system alone is not an axle.  Seed 002's soft timing
      decides what it is: with nothing else at the head for ``isolation_s``
      before it, it holds the section (INTERFERENCE) and is confirmed
      accidental (ACCIDENTAL) once ``isolation_s`` passes quietly after it;
      activity inside that window makes it a possibly missed axle
      (SINGLE_CHANNEL), as does a lone damping amid other activity.  A lone
      damping is known at its release (or when the pairing window closes),
      and its event carries that time;
    * HEAD_DAMPED / HEAD_FREE bracket every time anything is over the head.
    """

    def __init__(
        self,
        head: str,
        *,
        up_is_sys1_first: bool = True,
        settings: CountingSettings | None = None,
        point_mode: bool = False,
        source: str = "diag",
        whole_second: bool = False,
    ) -> None:
        self.head, self.up_first, self.point_mode, self.source = head, up_is_sys1_first, point_mode, source
        self.whole_second = whole_second
        self.s = settings or CountingSettings()
        self.iso = int(self.s.isolation_s * NS)
        # Whole-second stamps of one wheel's two onsets may differ by a second.
        self.tol = max(int(self.s.pair_window_s * NS), NS if whole_second else 0)
        # Per channel: onset of the current damping, whether it is part of an
        # axle, and the head's previous activity when it began.
        self.open: dict[int, int | None] = {SYS1: None, SYS2: None}
        self.paired: dict[int, bool] = {SYS1: False, SYS2: False}
        self.before: dict[int, int | None] = {SYS1: None, SYS2: None}
        self.pending: list[tuple[int, int, int | None]] = []  # point mode: (onset, channel, previous activity)
        self.holds: list[tuple[int, int]] = []  # (pulse onset, channel) held as interference
        self.last_onset: int | None = None

    def _ev(
        self, t: int, kind: EventKind, direction: int = 0, channel: int | None = None, detail: str = ""
    ) -> DetectionEvent:
        return DetectionEvent(t, kind, self.head, direction, channel, self.source, detail)

    def _axle(self, t_first: int, ch_first: int, t_second: int) -> DetectionEvent:
        # +1: Sys1 first.  Equal sub-second stamps say nothing about the order;
        # equal whole-second stamps are ordered by the lines (fed first = first).
        same = t_first == t_second and not self.whole_second
        order = 0 if same else (1 if ch_first == SYS1 else -1)
        direction = order if self.up_first else -order
        t1, t2 = (t_first, t_second) if ch_first == SYS1 else (t_second, t_first)
        return self._ev(max(t_first, t_second), EventKind.AXLE, direction, None, f"Sys1 {t1} Sys2 {t2}")

    def _lone(self, t_on: int, ch: int, now: int, before: int | None) -> DetectionEvent:
        """A damping of one system alone, settled at ``now``."""
        if before is not None and t_on - before <= self.iso:
            return self._ev(now, EventKind.SINGLE_CHANNEL, 0, ch, "one system damped")
        self.holds.append((t_on, ch))
        return self._ev(now, EventKind.INTERFERENCE, 0, ch, "isolated pulse: held")

    def advance(self, t: int) -> list[DetectionEvent]:
        """Let time pass to ``t``: close pairing windows, confirm quiet holds."""
        out: list[DetectionEvent] = []
        while self.pending and self.pending[0][0] + self.tol < t:
            t_on, ch, before = self.pending.pop(0)
            out.append(self._lone(t_on, ch, t_on + self.tol, before))
        if self.holds:
            due = [h for h in self.holds if h[0] + self.iso <= t]
            self.holds = [h for h in self.holds if h[0] + self.iso > t]
            detail = f"nothing else within {self.s.isolation_s:g} s: accidental"
            out += [self._ev(t_on + self.iso, EventKind.ACCIDENTAL, 0, ch, detail) for t_on, ch in due]
        return out

    def feed(self, ch: int, t: int, value: int) -> list[DetectionEvent]:
        """One wheel-sensor record of this head; records must come in time order."""
        if ch not in (SYS1, SYS2):
            return []
        out = self.advance(t)
        other = SYS2 if ch == SYS1 else SYS1
        if value == 1:
            if self.open[ch] is not None:
                return out  # already damped: a repeated onset
            before, self.last_onset = self.last_onset, t
            if self.holds:  # activity during a hold: the held pulse may have been a missed wheel
                for t_pulse, hch in self.holds:
                    gap = (t - t_pulse) / NS
                    out.append(
                        self._ev(t, EventKind.SINGLE_CHANNEL, 0, hch, f"activity {gap:.1f} s after an isolated pulse")
                    )
                self.holds = []
            if self.point_mode:
                partner = next((p for p in self.pending if p[1] == other and t - p[0] <= self.tol), None)
                if partner is not None:
                    self.pending.remove(partner)
                    out.append(self._axle(partner[0], other, t))
                else:
                    self.pending.append((t, ch, before))
                return out
            if self.open[other] is None:
                out.append(self._ev(t, EventKind.HEAD_DAMPED))
            o = self.open[other]
            if o is not None and not self.paired[other]:
                out.append(self._axle(o, other, t))
                self.paired[other] = self.paired[ch] = True
            self.open[ch], self.before[ch] = t, before
        else:
            t_on = self.open[ch]
            if t_on is None:
                return out
            if not self.paired[ch]:
                out.append(self._lone(t_on, ch, t, self.before[ch]))
            elif (o := self.open[other]) is not None and o < t_on:
                # The system damped second is freed first: not a wheel crossing one way (the first damped is
                # the first freed), but e.g. a pulse on one system over a wheel, which may have set the direction.
                out.append(self._ev(t, EventKind.SINGLE_CHANNEL, 0, ch, REVERSED_RELEASE))
            self.open[ch], self.paired[ch] = None, False
            if self.open[other] is None:
                out.append(self._ev(t, EventKind.HEAD_FREE))
        return out

    def flush(self) -> list[DetectionEvent]:
        """End of input: settle everything still open in time."""
        if self.last_onset is None:
            return []
        return self.advance(self.last_onset + self.iso + self.tol + 1)
