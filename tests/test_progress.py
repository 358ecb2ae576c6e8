"""The progress bar: on a terminal for big inputs, silent otherwise."""

from __future__ import annotations

import io

from rich.console import Console

from console.progress import MIN_BYTES_FOR_PROGRESS, byte_progress


def test_bar_on_a_terminal_for_big_inputs() -> None:
    buf = io.StringIO()
    term = Console(file=buf, force_terminal=True, width=80)
    with byte_progress(MIN_BYTES_FOR_PROGRESS * 2, "parsing", console=term) as advance:
        assert advance is not None
        advance(MIN_BYTES_FOR_PROGRESS)
    assert "parsing" in buf.getvalue()


def test_silent_when_not_a_terminal() -> None:
    buf = io.StringIO()
    with byte_progress(MIN_BYTES_FOR_PROGRESS * 2, "parsing", console=Console(file=buf)) as advance:
        assert advance is None
    assert buf.getvalue() == ""


def test_silent_for_small_inputs() -> None:
    term = Console(file=io.StringIO(), force_terminal=True)
    with byte_progress(1000, "parsing", console=term) as advance:
        assert advance is None
