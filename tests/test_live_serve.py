"""station --live and --serve: the live view in the terminal (Pilot) and in headless Chromium."""

from __future__ import annotations

import asyncio
import contextlib
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from console.inputs.uri import open_source
from console.layout import load_layout
from console.tui.live_app import LiveStationApp
from console.tui.live_source import LiveSource
from tests.live_fixtures import REPO, DevToolsPage, HeadlessChromium, free_port, port_open, trackside, wait_until

pytestmark = pytest.mark.timeout(90)

SAMPLE = (REPO / "sample_logs" / "example_station.log").read_bytes().splitlines(keepends=True)
FIRST_WHEEL = next(i for i, line in enumerate(SAMPLE) if b"Radsensor" in line)
BEFORE_TRAIN = b"".join(SAMPLE[:FIRST_WHEEL])
FIRST_TRAIN = b"".join(SAMPLE[FIRST_WHEEL : FIRST_WHEEL + 400])  # the sweep train over the whole line


def test_live_station_view_follows_a_growing_log_and_shows_each_source(tmp_path: Path) -> None:
    log = tmp_path / "station.log"
    log.write_bytes(BEFORE_TRAIN)
    source = LiveSource(load_layout("example"), [open_source(f"file:{log}", from_start=True)])
    app = LiveStationApp(source)

    async def scenario() -> float:
        async with app.run_test(size=(160, 50)) as pilot:

            async def until(cond: object, timeout_s: float) -> bool:
                end = time.monotonic() + timeout_s
                while time.monotonic() < end:
                    if cond():  # type: ignore[operator]
                        return True
                    await pilot.pause(0.02)
                return False

            status = app.query_one("#sources")
            assert await until(lambda: "connected" in str(status.render()), 5)
            states = lambda: {s.id: s.state for s in app.model.snapshot().sections}  # noqa: E731
            assert set(states().values()) == {"preparatory"}
            t0 = time.monotonic()
            with log.open("ab") as f:
                f.write(FIRST_TRAIN)
            assert await until(lambda: "clear" in states().values(), 5), states()
            return time.monotonic() - t0

    seconds = asyncio.run(scenario())
    # Appended to shown on screen: the 0.1 s redraw tick plus inotify and the engine.
    assert seconds < 2.0
    source.stop()


def test_the_live_view_redraws_when_data_arrives_not_on_a_timer(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import console.tui.live_app as live_app

    # With the status timer an hour long, only the sources' wake-up can bring the new state on screen.
    monkeypatch.setattr(live_app, "STATUS_S", 3600.0)
    log = tmp_path / "station.log"
    log.write_bytes(BEFORE_TRAIN)
    source = LiveSource(load_layout("example"), [open_source(f"file:{log}", from_start=True)])
    app = LiveStationApp(source)
    drawn: list[set[str]] = []
    refresh = app.refresh_views

    def noted() -> None:
        refresh()
        drawn.append({s.state for s in app.model.snapshot().sections})

    app.refresh_views = noted  # type: ignore[method-assign]

    async def scenario() -> tuple[float, int]:
        async with app.run_test(size=(160, 50)):
            end = time.monotonic() + 5
            while source.statuses()[0].messages == 0 and time.monotonic() < end:
                await asyncio.sleep(0.02)
            await asyncio.sleep(0.3)
            idle_advances = app.advances
            await asyncio.sleep(1.0)  # nothing arrives: no advance, no redraw
            assert app.advances == idle_advances
            t0 = time.monotonic()
            with log.open("ab") as f:
                f.write(FIRST_TRAIN)
            while not any("clear" in d for d in drawn) and time.monotonic() - t0 < 5:
                await asyncio.sleep(0.01)
            return time.monotonic() - t0, app.advances - idle_advances

    seconds, advances = asyncio.run(scenario())
    source.stop()
    assert any("clear" in d for d in drawn)
    assert seconds < 2.0
    assert advances >= 1


def test_an_unchanged_panel_is_not_repainted() -> None:
    from rich.text import Text
    from textual.app import App, ComposeResult
    from textual.widgets import Static

    from console.tui.widgets.quiet import retitle, update_if_changed

    class One(App[None]):
        def compose(self) -> ComposeResult:
            yield Static("", id="panel")

    repaints: list[bool] = []

    async def scenario() -> str | None:
        app = One()
        async with app.run_test():
            panel = app.query_one("#panel", Static)
            panel.refresh = lambda *a, **k: repaints.append(True) or panel  # type: ignore[method-assign]
            assert update_if_changed(panel, Text("WS1 · 4 axles", style="green"))
            assert not update_if_changed(panel, Text("WS1 · 4 axles", style="green"))
            assert update_if_changed(panel, Text("WS1 · 4 axles", style="red"))  # a new style is a change
            retitle(panel, title="Sections", subtitle="B1: ok")
            retitle(panel, title="Sections", subtitle="B1: ok")
            retitle(panel, subtitle="B1: count 2")
            return panel.border_subtitle

    assert asyncio.run(scenario()) == "B1: count 2"
    assert len(repaints) == 2 + 2 + 1


def _serve(log: Path, port: int) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        trackside(
            "station",
            "--serve",
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            "--layout",
            "example",
            "--live",
            f"file:{log}",
        ),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # textual-serve starts the app per browser: stop the whole group
        env={**os.environ, "COLUMNS": "160"},
    )


