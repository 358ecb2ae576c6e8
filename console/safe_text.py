"""Log content is data: make any string from a log inert before rendering.

Rich would read ``[bold]`` as markup and a terminal would obey ESC
sequences; log text goes through :func:`inert` into a :class:`rich.text.Text`
(never parsed as markup) with control characters shown as ``\\xNN``.
"""

from __future__ import annotations

import re

from rich.text import Text

_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]")


def clean(value: object) -> str:
    """The string with control characters escaped as \\xNN."""
    text = "" if value is None else str(value)
    return _CONTROL.sub(lambda m: f"\\x{ord(m.group()):02x}", text)


def inert(value: object, style: str = "") -> Text:
    """A Rich Text that shows value literally: no markup, no escapes."""
    return Text(clean(value), style=style)
