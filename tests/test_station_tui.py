"""The station view, driven as an operator drives it: Pilot presses keys and
clicks, the test steps the simulation by hand and asserts what the console
derived (section states, reset decisions, log entries), never the pixels."""

from __future__ import annotations

import asyncio
import time
from pathlib import Path

import pytest
from textual.widgets import DataTable

from console.cli.common import load_layout as _load_layout
from console.tui.app import StationApp
from console.tui.help import HelpScreen
from console.tui.model import SPEEDS, StationModel
from console.tui.replay_source import ReplaySource
from console.tui.sim_source import SimSource
from console.tui.widgets.sections_table import SectionsTable
from console.tui.widgets.speed_plot import SpeedPlot
from console.tui.widgets.track import TrackDiagram
from console.tui.widgets.trains_table import TrainsTable

ROOT = Path(__file__).resolve().parents[1]
SIZE = (100, 30)


def make_app(seed: int = 1) -> StationApp:
    model = StationModel(SimSource(_load_layout("example"), seed=seed))
    return StationApp(model, autoplay=False)


def states(app: StationApp) -> dict[str, str]:
    return {s.id: s.state for s in app.model.snapshot().sections}


def log_texts(app: StationApp) -> list[str]:
    return [e.text for e in app.model.log]


def run(coro: object) -> None:
    asyncio.run(coro)  # type: ignore[arg-type]


def test_pause_speed_and_single_step_keys() -> None:
    async def go() -> None:
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            m = app.model
            assert m.speed == 5 and not m.paused
            await pilot.press("space")
            assert m.paused and "paused" in app.sub_title
            await pilot.press("plus", "plus")
            assert m.speed == 20
            await pilot.press("minus")
            assert m.speed == 10
            for _ in range(20):
                await pilot.press("minus")
            assert m.speed == SPEEDS[0] == 1  # the slowest is real time
            for _ in range(20):
                await pilot.press("plus")
            assert m.speed == SPEEDS[-1] == 1000
            t0 = m.source.now_ns
            m.tick(1.0)  # a timer tick while paused does nothing
            assert m.source.now_ns == t0
            await pilot.press("full_stop")  # one step works while paused
            assert m.source.now_ns - t0 == 1_000_000_000
            await pilot.press("space")
            assert not m.paused and "1000×" in app.sub_title

    run(go())


def test_the_app_moves_by_itself() -> None:
    """With autoplay the timer and the worker advance the clock, and a pause stops it."""

    async def go() -> None:
        model = StationModel(SimSource(_load_layout("example"), seed=1))
        app = StationApp(model, autoplay=True)
        async with app.run_test(size=SIZE) as pilot:
            t0 = model.source.now_ns
            # The first tick is due after 0.1 s, but its worker thread can wait long for the CPU on a loaded
            # machine: wait for the clock to move (a stuck clock still fails, after 10 s).
            end = time.monotonic() + 10
            while model.source.now_ns == t0 and time.monotonic() < end:
                await pilot.pause(0.05)
            assert model.source.now_ns > t0
            await pilot.press("space")
            # A tick already in flight when the pause came may still move the clock: wait for it to end (a
            # fixed wait was too short under load, and the tick then moved the clock after t2 was read).
            await app.workers.wait_for_complete()
            t2 = model.source.now_ns
            await pilot.pause(0.5)
            assert model.source.now_ns == t2

    run(go())


def test_a_tick_that_ends_after_the_app_draws_nothing() -> None:
    """A tick's worker can finish while the app shuts down (its widgets gone): that is not an error."""

    async def go() -> None:
        app = StationApp(StationModel(SimSource(_load_layout("example"), seed=1)), autoplay=False)
        async with app.run_test(size=SIZE):
            pass
        app._busy = True
        app._after_advance()  # what call_from_thread runs when the tick ends
        assert not app._busy

    run(go())


