"""The served app's side of ``station --serve`` (:mod:`console.tui.served`): never outlive the server.

Kept apart from the server's module: an app process imports only this (no aiohttp, no textual-serve).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import threading
import time

SERVER_PID_ENV = "TRACKSIDE_SERVE_PID"  # set for the apps: the server they belong to
_PR_SET_PDEATHSIG = 1


def _watch_parent(server_pid: int) -> None:
    while True:
        if os.getppid() != server_pid:
            os._exit(0)  # the server is gone: nobody reads this view any more
        time.sleep(0.5)


def guard_served_app() -> None:
    """In an app started by :class:`StationServer`: die with the server, and never outlive a SIGTERM.

    The kernel's parent-death signal where there is one (Linux), a thread watching the parent besides;
    a SIGTERM before the view is up ends the process at once (the view's own handler replaces this one).
    """
    try:
        server_pid = int(os.environ[SERVER_PID_ENV])
    except (KeyError, ValueError):
        return
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != server_pid:
        os._exit(0)  # the server went before the signal was armed
    threading.Thread(target=_watch_parent, args=(server_pid,), name="serve-parent", daemon=True).start()
    signal.signal(signal.SIGTERM, lambda *_: os._exit(128 + signal.SIGTERM))
