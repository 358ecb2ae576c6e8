"""`trackside report`: one call that reads the inputs, renders a format, and writes it atomically.

:func:`run_report` raises only when stdout fails: it returns the exit code (0 ok, 1 a
finding reached ``--fail-on``, 2 an error) and writes errors as one line
on stderr, ``trackside: error: …`` (a failed write to standard output is
raised, for the command's guard).  Without ``-o`` the report itself is
the only thing on stdout; with ``-o`` nothing is printed at all.  Progress
goes to stderr only on a terminal, for big inputs.

The report is written as it is rendered, a megabyte at a time: with ``-o``
into a temporary file that replaces the target only once it is whole
(:func:`console.output_path.open_output`).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path

from console import exit_codes
from console.analysis.health.findings import Severity
from console.interrupt import is_ctrl_c
from console.layout import LayoutError
from console.output_path import STDOUT, OutputError, OutputTarget, check_output_file, open_output
from console.safe_text import clean, show_path
from console.sinks.report.collect import ReportInputError, collect
from console.sinks.report.document import document
from console.sinks.report.jsonwrite import Write, write_json
from console.sinks.report.model import ReportData
from parsers.sources import InputError

FORMATS = ("md", "html", "json")
CHUNK_CHARS = 1 << 20  # written out at a time


def _error(message: str) -> int:
    sys.stderr.write(f"trackside: error: {clean(message)}\n")
    sys.stderr.flush()
    return exit_codes.USAGE


class _WriteFailed(Exception):
    """Writing the report out failed (``error``): told apart from a failure to render it."""

    def __init__(self, error: OSError) -> None:
        super().__init__(str(error))
        self.error = error


class _Pieces:
    """Text written in pieces, handed on (``put``) a megabyte at a time."""

    def __init__(self, put: Callable[[str], object]) -> None:
        self._put = put
        self._parts: list[str] = []
        self._size = 0

    def write(self, text: str) -> None:
        self._parts.append(text)
        self._size += len(text)
        if self._size >= CHUNK_CHARS:
            self.flush()

    def flush(self) -> None:
        text = "".join(self._parts)
        self._parts, self._size = [], 0
        try:
            self._put(text)
        except OSError as exc:
            raise _WriteFailed(exc) from exc


def render_to(data: ReportData, fmt: str, write: Write) -> None:
    """The report in one format (md, html or json), handed to ``write`` piece by piece."""
    doc = document(data)
    # Each renderer imported when its format is asked for (the HTML one brings the plots).
    if fmt == "json":
        write_json(doc, write)
    elif fmt == "md":
        from console.sinks.report.markdown import render_markdown

        render_markdown(doc, write)
    else:
        from console.sinks.report.html import render_html

        render_html(data, doc, write)


def render(data: ReportData, fmt: str) -> str:
    """The report in one format (md, html or json), as one string."""
    parts: list[str] = []
    render_to(data, fmt, parts.append)
    return "".join(parts)


def _write(data: ReportData, fmt: str, target: OutputTarget | None) -> None:
    """Render into the target (stdout when None); _WriteFailed when writing fails."""
    if target is not None:
        with open_output(target) as f:
            out = _Pieces(lambda text: f.write(text.encode("utf-8")))
            render_to(data, fmt, out.write)
            out.flush()
        return
    buf = getattr(sys.stdout, "buffer", None)
    out = _Pieces((lambda text: buf.write(text.encode("utf-8"))) if buf is not None else sys.stdout.write)
    render_to(data, fmt, out.write)
    out.flush()
    try:
        sys.stdout.flush()
    except OSError as exc:
        raise _WriteFailed(exc) from exc


def exit_code(data: ReportData, threshold: Severity | None) -> int:
    """1 when a health finding or a safety item (unsafe = critical, failing = warning) reaches the threshold."""
    if threshold is None:
        return exit_codes.OK
    worst = data.worst()
    return exit_codes.FINDINGS if worst is not None and worst >= threshold else exit_codes.OK


def run_report(
    inputs: list[Path],
    layout: str | None,
    fmt: str,
    output: Path | None,
    fail_on: str | None,
    collector: Callable[[], ReportData] | None = None,
) -> int:
    """Read ``inputs`` (files or directories), write the report to ``output`` (or stdout); the exit code.

    ``output`` is checked before any work (:func:`console.output_path.check_output_file`):
    never an input, a device or FIFO written through, a directory refused.
    A failed write to standard output raises :class:`OSError` for the
    command's guard to report (``cannot write output``, or quiet for ``| head``).
    """
    if fmt not in FORMATS:
        return _error(f"--format: expected md, html or json, found {fmt!r}")
    threshold = None
    if fail_on is not None:
        try:
            threshold = Severity.parse(fail_on)
        except ValueError as exc:
            return _error(f"--fail-on: {exc}")
    if not inputs and collector is None:
        return _error("give input files or directories (a `trackside simulate` directory, logs, tables)")
    if output is not None and os.fsdecode(output) == STDOUT:
        output = None
    target = None
    data: ReportData | None = None
    try:
        if output is not None:
            target = check_output_file(output, inputs, what="report")
        # The archive's faces (report --archive) bring their own collector; files keep what this format shows.
        data = collector() if collector is not None else collect(inputs, layout, exclude=output, for_format=fmt)
        if output is not None:
            # Again against every file read (those found in directories too).
            target = check_output_file(output, [Path(i.path) for i in data.inputs], what="report")
        code = exit_code(data, threshold)
        _write(data, fmt, target)
        if target is not None and not target.stream:
            _say_where(target.path)
    except (ReportInputError, InputError, LayoutError, OutputError) as exc:
        return _error(str(exc))
    except _WriteFailed as exc:
        if target is None:
            raise exc.error from None  # the command's guard: "cannot write output", or quiet for `| head`
        return _cannot_write(output or target.path, exc.error)
    except OSError as exc:
        if data is not None and target is not None:
            return _cannot_write(output or target.path, exc)  # the temporary file's flush, fsync or rename
        if data is not None:
            raise  # standard output: the command's guard
        return _internal(exc)
    except MemoryError:
        return _error("out of memory")
    except Exception as exc:
        return _internal(exc)
    finally:
        if data is not None:
            data.close()
    return code


def _say_where(path: Path) -> None:
    """Tell a person where the report went (nothing else is printed); scripts and cron, not on a terminal, get
    nothing on stderr."""
    stderr = sys.stderr
    try:
        if stderr is None or not stderr.isatty():
            return
        size = os.stat(path).st_size
        stderr.write(f"trackside: wrote {show_path(path)} ({size:,} bytes)\n")
        stderr.flush()
    except (OSError, ValueError):
        return  # a closed or broken terminal: the report is written, which is what matters


def _internal(exc: Exception) -> int:
    if is_ctrl_c(exc):
        raise KeyboardInterrupt from None  # Ctrl-C, as DuckDB reports it: the command's guard ends with 130
    if os.environ.get("TRACKSIDE_DEBUG"):
        raise exc
    return _error(f"internal error: {type(exc).__name__}: {exc} (set TRACKSIDE_DEBUG=1 for details)")


def _cannot_write(path: Path, exc: OSError) -> int:
    return _error(f"{show_path(path)}: cannot write the report ({exc.strerror or exc})")
