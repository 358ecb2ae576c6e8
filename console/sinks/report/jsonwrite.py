"""The report's JSON written piece by piece, byte for byte what one ``json.dumps`` of the whole document gives.

The whole-document form is ``json.dumps(doc, ensure_ascii=True, indent=1,
allow_nan=False)`` with lone surrogates made visible (:func:`console.jsonout.valid_unicode`).
With ``indent=1`` a value nested ``depth`` levels deep is its own
``indent=1`` text with every line after the first indented ``depth`` more
spaces: so each part is encoded alone (:func:`indented`) and a long list
(:class:`Rows`: passages, the section timeline, the count ledger) is written
an item at a time, or copied from the spill its rows were written to in this
very form (:mod:`console.sinks.report.spooled`).

:func:`indented` runs json's C encoder on flat objects and arrays (an
``indent`` makes ``json.dumps`` fall back to its pure-Python encoder): the
separators carry the newline and indent.  ``tests/test_report_stream.py``
holds it equal to ``json.dumps`` on random values.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from typing import Any

from console.jsonout import valid_unicode

Write = Callable[[str], None]

_CONTAINERS = (dict, list, tuple)
_FLAT: dict[int, json.JSONEncoder] = {}


def _flat_encoder(depth: int) -> json.JSONEncoder:
    """Members of a flat container at ``depth``: separated by a comma, a newline and the members' indent."""
    enc = _FLAT.get(depth)
    if enc is None:
        sep = ",\n" + " " * (depth + 1)
        enc = _FLAT[depth] = json.JSONEncoder(ensure_ascii=True, allow_nan=False, separators=(sep, ": "))
    return enc


def _nested(v: Any) -> bool:
    return isinstance(v, _CONTAINERS) and bool(v)


def indented(value: Any, depth: int = 0) -> str:
    """``json.dumps(value, ensure_ascii=True, indent=1, allow_nan=False)`` as it reads ``depth`` levels deep.

    Lone surrogates are left as ``\\udcff`` escapes, as ``json.dumps`` leaves them.
    """
    if not _nested(value):
        return json.dumps(value, ensure_ascii=True, allow_nan=False)
    inner, outer = "\n" + " " * (depth + 1), "\n" + " " * depth
    if isinstance(value, dict):
        if not all(isinstance(k, str) for k in value):
            return json.dumps(value, ensure_ascii=True, indent=1, allow_nan=False).replace("\n", outer)
        parts: list[str] = []
        run: dict[str, Any] = {}
        for k, v in value.items():
            if _nested(v):
                if run:
                    parts.append(_flat_encoder(depth).encode(run)[1:-1])
                    run = {}
                parts.append(json.dumps(k, ensure_ascii=True) + ": " + indented(v, depth + 1))
            else:
                run[k] = v
        if run:
            parts.append(_flat_encoder(depth).encode(run)[1:-1])
        return "{" + inner + ("," + inner).join(parts) + outer + "}"
    if any(_nested(v) for v in value):
        return "[" + inner + ("," + inner).join(indented(v, depth + 1) for v in value) + outer + "]"
    return "[" + inner + _flat_encoder(depth).encode(list(value))[1:-1] + outer + "]"


class Rows:
    """A long list of the document that is not held: its length, and its items made one at a time.

    ``make`` gives the items (JSON values, in order) each time it is called.
    Subclasses may write their JSON faster (copied from a spill file).
    """

    def __init__(self, count: int, make: Callable[[], Iterator[Any]]) -> None:
        self.count = count
        self._make = make

    def __len__(self) -> int:
        return self.count

    def __iter__(self) -> Iterator[Any]:
        return self._make()

    def write_json(self, write: Write, depth: int) -> None:
        """The list as ``json.dumps(indent=1)`` writes it ``depth`` levels deep."""
        if not self.count:
            write("[]")
            return
        inner = "\n" + " " * (depth + 1)
        first = True
        for item in self:
            write(("[" if first else ",") + inner + valid_unicode(indented(item, depth + 1)))
            first = False
        write("\n" + " " * depth + "]")


def _holds_rows(value: Any) -> bool:
    return isinstance(value, dict) and any(isinstance(v, Rows) or _holds_rows(v) for v in value.values())


def _write_value(value: Any, write: Write, depth: int) -> None:
    if isinstance(value, Rows):
        value.write_json(write, depth)
    elif _holds_rows(value):
        inner = "\n" + " " * (depth + 1)
        for i, (k, v) in enumerate(value.items()):
            write(("{" if i == 0 else ",") + inner + valid_unicode(json.dumps(k, ensure_ascii=True)) + ": ")
            _write_value(v, write, depth + 1)
        write("\n" + " " * depth + "}")
    else:
        write(valid_unicode(indented(value, depth)))


def write_json(doc: dict[str, Any], write: Write) -> None:
    """The document as ``json_text`` gives it (:func:`console.sinks.report.document.json_text`), piece by piece."""
    _write_value(doc, write, 0)
    write("\n")