def test_select_sections_and_trains_by_key_and_click() -> None:
    async def go() -> None:
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("s")
            assert app.model.section_id() == "B1"
            await pilot.press("S", "S")
            assert app.model.section_id() == "2G"  # wraps round
            # A click on a row of the sections panel selects that section.
            table = app.query_one(SectionsTable)
            await pilot.click(SectionsTable, offset=(3, 3))  # border, header, 1G, B1
            assert app.model.section_id() == str(table.coordinate_to_cell_key((table.cursor_row, 0)).row_key.value)
            assert app.model.section_id() == "B1"
            # Trains: add two, let them enter and report, select by key and click.
            await pilot.press("a", "a")
            app.advance(240)
            await pilot.pause()
            ids = [t.id for t in app.model.snapshot().trains]
            assert len(ids) >= 2
            await pilot.press("w")
            assert app.model.train_id() == ids[1]
            await pilot.click(TrainsTable, offset=(3, 2))  # the first train's row
            assert app.model.train_id() == ids[0]
            plot = app.query_one(SpeedPlot)
            assert plot.border_title is not None and str(plot.border_title).startswith(ids[0])

    run(go())


def test_dead_channel_disturbs_both_sections_of_its_head_when_a_train_passes() -> None:
    async def go() -> None:
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("s")  # B1, whose first head is WS2
            await pilot.press("1")
            assert any("fault injected: dead channel at WS2" in t for t in log_texts(app))
            assert states(app)["B1"] == "clear"  # nothing happens until a wheel passes
            app.advance(300)
            await pilot.pause()
            st = states(app)
            assert st["1G"] == st["B1"] == "disturbed"
            # What follow shows of it: the axles seen by one system only, and the health finding.
            assert any("Sys1 only at WS2" in t for t in log_texts(app))
            assert any(t.startswith("health single_channel WS2") for t in log_texts(app))
            # A reset is a request, decided in time order with the detections (as `sections --reset` decides
            # it): its verdict follows.  Accepted or not, with the channel still dead B1 is never shown clear:
            # the next train through WS2 is seen by one system only again.
            await pilot.press("r")
            assert "section B1: reset requested" in log_texts(app)[-1]
            app.advance(5)
            await pilot.pause()
            assert any(t.startswith("section B1: reset ") and "—" in t for t in log_texts(app))
            seen = []
            for _ in range(60):
                app.advance(10)
                seen.append(states(app)["B1"])
            assert "clear" not in seen and seen[-1] == "disturbed"

    run(go())


def test_power_loss_refuses_a_reset_until_power_returns() -> None:
    async def go() -> None:
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("s", "3")  # B1's first head loses power for 5 minutes
            # The console knows it from the silence: no record from WS2 for the power gap (a heartbeat missed:
            # the last at 0 s, the gap 30 s).
            app.advance(25)
            await pilot.pause()
            assert states(app)["B1"] == "clear"
            app.advance(20)
            await pilot.pause()
            assert states(app)["B1"] == "disturbed"
            assert any("power or contact lost at WS2" in t for t in log_texts(app))
            await pilot.press("r")
            app.advance(5)
            await pilot.pause()
            assert states(app)["B1"] == "disturbed"
            assert "section B1: reset REFUSED — no power or contact at WS2" in log_texts(app)

    run(go())


def test_reset_accepted_shows_preparatory_until_the_sweep_train() -> None:
    async def go() -> None:
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("s", "2")  # an isolated pulse at WS2, the line empty
            app.advance(15)  # WS2's first run closes after its idle gap: until then its records are held
            await pilot.pause()
            assert states(app)["B1"] != "clear"  # a pulse is never taken as proof of nothing
            await pilot.press("r")
            app.advance(1)
            await pilot.pause()
            assert states(app)["B1"] == "preparatory"
            assert any("section B1: reset accepted" in t for t in log_texts(app))
            before = {s.id: s for s in app.model.snapshot().sections}["B1"]
            seen = []
            for _ in range(60):
                app.advance(10)
                seen.append(states(app)["B1"])
                if seen[-1] == "clear":
                    break
            await pilot.pause()
            # Clear only once a train has swept the section: axles in and out.
            after = {s.id: s for s in app.model.snapshot().sections}["B1"]
            assert seen[-1] == "clear" and set(seen[:-1]) == {"preparatory"}
            assert after.count_in > before.count_in and after.count_out == after.count_in
            assert "sweep" in after.reason

    run(go())


