"""`trackside report`: one call that reads the inputs, renders a format, and writes it atomically.

:func:`run_report` raises only when stdout fails: it returns the exit code (0 ok, 1 a
finding reached ``--fail-on``, 2 an error) and writes errors as one line
on stderr, ``trackside: error: …`` (a failed write to standard output is
raised, for the command's guard).  Without ``-o`` the report itself is
the only thing on stdout; with ``-o`` nothing is printed at all.  Progress
goes to stderr only on a terminal, for big inputs.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path

from console import exit_codes
from console.analysis.health import Severity
from console.jsonout import valid_unicode
from console.layout import LayoutError
from console.output_path import STDOUT, OutputError, check_output_file, write_output
from console.report.collect import ReportInputError, collect
from console.report.html import render_html
from console.report.markdown import render_markdown
from console.report.model import ReportData, document, json_text
from console.safe_text import clean, show_path
from parsers.sources import InputError

FORMATS = ("md", "html", "json")


def _error(message: str) -> int:
    sys.stderr.write(f"trackside: error: {clean(message)}\n")
    sys.stderr.flush()
    return exit_codes.USAGE


def render(data: ReportData, fmt: str) -> str:
    """The report in one format (md, html or json)."""
    doc = document(data)
    if fmt == "json":
        return valid_unicode(json_text(doc))
    if fmt == "md":
        return render_markdown(doc)
    return render_html(data, doc)


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
    try:
        if output is not None:
            target = check_output_file(output, inputs, what="report")
        # The archive's faces (report --archive) bring their own collector.
        data = collector() if collector is not None else collect(inputs, layout, exclude=output)
        if output is not None:
            # Again against every file read (those found in directories too).
            target = check_output_file(output, [Path(i.path) for i in data.inputs], what="report")
        text = render(data, fmt)
    except (ReportInputError, InputError, LayoutError, OutputError) as exc:
        return _error(str(exc))
    except MemoryError:
        return _error("out of memory")
    except Exception as exc:
        if os.environ.get("TRACKSIDE_DEBUG"):
            raise
        return _error(f"internal error: {type(exc).__name__}: {exc} (set TRACKSIDE_DEBUG=1 for details)")
    payload = text.encode("utf-8")
    if target is None:
        if hasattr(sys.stdout, "buffer"):
            sys.stdout.buffer.write(payload)
        else:
            sys.stdout.write(text)
        sys.stdout.flush()
    else:
        try:
            write_output(target, payload)
        except OSError as exc:
            return _error(f"{show_path(output or target.path)}: cannot write the report ({exc.strerror or exc})")
    return exit_code(data, threshold)
