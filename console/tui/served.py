"""``station --serve``: textual-serve's server, with every app process it starts tied to its tab and to itself.

textual-serve starts one app process per browser tab (through ``/bin/sh -c``)
and, when the tab goes, asks it to quit and waits; when the server goes, its
apps are left to themselves.  Seen: an app whose tab closed while it was still
starting, and the apps of a server stopped by Ctrl-C, kept running without a
browser.  Here:

* each app is started without a shell, in a process group of its own
  (:class:`TiedAppService`); when its tab goes it is asked to quit, then sent
  SIGTERM, then SIGKILL, each after a grace period (:data:`QUIT_S`, :data:`TERM_S`);
* Ctrl-C or SIGTERM to the server alone ends every app's group before the
  server stops (:class:`StationServer`), instead of waiting for the tabs;
* an app whose server dies without a word (``kill -9``) gets SIGKILL from the
  kernel (``PR_SET_PDEATHSIG``, set by the app itself at start:
  :func:`console.tui.serve_guard.guard_served_app`), and a thread that watches
  its parent ends it where that is not available.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import signal
import threading
from collections.abc import Sequence
from typing import Any

from textual_serve.app_service import AppService
from textual_serve.server import Server

from console.tui.serve_guard import SERVER_PID_ENV

QUIT_S = 3.0  # after "quit", the app has this long to exit by itself
TERM_S = 2.0  # after SIGTERM, this long before SIGKILL


def _signal_group(pid: int, sig: signal.Signals) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pid, sig)


class TiedAppService(AppService):
    """One tab's app: started in its own process group, and ended for sure when the tab goes."""

    def __init__(self, argv: Sequence[str], live: set[TiedAppService], **kwargs: Any) -> None:
        super().__init__(" ".join(argv), **kwargs)
        self.argv = list(argv)
        self.live = live

    async def _open_app_process(self, width: int = 80, height: int = 24) -> asyncio.subprocess.Process:
        env = self._build_environment(width=width, height=height)
        env[SERVER_PID_ENV] = str(os.getpid())
        self._process = process = await asyncio.create_subprocess_exec(
            *self.argv,
            stdin=asyncio.subprocess.PIPE,
            stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.PIPE,
            env=env,
            start_new_session=True,  # its own group: the app and anything it starts end together
        )
        assert process.stdin is not None
        self._stdin = process.stdin
        self.live.add(self)
        return process

    def kill_group(self, sig: signal.Signals) -> None:
        if self._process is not None and self._process.returncode is None:
            _signal_group(self._process.pid, sig)

    async def _exited(self, timeout_s: float) -> bool:
        assert self._process is not None
        try:
            await asyncio.wait_for(asyncio.shield(self._process.wait()), timeout_s)
        except TimeoutError:
            return False
        return True

    async def stop(self) -> None:
        """Ask the app to quit; past the grace periods, SIGTERM and SIGKILL to its group; then wait for it."""
        try:
            if self._process is not None and self._process.returncode is None:
                with contextlib.suppress(Exception):  # its stdin may be closed already
                    await asyncio.wait_for(self.send_meta({"type": "quit"}), 1.0)
                if not await self._exited(QUIT_S):
                    self.kill_group(signal.SIGTERM)
                    if not await self._exited(TERM_S):
                        self.kill_group(signal.SIGKILL)
                        await self._exited(TERM_S)
            if self._task is not None:
                with contextlib.suppress(asyncio.CancelledError):
                    await self._task
                self._task = None
        finally:
            self.kill_group(signal.SIGKILL)  # cancelled half-way, or anything left in its group
            self.live.discard(self)


class StationServer(Server):
    """textual-serve's server running ``argv`` per tab, whose apps never outlive their tab or the server."""

    def __init__(self, argv: Sequence[str], **kwargs: Any) -> None:
        super().__init__(" ".join(argv), **kwargs)
        self.argv = list(argv)
        self.live: set[TiedAppService] = set()
        self.sockets: set[Any] = set()  # the tabs' websockets: closed on exit, or aiohttp waits for them
        self.closing: list[asyncio.Task[Any]] = []
        self.stopped_by: int | None = None  # the signal that stopped the server: the exit code says it

    def _on_signal(self, signum: int) -> None:
        self.stopped_by = self.stopped_by or signum
        self.request_exit()

    def request_exit(self) -> None:
        """Ctrl-C or SIGTERM: end every app's group now (SIGKILL after TERM_S), then stop serving."""
        apps = list(self.live)
        for app in apps:
            app.kill_group(signal.SIGTERM)
        if apps:

            def kill() -> None:
                for app in apps:
                    app.kill_group(signal.SIGKILL)

            threading.Timer(TERM_S, kill).start()
        loop = asyncio.get_running_loop()
        # Run while aiohttp shuts down: the tabs' handlers then end (kept: a task needs a reference).
        self.closing = [loop.create_task(ws.close()) for ws in list(self.sockets)]
        super().request_exit()

    async def on_startup(self, app: Any) -> None:
        await super().on_startup(app)
        # In place of textual-serve's handlers (set in serve()), to know which signal it was: 130 or 143.
        loop = asyncio.get_running_loop()
        for signum in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(signum, self._on_signal, signum)
        self.console.print(
            "Each browser tab starts its own station view: the page shows textual-serve's splash "
            "for a few seconds while it starts.",
            highlight=False,
        )

    async def handle_websocket(self, request: Any) -> Any:
        """As textual-serve's, with a :class:`TiedAppService` for the tab."""
        from aiohttp import web
        from textual_serve.server import log, to_int

        websocket = web.WebSocketResponse(heartbeat=15)
        width = to_int(request.query.get("width", "80"), 80)
        height = to_int(request.query.get("height", "24"), 24)
        app_service: TiedAppService | None = None
        self.sockets.add(websocket)
        try:
            await websocket.prepare(request)
            app_service = TiedAppService(
                self.argv,
                self.live,
                write_bytes=websocket.send_bytes,
                write_str=websocket.send_str,
                close=websocket.close,
                download_manager=self.download_manager,
                debug=self.debug,
            )
            await app_service.start(width, height)
            await self._process_messages(websocket, app_service)
        except asyncio.CancelledError:
            await websocket.close()
        except Exception as error:
            log.exception(error)
        finally:
            self.sockets.discard(websocket)
            if app_service is not None:
                await app_service.stop()
        return websocket