def test_eot_loss_keeps_the_crossing_warning_on() -> None:
    """Fail-safe: without an EOT report the crossing cannot prove the train has
    passed, so the warning stays on after the head has gone by."""

    async def go() -> None:
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            app.advance(20)
            await pilot.pause()
            assert app.model.train_id() is not None
            await pilot.press("4")
            assert any("fault injected: eot loss" in t for t in log_texts(app))
            app.advance(400)
            await pilot.pause()
            snap = app.model.snapshot()
            assert snap.trains and snap.trains[0].eot_age_s is not None and snap.trains[0].eot_age_s > 30
            assert any(c.warning_on for c in snap.crossings)

    run(go())


def test_eot_loss_is_doubt_and_a_parting_is_parted_in_the_train_row() -> None:
    """Key 4 silences the EOT unit: the train row says doubt, never parted. Key 6 parts a
    train: its row says PARTED and the event log carries the evidence, as critical."""

    async def go() -> None:
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            app.advance(40)
            await pilot.pause()
            assert app.model.snapshot().trains[0].integrity == "whole"
            await pilot.press("4")
            app.advance(200)
            await pilot.pause()
            snap = app.model.snapshot()
            assert snap.trains[0].integrity == "doubtful"
            assert str(app.query_one(TrainsTable).get_row(snap.trains[0].id)[4]) == "doubt"
            assert not any("parted" in t for t in log_texts(app))

        app = make_app(seed=2)
        async with app.run_test(size=SIZE) as pilot:
            app.advance(40)
            await pilot.pause()
            await pilot.press("6")
            assert any("fault injected: train parting" in t for t in log_texts(app))
            app.advance(60)
            await pilot.pause()
            snap = app.model.snapshot()
            train = snap.trains[0]
            assert train.integrity == "parted"
            assert str(app.query_one(TrainsTable).get_row(train.id)[4]) == "PARTED"
            parted = [e for e in app.model.log if f"train {train.id} parted" in e.text]
            # The simulated units report the brake pipe: the EOT unit's emergency status with the front charged.
            assert parted and parted[0].severity == "critical" and "rear brake pipe vented" in parted[0].text

    run(go())


def test_truth_view_shows_the_truth_and_marks_differences() -> None:
    async def go() -> None:
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("s", "2")
            app.advance(15)
            await pilot.press("v")
            assert app.model.show_truth and "truth view" in app.sub_title
            snap = app.model.snapshot()
            assert {s.id: s.true_count for s in snap.sections}["B1"] == 0
            table = app.query_one(SectionsTable)
            assert "Truth" in [str(c.label) for c in table.columns.values()]
            # The pulse left 1G and B1 held occupied with no train in them: both differ.
            assert {"1G", "B1"} <= app.model.differences(snap)
            await pilot.press("v")
            assert "Truth" not in [str(c.label) for c in table.columns.values()]

    run(go())


def test_head_loss_makes_the_train_stale_and_differ_from_the_truth() -> None:
    async def go() -> None:
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            app.advance(30)
            await pilot.press("v", "5")
            app.advance(60)
            await pilot.pause()
            snap = app.model.snapshot()
            train = snap.trains[0]
            assert train.head_age_s is not None and train.head_age_s > 30
            assert train.id in app.model.differences(snap)
            cells = app.query_one(TrainsTable).get_row(train.id)
            units = str(cells[4])  # Train, km/h, Head m, True head, Units
            assert "head" in units and "old" in units

    run(go())


def test_log_filter_and_help_screen() -> None:
    async def go() -> None:
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("s", "1")
            app.advance(300)
            await pilot.press("f")
            assert app.model.log_filter == "warning"
            assert all(e.severity != "info" for e in app.model.visible_log())
            await pilot.press("f")
            assert all(e.severity == "critical" for e in app.model.visible_log())
            await pilot.press("question_mark")
            assert isinstance(app.screen, HelpScreen)
            await pilot.press("escape")
            assert not isinstance(app.screen, HelpScreen)
            await pilot.press("q")
        assert app.return_code == 0

    run(go())


def test_log_text_stays_data() -> None:
    """A section name or log line that looks like markup is drawn as written."""
    from console.tui.model import LogEntry
    from console.tui.widgets.event_log import EventLog

    async def go() -> None:
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            app.model.log.append(LogEntry(app.model.source.now_ns, "warning", "[bold red]x[/] \x1b[31mred"))
            app.refresh_views()
            await pilot.pause()
            text = app.query_one(EventLog).render()
            assert "[bold red]x[/]" in str(text)
            assert "\x1b" not in str(text)

    run(go())


