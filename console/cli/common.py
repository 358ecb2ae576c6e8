"""What the commands share: one-line errors, the guard that turns input errors into exit 2,
JSON output, layouts and the diagnostic job (the option types are in :mod:`console.cli.options`)."""

from __future__ import annotations

import contextlib
import errno
import functools
import inspect
import io
import math
import os
import re
import signal
import stat
import sys
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, cast

import typer

from console import exit_codes
from console.cli.options import REJECTIONS_LISTED, STDIN
from console.interrupt import is_ctrl_c
from console.safe_text import clean, show_path

JSON_SCHEMA_ANALYZE = "trackside.analyze/1"


def fail(message: str, code: int = exit_codes.USAGE) -> typer.Exit:
    """One unwrapped line on stderr (file names may hold anything: escaped)."""
    sys.stderr.write(f"trackside: error: {clean(message)}\n")
    sys.stderr.flush()
    return typer.Exit(code)


def check_inputs(paths: list[Path]) -> None:
    """Every input readable, before any work: one line and exit 2 for the first that is not.

    ``-`` is standard input (once); FIFOs, ``/dev/stdin`` and process
    substitution (``<(zcat x.gz)``) are read as streams; a directory, a
    dangling symlink or a symlink loop is refused with its own reason.
    """
    stdin_given = False
    seen: dict[tuple[int, int], Path] = {}  # a file given twice would be read twice (its fixes, frames doubled)
    for p in paths:
        if os.fsdecode(p) == STDIN:
            if stdin_given:
                raise fail("-: standard input given twice")
            if sys.stdin is None:
                raise fail("-: standard input is closed")
            stdin_given = True
            continue
        try:
            st = os.stat(p)
        except FileNotFoundError:
            raise fail(f"{show_path(p)}: {'symlink to nothing' if os.path.islink(p) else 'no such file'}") from None
        except OSError as exc:
            reason = "symlink loop" if exc.errno == errno.ELOOP else f"cannot open ({exc.strerror or exc})"
            raise fail(f"{show_path(p)}: {reason}") from None
        if stat.S_ISDIR(st.st_mode):
            raise fail(f"{show_path(p)}: is a directory, expected a log file")
        if stat.S_ISSOCK(st.st_mode):
            raise fail(f"{show_path(p)}: is a socket, expected a log file")
        if not os.access(p, os.R_OK):
            raise fail(f"{show_path(p)}: permission denied")
        if stat.S_ISREG(st.st_mode):
            first = seen.setdefault((st.st_dev, st.st_ino), p)
            if first is not p:
                same = "" if os.fsdecode(first) == os.fsdecode(p) else f" (the same file as {show_path(first)})"
                raise fail(f"{show_path(p)}: given twice{same}")


# Errors that mean the output cannot be written (not that an input is bad: the
# readers turn theirs into InputError): a full disk or quota, a file too large,
# a read-only file system, a closed standard output.  Not EIO, which a failing
# input disk raises too.
OUTPUT_ERRNOS = frozenset((errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EBADF, errno.EROFS))


class Terminated(BaseException):
    """SIGTERM, raised in the main thread so that partial output files are cleaned up on the way out."""


class ClosedOutput:
    """Standard output that was closed before we started (``>&-``): any write fails, as it would on a file."""

    encoding = "utf-8"
    errors = "strict"

    def write(self, text: str) -> int:
        raise OSError(errno.EBADF, "standard output is closed")

    def flush(self) -> None:
        return None

    def isatty(self) -> bool:
        return False

    def fileno(self) -> int:
        raise OSError(errno.EBADF, "standard output is closed")

    def writable(self) -> bool:
        return True


def _silence_stdout() -> None:
    """Point fd 1 at /dev/null so that Python's own flush at exit cannot fail a second time."""
    try:
        fd = sys.stdout.fileno() if sys.stdout is not None else -1
    except (OSError, ValueError, AttributeError):
        return
    if fd != 1:
        return
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 1)
        os.close(devnull)
    except OSError:
        pass


