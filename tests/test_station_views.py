"""What the station view shows in each mode, as an operator met it (issue "The first hour", point 10).

* live, on a station's log: no status-only bursts in the event log (``follow`` hides them too); the
  log's own times on its entries and on the view's clock, not the console's; one "live" in the title;
* live, on recorded GNSS at many times real time: the crossing's warning goes off once the train has passed
  (the units run on the recording's clock, not on the console's);
* the key bar shows only the keys that act: no faults, added trains or truth outside the simulation;
* a replay's ``]`` jump puts the section changes it passed over into the event log.
"""

from __future__ import annotations

import asyncio
import time
from pathlib import Path

from console.cli.common import load_layout as _load_layout
from console.inputs.base import GnssFix, LineBlock
from console.layout import load_layout
from console.live.engine import LiveEngine
from console.tui.app import StationApp
from console.tui.live_app import LiveStationApp
from console.tui.live_source import LiveSource
from console.tui.model import StationModel
from console.tui.replay_source import ReplaySource
from console.tui.sim_source import SimSource
from console.tui.widgets.key_bar import KeyBar

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_logs" / "example_station.log"
SIZE = (120, 40)


def _fed(source: LiveSource, data: bytes) -> None:
    source._queue.put(LineBlock("file:station.log", "station.log", 1, data, time.monotonic()))
    source.started = True


def test_the_live_log_shows_trains_not_status_bursts_at_the_logs_own_times() -> None:
    source = LiveSource(load_layout("example"), [])
    _fed(source, SAMPLE.read_bytes())
    model = StationModel(source)
    model.step(1.0)
    source.live.finish()
    model.record(*source.advance(0.0))
    passages = [e for e in model.log if e.text.startswith("passage at")]
    assert passages, "trains reach the log"
    # A board's status dumps make a passage each (every few seconds): counted, not shown, as follow does.
    from tests.reads import whole_job

    shown = whole_job([SAMPLE]).analysis.passages
    assert len(passages) == int((shown["kind"] != "status").sum()) < len(shown)
    # Every entry is stamped in the log's day (2026-03-02), as its section changes are: not the console's.
    log_day = passages[0].time_ns // 86_400_000_000_000
    assert {e.time_ns // 86_400_000_000_000 for e in model.log} == {log_day}
    assert source.now_ns // 86_400_000_000_000 == log_day  # the view's clock: the log's


def test_the_live_title_says_live_once() -> None:
    source = LiveSource(load_layout("example"), [])
    app = LiveStationApp(source, autoplay=False)

    async def go() -> tuple[str, str]:
        async with app.run_test(size=SIZE):
            return app.title, app.sub_title

    title, sub = asyncio.run(go())
    assert f"{title} — {sub}".count("live") == 1, (title, sub)


def test_a_tick_that_ends_after_the_live_app_closed_starts_no_other() -> None:
    """A tick's end with data still waiting would start the next tick: not once the app has shut down
    (its worker would tick a closed app and call back into it)."""
    source = LiveSource(load_layout("example"), [])
    app = LiveStationApp(source, autoplay=False)

    async def go() -> None:
        async with app.run_test(size=SIZE):
            pass
        advances = app.advances
        app._busy, app._again = True, True  # a tick in flight, and data came meanwhile
        app._after_advance()  # what call_from_thread runs when the tick ends
        assert not app._busy
        assert app.advances == advances
        assert not list(app.workers)

    asyncio.run(go())


def test_recorded_fixes_run_the_crossing_on_their_own_clock() -> None:
    """A recording read at many times its speed: the warning comes on and goes off at the recording's times
    (on the console's clock the fixes would be minutes in the future, then stale: the warning stuck on)."""
    from console.analysis.geo import TrackProjector

    lay = load_layout("example")
    proj = TrackProjector(lay.track)
    events: list[dict[str, object]] = []
    engine = LiveEngine(lay, events.append)
    t0 = 1_772_438_400 * 10**9  # 2026-03-02, hours from the console's clock
    for k in range(0, 600, 2):  # a train at 15 m/s past the whole line, fixes every 2 s, read in a burst
        for role, back in (("head", 0.0), ("eot", 120.0)):
            lat, lon = proj.position(9000.0 + 15.0 * k - back)
            engine.handle(
                GnssFix(
                    "file:T1.nmea",
                    f"T1-{role}",
                    t0 + k * 10**9,
                    float(lat[0]),
                    float(lon[0]),
                    15.0,
                    proj.bearing_deg(9000.0 + 15.0 * k),
                    time.monotonic(),
                    role=role,
                    recorded=True,
                )
            )
        engine.tick()
    engine.finish()
    crossing = [e for e in events if e["type"] == "crossing"]
    kinds = [e["kind"] for e in crossing]
    assert "on" in kinds and "off" in kinds, kinds
    assert all(t0 <= int(e["time_ns"]) <= t0 + 700 * 10**9 for e in crossing)  # the recording's own times


def _keys(app: StationApp) -> str:
    async def go() -> str:
        async with app.run_test(size=SIZE):
            return str(app.query_one(KeyBar).render())

    return asyncio.run(go())


def test_the_key_bar_shows_only_the_keys_that_act() -> None:
    sim = _keys(StationApp(StationModel(SimSource(_load_layout("example"), seed=1)), autoplay=False))
    assert "faults" in sim and "add train" in sim and "truth" in sim
    replay = _keys(StationApp(StationModel(ReplaySource([SAMPLE], load_layout("example"))), autoplay=False))
    assert "jump" in replay and not {"faults", "add train", "truth", "reset"} & set(replay.split("  "))
    for gone in ("faults", "add train", "truth"):
        assert gone not in replay
    live = _keys(LiveStationApp(LiveSource(load_layout("example"), []), autoplay=False))
    for gone in ("faults", "add train", "truth", "jump", "speed"):
        assert gone not in live
    assert "pause" in live and "quit" in live


def test_a_replay_jump_puts_the_section_changes_it_passed_into_the_log() -> None:
    source = ReplaySource([SAMPLE], load_layout("example"))
    app = StationApp(StationModel(source), autoplay=False)

    async def go() -> list[str]:
        async with app.run_test(size=SIZE) as pilot:
            for _ in range(12):  # an hour of the morning's trains, five minutes a press
                await pilot.press("right_square_bracket")
            return [e.text for e in app.model.log]

    texts = asyncio.run(go())
    assert any(t.startswith("section ") for t in texts), texts[:10]


def test_the_live_view_wakes_when_a_crossing_warning_falls_due() -> None:
    # Between its steady wake-ups (every STATUS_S) the live view also wakes at the instant the engine says
    # a crossing unit has something due, as `follow` does: a warning comes on at its instant, not later.
    source = LiveSource(load_layout("example"), [])
    source.live.next_wake_s = lambda: 0.05  # type: ignore[method-assign]
    app = LiveStationApp(source, autoplay=True)
    timers: list[float] = []

    async def go() -> None:
        async with app.run_test(size=SIZE) as pilot:
            set_timer = app.set_timer

            def recording(delay: float, callback: object = None, **kw: object) -> object:
                timers.append(delay)
                return set_timer(delay, callback, **kw)  # type: ignore[arg-type]

            app.set_timer = recording  # type: ignore[method-assign,assignment]
            for _ in range(200):  # until an advance has ended (a loaded machine may take a while)
                await pilot.pause(0.05)
                if timers:
                    break

    asyncio.run(go())
    assert 0.05 in timers
