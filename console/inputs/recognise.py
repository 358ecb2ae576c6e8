"""What an input is: expand directories, and recognise each file for the commands that read many kinds.

Recognition is by content, by the one recogniser of file kinds
(:func:`parsers.kinds.classify_head`), with what only a report or an ingest
reads or refuses first: layouts (``*.toml``), the simulator's truth, and
trackside's own reports.  No pandas, no analysis: ``ingest`` lists and
recognises its inputs with this alone (on Dask, in the workers' prescan).
"""

from __future__ import annotations

import errno
import os
import re
import stat
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from console.output_path import file_identity
from console.safe_text import show_path
from parsers.kinds import classify_head, read_head
from parsers.report import escape_text

# Input formats, as the input summary names them.
DIAGNOSTIC = "diagnostic"
NMEA = "nmea"
GNSS_CSV = "gnss-csv"
GNSS_JSONL = "gnss-jsonl"
CENTRE = "centre"
GPX = "gpx"
FRAMES = "frames"
CAN = "can"
VOLTAGES = "voltages"
LAYOUT = "layout"
TRUTH = "truth"
EMPTY = "empty"
UNKNOWN = "unknown"
GNSS_FORMATS = (NMEA, GNSS_CSV, GNSS_JSONL, CENTRE, GPX)

NUMBER_PARTS = re.compile(r"(\d+)")  # the runs of digits natural order reads as numbers


def natural_key(text: str) -> tuple[Any, ...]:
    """``WS10`` after ``WS9``, train ``T10`` after ``T2``."""
    return tuple(int(p) if i % 2 else p.casefold() for i, p in enumerate(NUMBER_PARTS.split(text)))


STDIN_NAME = "-"  # an input that means standard input


class ReportInputError(Exception):
    """An input, layout or option the report cannot use: one line for the user, exit 2."""


# The one recogniser's kinds (parsers.kinds) → the report's input formats.
_FORMATS = {
    "diag": DIAGNOSTIC,
    "can": CAN,
    "frames": FRAMES,
    "voltages": VOLTAGES,
    "nmea": NMEA,
    "gpsd": NMEA,  # gpsd JSON is read by the stream parser, beside any NMEA in the file
    "gnss-csv": GNSS_CSV,
    "jsonl": GNSS_JSONL,
    "centre": CENTRE,
    "gpx": GPX,
}


def recognise(path: Path) -> tuple[str, str]:
    """(format, note) of one file; InputError when it cannot be opened at all.

    What the file is comes from the one recogniser (:func:`parsers.kinds.classify_head`); the report
    adds what only it reads or refuses: layouts, the simulator's truth and its own reports.
    """
    if is_layout_file(path):
        return LAYOUT, ""
    head = read_head(path)
    if path.name == "truth.json" or b'"schema": "trackside.truth/' in head:
        return TRUTH, "the simulator's ground truth: not read, the report shows what the logs say"
    if head.startswith(b"# trackside report") or b'"schema": "trackside.report/' in head[:200]:
        return UNKNOWN, "not read: a trackside report"
    if head.lstrip().startswith(b"<!DOCTYPE html>") and b"trackside report" in head:
        return UNKNOWN, "not read: a trackside report"
    guess = classify_head(head)
    if guess.kind in _FORMATS:
        return _FORMATS[guess.kind], ""
    if guess.kind == "empty":
        return EMPTY, "empty: no line to read"
    if b"\0" in head[:4096]:
        return UNKNOWN, "not read: binary data in no format trackside reads"
    first = next(line.strip() for line in head.split(b"\n") if line.strip() and not line.strip().startswith(b"#"))
    text = first.decode("utf-8", errors="replace")
    return UNKNOWN, f"not read: unrecognised format, first line '{escape_text(text, 60)}'"


def _special_kind(mode: int) -> str:
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return "not a regular file"


def _entry_problem(p: Path) -> str | None:
    """Why a directory entry is skipped (a dangling link, a loop, a FIFO…), or None for a regular file."""
    try:
        st = os.stat(p)
    except FileNotFoundError:
        return "a symlink to nothing" if os.path.islink(p) else "vanished while the directory was read"
    except OSError as exc:
        return "a symlink loop" if exc.errno == errno.ELOOP else f"cannot be opened ({exc.strerror or exc})"
    if stat.S_ISREG(st.st_mode):
        return None
    # A FIFO would block the report until some writer appears: never opened from a directory.
    return f"{_special_kind(st.st_mode)}, not a regular file"


