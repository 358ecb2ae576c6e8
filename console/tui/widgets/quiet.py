"""Widget updates that repaint only on change.

Textual repaints a widget on every assignment of ``border_title`` or
``border_subtitle`` and on every ``Static.update``, even with the value it
already shows.  The view is redrawn on every piece of live data, so an
unchanged panel must not cost a repaint (a repaint of the speed plot alone
takes tens of milliseconds on a loaded machine).
"""

from __future__ import annotations

from typing import Any

from rich.text import Text
from textual.widget import Widget
from textual.widgets import Static

_UNSET: Any = object()


def same(a: object, b: object) -> bool:
    """Equal as shown: rich's ``Text ==`` compares the characters and spans, not the base style."""
    if isinstance(a, Text) and isinstance(b, Text):
        return a.plain == b.plain and a.style == b.style and a.spans == b.spans
    return type(a) is type(b) and a == b


def retitle(widget: Widget, *, title: str | Text | None = _UNSET, subtitle: str | Text | None = _UNSET) -> None:
    """Set the border title and subtitle, each only when it differs from what was set last."""
    last: dict[str, object] = widget.__dict__.setdefault("_quiet_titles", {})
    for name, value in (("border_title", title), ("border_subtitle", subtitle)):
        if value is not _UNSET and not same(last.get(name, _UNSET), value):
            setattr(widget, name, value)
            last[name] = value.copy() if isinstance(value, Text) else value


def update_if_changed(widget: Static, content: Text | str) -> bool:
    """``Static.update`` (no new layout) only when the content differs from the last; True if updated."""
    last = widget.__dict__.get("_quiet_content", _UNSET)
    if same(last, content):
        return False
    widget.update(content, layout=False)
    widget.__dict__["_quiet_content"] = content.copy() if isinstance(content, Text) else content
    return True