def test_five_trains_on_the_line() -> None:
    async def go() -> None:
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            app.advance(10)
            for _ in range(5):
                await pilot.press("a")
            best = 0
            for _ in range(30):
                app.advance(20)
                best = max(best, len(app.model.snapshot().trains))
            await pilot.pause()
            assert best >= 5
            added = [t for t in log_texts(app) if "added by the operator" in t]
            assert len(added) == 5

    run(go())


def test_replay_drives_the_same_view_and_jumps() -> None:
    logs = [ROOT / "sample_logs" / "example_station.log", ROOT / "sample_logs" / "crossing_example.csv"]
    source = ReplaySource(logs, _load_layout("example"))
    app = StationApp(StationModel(source), autoplay=False)

    async def go() -> None:
        async with app.run_test(size=SIZE) as pilot:
            start = source.now_ns
            await pilot.press("right_square_bracket")
            assert source.now_ns - start == 300 * 1_000_000_000
            await pilot.press("left_square_bracket")
            assert source.now_ns == start
            # The two logs are six weeks apart: with no train in view the replay
            # skips the quiet stretch instead of playing it.
            first_diag = source.first_record_ns
            assert first_diag is not None
            for _ in range(200):
                app.advance(60)
                if source.now_ns >= first_diag:
                    break
            assert source.now_ns >= first_diag
            assert any("skipped to the next record" in t for t in log_texts(app))
            app.advance((source.end_ns - source.start_ns) / 1e9)
            await pilot.pause()
            assert "replay" in app.sub_title
            # The replayed records moved the section engine off its start state.
            snap = app.model.snapshot()
            assert sum(snap.head_counts.values()) > 0
            assert any(s.count_in > 0 for s in snap.sections)
            # Operator actions on a replay are refused with a notice, not a crash.
            await pilot.press("1", "r", "v", "a")
            assert not app.model.show_truth

    run(go())


def test_diagram_reads_without_colour() -> None:
    from console.tui.widgets.track import draw

    app = make_app()
    app.model.source.advance(2)
    app.model.source.inject("power_loss", "WS2", 300)  # type: ignore[attr-defined]
    app.model.step(45)  # known lost after the power gap of silence
    text = draw(app.model.source.layout, app.model.snapshot(), 96).plain
    rows = text.split("\n")
    assert len(rows) == 5
    assert "1G!" in rows[1] and "B1!" in rows[1]  # disturbed, marked by a letter as well as a colour
    assert "B2·" in rows[1]
    assert "┃WS2:" in rows[2]
    assert "╳11+850" in rows[3]


@pytest.mark.parametrize("size", [(80, 24), (160, 50)])
def test_small_and_large_terminals(size: tuple[int, int]) -> None:
    async def go() -> None:
        app = make_app()
        async with app.run_test(size=size) as pilot:
            app.advance(60)
            await pilot.pause()
            for widget in (TrackDiagram, SectionsTable, TrainsTable):
                region = app.query_one(widget).region
                assert region.width > 0 and region.height >= 3
            assert isinstance(app.query_one(SectionsTable), DataTable)

    run(go())


# -- SVG snapshots: the layout as a person sees it ------------------------------


def _stepped(seconds: float, keys: tuple[str, ...] = ()) -> StationApp:
    app = make_app()
    for k in keys:
        if k == "dead_channel_B1":
            app.model.select_section(1)
            app.model.source.inject("dead_channel", "WS2")  # type: ignore[attr-defined]
    for _ in range(int(seconds)):  # second by second, as the live view does, so the plot has a history
        app.model.step(1.0)
    return app


def test_snapshot_main_screen(snap_compare: object) -> None:
    assert snap_compare(_stepped(150), terminal_size=SIZE)  # type: ignore[operator]


def test_snapshot_help_screen(snap_compare: object) -> None:
    assert snap_compare(_stepped(0), press=["question_mark"], terminal_size=SIZE)  # type: ignore[operator]


def test_snapshot_fault(snap_compare: object) -> None:
    assert snap_compare(_stepped(300, ("dead_channel_B1",)), press=["v"], terminal_size=SIZE)  # type: ignore[operator]