def test_served_station_view_loads_in_headless_chromium_shows_the_track_and_updates(tmp_path: Path) -> None:
    import aiohttp

    log = tmp_path / "station.log"
    log.write_bytes(BEFORE_TRAIN)
    port = free_port()
    server = _serve(log, port)
    browser = HeadlessChromium(tmp_path)
    try:
        assert wait_until(lambda: port_open(port), 20), "textual-serve did not listen"
        ws_url = browser.page_ws_url()

        async def scenario() -> tuple[str, str, bytes, bytes]:
            import base64

            async with aiohttp.ClientSession() as session, session.ws_connect(ws_url, max_msg_size=0) as ws:
                page = DevToolsPage(ws)
                await page.call("Network.enable")
                await page.call("Page.enable")
                await page.call("Page.navigate", url=f"http://127.0.0.1:{port}/")
                for _ in range(40):  # the app starts in its own process: up to 20 s
                    await page.pump(0.5)
                    shown = page.text()
                    if "WS5" in shown and "12+940" in shown and "connected" in shown:
                        break
                first = page.text()
                shot1 = base64.b64decode((await page.call("Page.captureScreenshot", format="png"))["data"])
                page.frames.clear()
                with log.open("ab") as f:
                    f.write(FIRST_TRAIN)
                for _ in range(20):
                    await page.pump(0.5)
                    if "clear" in page.text():
                        break
                shot2 = base64.b64decode((await page.call("Page.captureScreenshot", format="png"))["data"])
                return first, page.text(), shot1, shot2

        first, later, shot1, shot2 = asyncio.run(scenario())
    finally:
        browser.close()
        with contextlib.suppress(ProcessLookupError):
            os.killpg(server.pid, signal.SIGTERM)
        code = server.wait(10)
    assert code == 143  # stopped by SIGTERM, as the README's exit codes say
    # The track diagram: every counting head and both crossings of the example line.
    for label in ("WS1", "WS2", "WS3", "WS4", "WS5", "11+850", "12+940", "preparatory"):
        assert label in first, label
    assert "connected" in first  # the source status line
    # It updates: the sweep train cleared sections, and the picture changed.
    assert "clear" in later
    assert shot1[:8] == b"\x89PNG\r\n\x1a\n" and shot1 != shot2
    (tmp_path / "served.png").write_bytes(shot2)


@pytest.mark.parametrize(
    ("args", "error"),
    [
        (["--replay", "/nonexistent/ws4.log"], "/nonexistent/ws4.log: no such file"),
        (["--replay"], "--replay needs the logs to replay"),
        (["--archive", "/nonexistent/arc"], "add --replay"),
        (["--replay", "--archive", "/nonexistent/arc"], "/nonexistent/arc: no archive here yet"),
        (["--replay", str(REPO / "sample_logs" / "README.md")], "nothing to replay"),
    ],
)
def test_a_served_view_that_could_not_start_is_refused_before_serving(args: list[str], error: str) -> None:
    """`station --serve` with a replay that cannot start served the page anyway: each browser tab then failed
    (and --archive alone served the simulation, the archive ignored).  Now the same one-line error as without
    --serve, exit 2, and no server."""
    port = free_port()
    proc = subprocess.run(
        trackside("station", "--serve", "--port", str(port), *args), capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 2, proc.stdout
    assert proc.stderr.count("\n") == 1 and error in proc.stderr, proc.stderr
    assert "Serving" not in proc.stdout


def test_a_served_archive_replay_runs_the_archive_replay_in_each_tab() -> None:
    """The served command dropped --archive, --from and --to: every tab of `station --replay --archive DIR
    --serve` failed with "--replay needs the logs to replay"."""
    from console.cli.commands.station_live import served_command

    argv = served_command("example", [], 1, 5.0, True, [], Path("arc"), "2026-03-02T08:00", "2026-03-02T09:00")
    assert argv[argv.index("station") :] == [
        *("station", "--layout", "example", "--seed", "1", "--speed", "5.0", "--replay"),
        *("--archive", "arc", "--from", "2026-03-02T08:00", "--to", "2026-03-02T09:00"),
    ]