def output_failed(exc: OSError) -> int:
    """The exit code for a failed write to the output: 0 for a reader that left (``| head``), else 2."""
    _silence_stdout()
    if isinstance(exc, BrokenPipeError) or exc.errno == errno.EPIPE:
        return exit_codes.OK
    reason = exc.strerror or str(exc) or type(exc).__name__
    try:
        sys.stderr.write(f"trackside: error: cannot write output: {reason}\n")
        sys.stderr.flush()
    except (OSError, ValueError, AttributeError):
        pass
    return exit_codes.USAGE


def _flush_at_exit() -> None:
    # Python flushes stdout once more at shutdown and, if that fails, prints
    # "Exception ignored ... BrokenPipeError" and exits 120: do it here first.
    try:
        if sys.stdout is not None:
            sys.stdout.flush()
    except OSError as exc:
        if output_failed(exc) != exit_codes.OK:
            os._exit(exit_codes.USAGE)


def exit_at_once(exc: SystemExit) -> None:
    """End the process now with ``exc``'s status, as a normal exit would but without the interpreter's teardown.

    After a large read that teardown (freeing every object, module by module) took 20–30 ms of a 0.7 s
    `analyze`.  Taken only when nothing else runs (no other thread) and the status is a number: the exit
    handlers run and stdout and stderr are flushed first, as at a normal exit; a flush that fails leaves the
    exit to Python (and to :func:`_flush_at_exit`).
    """
    code = exc.code
    if not (code is None or isinstance(code, int)) or threading.active_count() > 1:
        return
    import atexit

    atexit._run_exitfuncs()
    try:
        for stream in (sys.stdout, sys.stderr):
            if stream is not None:
                stream.flush()
    except (OSError, ValueError):
        return
    os._exit(code or 0)


def _reopen_closed_std_fds() -> None:
    """Occupy fds 0-2 if they were closed at start, so no file we open later becomes our stdout."""
    for fd in (0, 1, 2):
        try:
            os.fstat(fd)
        except OSError:
            try:
                new = os.open(os.devnull, os.O_RDWR)
            except OSError:
                continue
            if new != fd:
                os.dup2(new, fd)
                os.close(new)


_process_guarded = False


def install_process_guards() -> Callable[[], None]:
    """Once per process: closed stdout, SIGTERM and the exit-time flush; returns an undo for SIGTERM."""
    global _process_guarded
    if not _process_guarded and sys.stdout is sys.__stdout__:
        _process_guarded = True
        _reopen_closed_std_fds()
        if sys.stdout is None:
            sys.stdout = ClosedOutput()
        if sys.stderr is None:
            sys.stderr = open(os.devnull, "w")  # noqa: SIM115 - lives as long as the process
        # Last line of defence: a name that is not UTF-8 and escaped nobody's escaping
        # prints as \udcff instead of failing the whole command.
        for stream in (sys.stdout, sys.stderr):
            if isinstance(stream, io.TextIOWrapper):
                with contextlib.suppress(ValueError, OSError):
                    stream.reconfigure(errors="backslashreplace")
        import atexit

        atexit.register(_flush_at_exit)
    try:
        previous = signal.getsignal(signal.SIGTERM)

        def on_sigterm(signum: int, frame: object) -> None:
            raise Terminated()

        signal.signal(signal.SIGTERM, on_sigterm)
    except ValueError:  # not the main thread (an embedding app): leave signals alone
        return lambda: None

    def undo() -> None:
        signal.signal(signal.SIGTERM, previous)

    return undo


if TYPE_CHECKING:
    from rich.console import Console as RichConsole

    class Console(RichConsole):
        """Rich's console, quiet on a broken pipe (below)."""

        def on_broken_pipe(self) -> None: ...


# The width tables are laid out in when no terminal gives one: wide enough for any row of ours.
PIPED_WIDTH = 400
_TRAILING_SPACES = re.compile(r" +\n")


class _NoTrailingSpaces:
    """A text file whose lines are written without their trailing spaces (a table's cell padding)."""

    def __init__(self, file: Any) -> None:
        self._file = file

    def write(self, text: str) -> int:
        return int(self._file.write(_TRAILING_SPACES.sub("\n", text)) or 0)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._file, name)


