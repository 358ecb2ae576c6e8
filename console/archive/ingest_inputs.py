"""An ingest's inputs: the files to read and the names they are known by, and the layout the derivation uses."""

from __future__ import annotations

import shutil
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from console.archive.store import TMP, ArchiveError

STDIN_NAME = "<stdin>"


def expand_inputs(paths: Sequence[Path], root: Path, warnings: list[str] | None = None) -> list[tuple[Path, str]]:
    """(file to read, name it is known by): directories read whole (the report's order), ``-`` is stdin.

    ``warnings`` gets what the inputs hold but is not read, and why (the report's words)."""
    from console.inputs.recognise import ReportInputError, expand

    out: list[tuple[Path, str]] = []
    files: list[Path] = []
    said = warnings if warnings is not None else []

    def expanded(given: list[Path]) -> list[tuple[Path, str]]:
        found, notes = expand(given, exclude=None)
        said.extend(notes)
        return [(f, str(f.resolve())) for f in found]

    if sum(str(p) == "-" for p in paths) > 1:
        raise ArchiveError("-: standard input given twice")  # as every other command says
    for p in paths:
        if str(p) == "-":
            if files:
                out += expanded(files)
                files = []
            tmp = root / TMP / f"stdin-{time.time_ns()}"
            with tmp.open("wb") as dst:
                shutil.copyfileobj(sys.stdin.buffer, dst)
            out.append((tmp, STDIN_NAME))
        else:
            files.append(p)
    try:
        if files:
            out += expanded(files)
    except ReportInputError as exc:
        raise ArchiveError(str(exc)) from None
    return out


def chosen_layout(inputs: list[tuple[Path, str]], layout: str | None) -> tuple[Path | None, str | None]:
    """(the layout file among the inputs, by ``report``'s rule, or None; the layout the derivation uses:
    ``--layout``, else that file)."""
    from console.inputs.recognise import chosen_layout_file
    from console.layout import LayoutError, load_layout

    layout_file = chosen_layout_file([p for p, _ in inputs], layout)
    if layout_file is None:
        return None, layout
    try:
        load_layout(layout_file)  # a bad layout fails before anything is read
    except LayoutError as exc:
        raise ArchiveError(str(exc)) from None
    return layout_file, str(layout_file.resolve())
