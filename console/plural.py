"""Counts in messages: "1 record", "2 records", "1,204 fixes".

Every message that counts things goes through :func:`count`, so a single
finding is never "1 findings".
"""

from __future__ import annotations

_IRREGULAR = {"fix": "fixes"}


def plural(n: int | float, noun: str, nouns: str | None = None) -> str:
    """``noun`` or its plural (``nouns``, else an -s, or -es after x/s/ch/sh) as ``n`` asks."""
    if n == 1:
        return noun
    if nouns is not None:
        return nouns
    if noun in _IRREGULAR:
        return _IRREGULAR[noun]
    if noun.endswith(("s", "x", "ch", "sh")):
        return noun + "es"
    return noun + "s"


def count(n: int | float, noun: str, nouns: str | None = None, *, sep: bool = False) -> str:
    """``"1 record"``, ``"3 records"``; with ``sep``, thousands separated: ``"1,204 records"``."""
    shown = f"{n:,}" if sep else f"{n}"
    return f"{shown} {plural(n, noun, nouns)}"
