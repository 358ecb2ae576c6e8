"""Log content is data: make any string from a log inert before rendering.

Rich would read ``[bold]`` as markup and a terminal would obey ESC
sequences; log text goes through :func:`inert` into a :class:`rich.text.Text`
(never parsed as markup) with control characters shown as ``\\xNN``.

Bidirectional formatting characters (embeddings, overrides, isolates and
the directional marks) and invisible ones (zero-width space, joiners, BOM,
tags) are shown as ``\\u202e`` too: left as they are, a
device name or a rejected line could display reversed and spoof the
columns beside it.  A file name that is not valid UTF-8 reaches Python
with its bad bytes as lone surrogates (``os.fsdecode``'s surrogateescape);
they are shown as the bytes they stand for, ``\\xff``, as ``ls`` does, so
printing never fails on them.
"""

from __future__ import annotations

import os
import re
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rich.text import Text

# C0, DEL, C1, line/paragraph separators; bidi marks, embeddings, overrides
# and isolates (U+061C, U+200E-200F, U+202A-202E, U+2066-2069); surrogates;
# and the invisible ones (zero-width space and joiners U+200B-200D, U+180E,
# word joiner and invisible operators U+2060-2064, U+206A-206F, BOM U+FEFF,
# tags U+E0000-E007F): "WS1\u200b" must not show as a second "WS1".
_CONTROL = re.compile(
    r"[\x00-\x1f\x7f-\x9f\u061c\u180e\u200b-\u200f\u2028-\u202e\u2060-\u206f\ufeff\ud800-\udfff\U000e0000-\U000e007f]"
)


def _escape(match: re.Match[str]) -> str:
    code = ord(match.group())
    if code < 0x100:
        return f"\\x{code:02x}"
    if 0xDC80 <= code <= 0xDCFF:
        return f"\\x{code - 0xDC00:02x}"  # a byte of a name that is not UTF-8
    return f"\\u{code:04x}" if code <= 0xFFFF else f"\\U{code:08x}"


# Text that no escaper changes (Markdown, HTML, terminal): letters, digits and a few signs, no control
# character.  Most cells of a report's long tables are like this (times, speeds, head names).
PLAIN = re.compile(r"[A-Za-z0-9 .:,/%()+=-]*")


def clean(value: object) -> str:
    """The string with control, bidi and undecodable characters escaped (``\\x1b``, ``\\u202e``, ``\\xff``)."""
    text = "" if value is None else os.fsdecode(value) if isinstance(value, bytes) else str(value)
    return _CONTROL.sub(_escape, text)


def show_path(path: str | os.PathLike[str] | os.PathLike[bytes] | bytes) -> str:
    """A file name as the user may see it: escaped like log text (``-`` stays ``-``, standard input)."""
    return clean(os.fsdecode(path))


def inert(value: object, style: str = "") -> Text:
    """A Rich Text that shows value literally: no markup, no escapes."""
    from rich.text import Text  # here: most of what imports this module never draws with Rich

    return Text(clean(value), style=style)


def one_line(exc: BaseException) -> str:
    """An exception's message on one line (a library's may span several), else its type's name."""
    text = " ".join(str(exc).split())
    return text or type(exc).__name__
