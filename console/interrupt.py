"""Ctrl-C stops a DuckDB statement while it runs, and ends the command as Ctrl-C does (exit 130).

DuckDB's engine alone (``_duckdb``, what ``trackside query`` runs its plain statements on) does not look for
Ctrl-C while a statement runs: a query of minutes ran on to its end.  The package's relations do, but turn it
into ``RuntimeError: Query interrupted``, which read as an internal error.  Here the signal reaches a thread
through Python's wakeup file descriptor (written by the C-level handler, whatever the main thread is doing);
that thread interrupts the connection, and whatever error the statement then raises becomes KeyboardInterrupt.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Iterator
from typing import Any


@contextlib.contextmanager
def interruptible(con: Any) -> Iterator[None]:
    """Within: a SIGINT interrupts ``con``'s running statement and the block ends in KeyboardInterrupt."""
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGINT) in (
        signal.SIG_IGN,
        None,
    ):
        yield  # signals reach the main thread only; an ignored Ctrl-C stays ignored
        return
    read_end, write_end = os.pipe()
    os.set_blocking(write_end, False)
    previous = signal.set_wakeup_fd(write_end)
    interrupted = threading.Event()

    def watch() -> None:
        while True:
            try:
                got = os.read(read_end, 64)
            except OSError:
                return
            if not got:
                return  # the write end closed: the block is over
            if signal.SIGINT in got:
                interrupted.set()
                with contextlib.suppress(Exception):
                    con.interrupt()

    watcher = threading.Thread(target=watch, name="query interrupt", daemon=True)
    watcher.start()
    try:
        yield
    except Exception:
        if interrupted.is_set():
            raise KeyboardInterrupt from None
        raise
    finally:
        signal.set_wakeup_fd(previous)
        os.close(write_end)
        watcher.join(timeout=5)
        os.close(read_end)


def is_ctrl_c(exc: BaseException) -> bool:
    """Ctrl-C as DuckDB reports it: its Python package turns the KeyboardInterrupt of a statement it runs into
    ``RuntimeError: Query interrupted`` (and ``Connection.interrupt`` into ``InterruptException``)."""
    if isinstance(exc, KeyboardInterrupt):
        return True
    if type(exc).__name__ == "InterruptException" and type(exc).__module__ in ("duckdb", "_duckdb"):
        return True
    return type(exc) is RuntimeError and str(exc) == "Query interrupted"
