"""Which CAN log a file is: candump, ASC, BLF or TRC, by its content or its name."""

from __future__ import annotations

import zlib
from pathlib import Path

from parsers.frames.can_head import can_format_of_head
from parsers.frames.trc import check_trc_header
from parsers.sources import InputError, open_input

_FORMATS = {".log": "candump", ".asc": "asc", ".blf": "blf", ".trc": "trc"}
_FORMAT_HEAD_BYTES = 64 * 1024  # a long run of comments or an ASC header before the first frame


def can_log_format(path: Path) -> str | None:
    """'candump', 'asc', 'blf' or 'trc' by name (``.gz`` aside; BLF also by its signature), else None."""
    suffixes = [s.lower() for s in path.suffixes]
    if suffixes and suffixes[-1] == ".gz":
        suffixes.pop()
    return _FORMATS.get(suffixes[-1] if suffixes else "")


def can_format(path: Path) -> str:
    """The file's format by its content (a candump saved as ``.txt``, an ASC export as ``.log``); by its name
    only when the content is no CAN log at all (an empty file)."""
    stream, raw, _ = open_input(path)
    try:
        head = stream.read(_FORMAT_HEAD_BYTES)
    except (OSError, EOFError, zlib.error) as exc:
        raise InputError(f"{path}: cannot read ({exc})") from None
    finally:
        stream.close()
        raw.close()
    by_content = can_format_of_head(head)
    if by_content is not None:
        if by_content == "trc":
            check_trc_header(path)
        return by_content
    fmt = can_log_format(path)
    if fmt is None:
        suffix = path.suffix.lower()
        raise InputError(
            f"{path}: unknown CAN log format '{suffix}': expected .log (candump), .asc, .blf or .trc (optionally .gz)"
        )
    if fmt == "blf":
        raise InputError(f"{path}: not a BLF file (no 'LOGG' signature)")
    if fmt == "trc":
        check_trc_header(path)
    return fmt