def _given_problem(p: Path) -> str | None:
    """Why an input named on the command line cannot be read, or None (files, ``-``, FIFOs, /dev/stdin)."""
    if os.fsdecode(p) == STDIN_NAME:
        return None
    try:
        st = os.stat(p)
    except FileNotFoundError:
        return "a symlink to nothing" if os.path.islink(p) else "no such file or directory"
    except OSError as exc:
        return "symlink loop" if exc.errno == errno.ELOOP else f"cannot be opened ({exc.strerror or exc})"
    if stat.S_ISSOCK(st.st_mode):
        return "a socket, not a file to read"
    return None


def expand(inputs: Sequence[Path], exclude: Path | None = None) -> tuple[list[Path], list[str]]:
    """Input files in order (a directory's files sorted, recursively), and warnings about what was skipped.

    ``exclude`` is the report being written: inside an input directory it is
    not read back when it is no log (a previous report); when it is a log
    the report would replace, or it is named as an input, the report is
    refused (:class:`ReportInputError`).  Named inputs may be ``-``, FIFOs
    and ``/dev/stdin`` (read as streams); inside a directory only regular
    files are read, and every other entry is skipped with its reason.
    """
    files: list[Path] = []
    warnings: list[str] = []
    skip = file_identity(exclude) if exclude is not None else None
    seen: set[object] = set()

    def add(p: Path) -> None:
        if os.fsdecode(p) != STDIN_NAME and not os.access(p, os.R_OK):
            raise ReportInputError(f"{show_path(p)}: permission denied")
        key = file_identity(p) or os.fsdecode(p)
        if key in seen:
            warnings.append(f"{show_path(p)}: given twice, read once")
            return
        seen.add(key)
        files.append(p)

    for given in inputs:
        problem = _given_problem(given)
        if problem is not None:
            raise ReportInputError(f"{show_path(given)}: {problem}")
        if not given.is_dir():
            if skip is not None and file_identity(given) == skip:
                raise ReportInputError(f"{show_path(given)}: is an input; refusing to write the report over it")
            add(given)
            continue
        hidden = 0
        found: list[Path] = []
        for root, dirs, names in os.walk(given):
            hidden += sum(1 for d in dirs if d.startswith(".")) + sum(1 for n in names if n.startswith("."))
            for d in dirs:
                if not d.startswith(".") and os.path.islink(os.path.join(root, d)):
                    warnings.append(f"{show_path(Path(root) / d)}: a symlink to a directory, not followed")
            dirs[:] = sorted(d for d in dirs if not d.startswith("."))
            found += [Path(root) / n for n in names if not n.startswith(".")]
        # Natural order (T2 before T10), by relative path: the same tree always reads the same way.
        for p in sorted(found, key=lambda q: natural_key(os.fsdecode(q.relative_to(given).as_posix()))):
            problem = _entry_problem(p)
            if problem is not None:
                warnings.append(f"{show_path(p)}: {problem}: skipped")
                continue
            if skip is not None and file_identity(p) == skip:
                if recognise(p)[0] in (UNKNOWN, EMPTY):
                    continue  # the previous report, written into the directory it reads
                raise ReportInputError(
                    f"{show_path(p)}: is an input (a log in {show_path(given)}); refusing to write the report over it"
                )
            add(p)
        if hidden:
            warnings.append(f"{show_path(given)}: {hidden} hidden entries (names starting with '.') not read")
    return files, warnings


def is_layout_file(path: Path) -> bool:
    return path.suffix.lower() == ".toml"


def chosen_layout_file(files: Sequence[Path], layout_spec: str | None) -> Path | None:
    """The layout file among the inputs that a run over them uses: none when ``--layout`` is given, else the first.

    The one rule for ``report`` and ``ingest`` (a ``trackside simulate`` output carries its ``layout.toml``).
    """
    if layout_spec is not None:
        return None
    return next((p for p in files if is_layout_file(p)), None)


def layout_note(path: Path, chosen: Path | None, layout_spec: str | None) -> str:
    """What became of one layout file among the inputs (the inputs table, ingest's summary)."""
    if path == chosen:
        return "the layout used"
    if layout_spec is not None:
        return "not used: --layout given"
    return f"not used: the layout {show_path(chosen) if chosen is not None else '?'} is used"