def __getattr__(name: str) -> Any:
    # Rich is imported when a command first asks for its console, not by every command that imports this
    # module (a short query prints none: a tenth of its start-up).
    if name != "Console":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from rich.console import Console as RichConsole

    class Console(RichConsole):
        """Rich's console, but a reader that stops early (``| head``) is not an error:
        Rich exits 1 on a broken pipe; we stop quietly with 0.

        Piped or redirected (no terminal, no ``COLUMNS``), lines are not cut at Rich's 80 columns: a script
        or ``grep`` reading the tables gets each file name and row on one line, without the spaces that pad
        it to the table's width."""

        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            if "width" not in kwargs and not self.is_terminal and not os.environ.get("COLUMNS"):
                self.width = PIPED_WIDTH
                self.file = cast("IO[str]", _NoTrailingSpaces(self.file))

        def on_broken_pipe(self) -> None:
            _silence_stdout()
            raise SystemExit(exit_codes.OK)

    globals()["Console"] = Console
    return Console


def _exit_within(code: int, seconds: float = 5.0) -> None:
    """End the process with ``code`` after ``seconds`` if the interpreter has not ended it by then.

    The interpreter's exit waits for every worker thread, and one blocked in a read (a FIFO whose writer
    stays open) never returns: a report on a FIFO once hung for a minute after Ctrl-C.  Its outputs are
    already removed by then (the stack has unwound)."""

    def last_resort() -> None:
        time.sleep(seconds)
        os._exit(code)

    threading.Thread(target=last_resort, name="exit watchdog", daemon=True).start()


def guard(fn: Callable[[], int]) -> int:
    """Run a command body: input errors become one-line messages and exit 2.

    The output is flushed here, so a full disk or a closed stdout is
    reported ("cannot write output: …", exit 2), a reader that left early
    (``| head``) ends quietly with 0, Ctrl-C exits 130 and SIGTERM 143.
    """
    from parsers.sources import InputError

    try:
        code = _run(fn)
        if sys.stdout is not None:
            sys.stdout.flush()
        return code
    except (typer.Exit, typer.Abort):
        raise
    except InputError as exc:
        raise fail(str(exc)) from None
    except KeyboardInterrupt:
        _silence_stdout()
        _exit_within(exit_codes.INTERRUPTED)
        return exit_codes.INTERRUPTED
    except Terminated:
        _silence_stdout()
        _exit_within(exit_codes.TERMINATED)
        return exit_codes.TERMINATED
    except OSError as exc:
        if isinstance(exc, BrokenPipeError) or exc.errno in OUTPUT_ERRNOS or exc.errno == errno.EPIPE:
            return output_failed(exc)
        if os.environ.get("TRACKSIDE_DEBUG"):
            raise
        raise fail(f"internal error: {type(exc).__name__}: {exc} (set TRACKSIDE_DEBUG=1 for details)") from None
    except MemoryError:
        raise fail("out of memory") from None
    except Exception as exc:
        if os.environ.get("TRACKSIDE_DEBUG"):
            raise
        raise fail(f"internal error: {type(exc).__name__}: {exc} (set TRACKSIDE_DEBUG=1 for details)") from None


def _run(fn: Callable[[], int]) -> int:
    """``fn()``, Ctrl-C that a library turned into an error of its own raised as the KeyboardInterrupt it was."""
    try:
        return fn()
    except (typer.Exit, typer.Abort):
        raise
    except Exception as exc:
        if is_ctrl_c(exc):
            raise KeyboardInterrupt from None
        raise


def print_json(doc: dict[str, Any]) -> None:
    from console.jsonout import write

    write(doc, sys.stdout)
    sys.stdout.flush()


def print_document(doc: dict[str, Any], lines: Mapping[str, str] | None) -> None:
    """``doc`` as one JSON document (``--json``), or with ``lines`` (array key → type) as JSON lines (``--jsonl``):
    a line per item of those arrays, then a ``summary`` line with the rest."""
    if lines is None:
        print_json(doc)
        return
    from console.jsonout import write_lines

    write_lines(doc, lines, sys.stdout)
    sys.stdout.flush()