# -- the command line -------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--replay"], "--replay needs the logs"),
        (["sample_logs/example_station.log"], "add --replay"),
        (["--replay", "no_such.log"], "no such file"),
        (["--replay", "sample_logs/README.md"], "nothing to replay"),
        (["--layout", "no_such.toml"], "no_such.toml"),
        ([], "needs a terminal"),  # CliRunner's streams are no terminal: never hang in a pipe
        (["--replay", "sample_logs/example_station.log"], "needs a terminal"),
    ],
)
def test_station_command_rejects_bad_input_cleanly(args: list[str], message: str) -> None:
    from typer.testing import CliRunner

    from console.cli.app import app as cli

    result = CliRunner().invoke(cli, ["station", *args], catch_exceptions=False)
    assert result.exit_code == 2
    assert message in result.stderr
    assert "Traceback" not in result.output + result.stderr


def test_the_speed_option_and_its_example_say_the_speeds_the_view_has() -> None:
    # The help said "1 to 1000 × real time" and its example asked --speed 30: the view has steps, and 30 ran at 20×.
    import re

    import typer

    from console.cli.app import app as cli
    from console.cli.examples import EXAMPLES

    command = typer.main.get_command(cli).commands["station"]  # type: ignore[attr-defined]
    help_text = next(p.help for p in command.params if "--speed" in p.opts)
    assert [int(n) for n in re.findall(r"\d+", help_text.split(":", 1)[1])] == list(SPEEDS)
    asked = [float(m) for e in EXAMPLES["station"] for m in re.findall(r"--speed (\S+)", e)]
    assert asked and all(x in SPEEDS for x in asked)


def test_station_command_error_as_a_subprocess() -> None:
    import subprocess
    import sys

    exe = Path(sys.executable).with_name("trackside")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-c", "from console.cli.app import app; app()"]
    proc = subprocess.run([*cmd, "station", "--replay"], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert proc.returncode == 2
    assert proc.stderr.startswith("trackside: error: --replay needs the logs")


def test_crossing_lights_then_barriers() -> None:
    """The barriers come down a few seconds after the lights start, and rise with them."""
    from console.analysis.crossing.values import ControllerSettings

    BARRIER_DELAY_S = ControllerSettings().barrier_delay_s

    app = make_app()
    m = app.model
    seen: list[tuple[bool, bool]] = []
    on_at = None
    for _ in range(600):
        m.step(1.0)
        c = m.snapshot().crossings[0]
        seen.append((c.warning_on, c.barrier_down))
        if c.warning_on and on_at is None:
            on_at = len(seen)
        if on_at is not None and not c.warning_on:
            break
    assert on_at is not None
    assert all(not down for on, down in seen if not on)  # never down with the lights off
    downs = [i for i, (_, down) in enumerate(seen, 1) if down]
    assert downs and downs[0] - on_at >= BARRIER_DELAY_S - 1


def test_a_replay_shows_the_lines_it_could_not_read(tmp_path: Path) -> None:
    """Replayed logs' rejected lines vanished: the view showed nothing of them.  Now each is a warning in the
    log, as ``station --live`` shows a followed file's."""
    lines = (ROOT / "sample_logs" / "example_station.log").read_text(encoding="utf-8").splitlines()
    log = tmp_path / "[b]station.log"  # a name that looks like markup is shown as written
    log.write_text("\n".join([*lines[:100], "not a record", *lines[100:]]) + "\n", encoding="utf-8")
    source = ReplaySource([log], _load_layout("example"))
    app = StationApp(StationModel(source), autoplay=False)

    async def go() -> None:
        async with app.run_test(size=SIZE) as pilot:
            app.advance(1)
            await pilot.pause()
            rejected = [e for e in app.model.log if e.text.startswith("rejected")]
            assert [(e.severity, e.text.split(": ")[0]) for e in rejected] == [("warning", f"rejected {log}:101")]
            app.advance(1)  # said once, not at every step
            assert len([e for e in app.model.log if e.text.startswith("rejected")]) == 1
            await pilot.press("f")  # warnings and worse: still listed
            await pilot.pause()
            from console.tui.widgets.event_log import EventLog

            assert f"rejected {log}:101" in str(app.query_one(EventLog).render())

    run(go())