def one_json_form(json_out: bool, jsonl: bool) -> None:
    """--json and --jsonl exclude each other: a one-line error."""
    if json_out and jsonl:
        raise fail("--json and --jsonl: choose one")


# Kinds a command refuses outright: files it could only reject line by line.
_NOT_DIAG_KINDS = frozenset({"nmea", "gpsd", "jsonl", "gpx", "gnss-csv", "centre", "frames", "can", "voltages"})
_NOT_FRAME_KINDS = frozenset({"diag", "nmea", "gpsd", "jsonl", "gpx", "gnss-csv", "centre", "voltages"})
_NOT_VOLTAGE_KINDS = frozenset({"diag", "nmea", "gpsd", "jsonl", "gpx", "gnss-csv", "centre", "frames", "can"})
# What each command reads, as its refusals name it.
READS = {
    "diag": "an axle-counter diagnostic log",
    "gnss": "GNSS",
    "frames": "sensor frames or a CAN log",
    "voltages": "a receiver-voltage table",
}


def refuse_wrong_kind(paths: list[Path], expected: str) -> None:
    """A file that plainly holds something else: one line naming it and what it looks like, exit 2.

    ``expected`` is a key of :data:`READS`.  Damaged files are not refused here: they are read and
    their lines rejected with reasons, as any other input; a file of which nothing at all was read
    is refused after reading (:func:`refuse_unread`).  An empty file is zero records, not an error.
    """
    from parsers.kinds import classify_head, not_gnss_reason, read_head

    for p in paths:
        if expected == "gnss":
            wrong = not_gnss_reason(p)
            if wrong is not None:
                raise fail(f"{show_path(p)}: nothing readable as GNSS: {wrong}")
            continue
        head = read_head(p)
        guess = classify_head(head)
        if expected == "diag":
            if guess.kind in _NOT_DIAG_KINDS:
                raise fail(f"{show_path(p)}: not an axle-counter diagnostic log: looks like {guess.description}")
            if guess.kind == "unknown" and b"Diag_id:" not in head:
                # Not one record in the head (64 KiB): an image, a document, notes.
                what = "binary data" if guess.why == "binary data" else _first_line(head)
                raise fail(f"{show_path(p)}: nothing readable as {READS['diag']}: no Diag_id: record ({what})")
        elif expected in ("frames", "voltages"):
            refused = _NOT_FRAME_KINDS if expected == "frames" else _NOT_VOLTAGE_KINDS
            if guess.kind in refused:
                raise fail(f"{show_path(p)}: nothing readable as {READS[expected]}: looks like {guess.description}")
            if guess.why == "binary data":
                raise fail(f"{show_path(p)}: nothing readable as {READS[expected]}: binary data")


def _first_line(head: bytes) -> str:
    from parsers.report import escape_text

    line = next((s for s in (x.strip() for x in head.split(b"\n")) if s), b"")
    return f"first line '{escape_text(line, 40)}'"


def refuse_unread(reports: Any, expected: str) -> None:
    """Exit 2 with one line for the first file of which no line was read (no record, some rejected).

    ``reports`` is a :class:`~parsers.report.ParseReport` or several; ``expected`` a key of :data:`READS`.
    """
    from console.plural import count

    for report in reports if isinstance(reports, list | tuple) else [reports]:
        for fr in report.files:
            if fr.records or not fr.rejected:
                continue
            first = next((r for r in report.rejections if r.file == fr.file), None)
            example = f"; line {first.line}: {first.reason}" if first is not None else ""
            raise fail(
                f"{show_path(fr.file)}: nothing readable as {READS[expected]}:"
                f" {count(fr.rejected, 'line')} rejected, none read{example}"
            )


def rejected_note(n: int, where: str = "trackside analyze lists them") -> str:
    """The text faces' closing line for rejected input lines (a record a table may lack), and where to see them."""
    from console.plural import count

    return f"{count(n, 'input line')} rejected ({where})"


def status_only_note(n: int) -> str:
    """The text faces' note of the status-only record bursts a passage table does not list."""
    from console.plural import count

    return f"{count(n, 'status-only record burst')} (no wheel onset) not listed; --include-status lists them"


def read_logs(
    files: list[Path],
    settings: Any,
    sink: Any = None,
    *,
    jsonl: Any = None,
    rejected_all: bool = False,
    hold_passages: bool = False,
) -> Any:
    """Read diagnostic logs through the pipeline (:func:`console.drivers.batch.read_diag`), with the
    checks every command makes first and a progress bar; ``jsonl`` (a
    :class:`~console.sinks.tables.diag_stream.JsonLinesOut`) also gets the rejected lines as they are met."""
    from console.drivers.batch import ReadOptions, input_bytes, read_diag
    from console.engine.sinks import Sinks
    from console.memory import heap_kept_for_reuse
    from console.progress import byte_progress

    check_inputs(files)
    refuse_wrong_kind(files, "diag")
    heap_kept_for_reuse()
    with byte_progress(input_bytes(files), "parsing") as advance:
        opts = ReadOptions(
            on_progress=advance,
            on_records=advance.records if advance is not None else None,
            max_rejections_kept=sys.maxsize if rejected_all else REJECTIONS_LISTED,
            on_reject=jsonl.rejected if jsonl is not None else None,
            passages_final=jsonl is not None,
            hold_passages=hold_passages,
        )
        job = read_diag(files, settings, Sinks(jsonl, sink), opts)
    refuse_unread(job.report, "diag")
    return job


def load_layout(spec: str, *, warn: bool = True, said_here: tuple[str, ...] = ()) -> Any:
    """The layout, or a one-line error (exit 2). With ``warn``, what `trackside layout` would warn of is named
    on stderr in one line: a section with its signs swapped shows disturbed in every command that reads it
    (but the checks in ``said_here``, which the command words itself)."""
    from console.layout import LayoutError, load_layout

    try:
        lay = load_layout(spec)
    except LayoutError as exc:
        raise fail(str(exc)) from None
    if warn:
        from console.analysis.layout_checks import WARNING, check_layout
        from console.plural import count

        warned = [f for f in check_layout(lay) if f.level == WARNING and f.check not in said_here]
        if warned:
            named = ", ".join(f"{f.check} {clean(f.subject)}" for f in warned[:4]) + (", …" if len(warned) > 4 else "")
            sys.stderr.write(
                f"trackside: warning: {clean(lay.source)}: {count(len(warned), 'layout warning')} ({named}); "
                f"`trackside layout {clean(spec)}` explains them\n"
            )
    return lay


# Every number option of every command, checked once here: Click's FloatRange lets nan through, and inf or
# 1e308 pass an open bound, then overflow a time in nanoseconds deep in a command (an internal error).  No
# option means anything beyond 1e9 (31 years in seconds, a million km in metres).
MAX_OPTION_NUMBER = 1e9


def finite_numbers(command: Callable[..., Any]) -> Callable[..., Any]:
    """``command`` refusing a number option that is not finite or beyond :data:`MAX_OPTION_NUMBER`: one line
    naming the option, exit 2, before any work."""

    @functools.wraps(command)
    def checked(*args: Any, **kwargs: Any) -> Any:
        for key, value in kwargs.items():
            for v in value if isinstance(value, list | tuple) else (value,):
                if isinstance(v, float) and not (math.isfinite(v) and abs(v) <= MAX_OPTION_NUMBER):
                    # The option's name only now: reading every signature would cost each start-up.
                    name = _option_names(command).get(key, key)
                    raise fail(f"{name}: expected a finite number of at most {MAX_OPTION_NUMBER:g}, got {v!r}")
        return command(*args, **kwargs)

    return checked


def _option_names(command: Callable[..., Any]) -> dict[str, str]:
    """Parameter name → its longest option name (``idle_gap`` → ``--idle-gap``)."""
    out: dict[str, str] = {}
    for name, param in inspect.signature(command, eval_str=True).parameters.items():
        for meta in getattr(param.annotation, "__metadata__", ()):
            # Inside Annotated, typer.Option("--idle-gap", ...) keeps its first name where a default would go.
            given = (getattr(meta, "default", None), *(getattr(meta, "param_decls", ()) or ()))
            decls = [d for d in given if isinstance(d, str) and d.startswith("--")]
            if decls:
                out[name] = max(decls, key=len)
    return out
