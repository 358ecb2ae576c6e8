"""Register labels: every spelling of a label → one canonical name.

Frauscher-style exports cut the German register names to ten characters
(``Summenzä`` for *Summenzähler*, ``Gerätestan`` for *Gerätestand*), write
them in UTF-8 or Latin-1/CP1252, and sometimes arrive already mangled by a
wrong decode (``ZÃ¤hler``).  The paper (seed 003) even prints ``Zähler 1-FI``
with a capital I where the device writes ``Fl`` (Flanken, edges).

The mapping runs once per distinct label (labels are categorical), never per
record.  A label we do not recognise is kept verbatim and counted by the
parser, never dropped or guessed.
"""

from __future__ import annotations

import unicodedata
from dataclasses import dataclass
from functools import lru_cache


@dataclass(frozen=True)
class Register:
    """A known register label: its canonical name and full German name."""

    canonical: str
    full_name: str
    meaning: str


REGISTERS: tuple[Register, ...] = (
    Register("diagnosis_info", "Diagnose Info", "diagnostic information word"),
    Register("designation", "Bezeichnung", "device designation, one character per register"),
    Register("type_number", "Typennummer", "device type number"),
    Register("hardware_state", "Gerätestand", "hardware revision state"),
    Register("serial_number", "Seriennummer", "serial number (numeric or characters)"),
    Register("crc_code", "CRC-Code", "configuration CRC"),
    Register("software_version", "Software Version", "software version"),
    Register("diagnosis", "Diagnose", "diagnostic status"),
    Register("wheel_sensor", "Radsensor", "wheel sensor state: 1 damped, 0 free"),
    Register("sum_counter", "Summenzähler", "sum counter"),
    Register("counter_4_edge", "Zähler 4-Flanken", "4-edge counter"),
    Register("counter_1_edge", "Zähler 1-Flanken", "1-edge counter (disturbances)"),
    Register("analog_value", "Analogwert", "analog receiver value"),
)

BY_CANONICAL = {r.canonical: r for r in REGISTERS}

# The shortest truncation we accept as naming a register: shorter cuts
# ("Zähl", "Dia") are too ambiguous to map safely.
MIN_PREFIX = 5


def _key(text: str) -> str:
    return " ".join(unicodedata.normalize("NFC", text).split()).casefold()


def _fold_i_l(key: str) -> str:
    # "Zähler 1-FI" (capital i) is the paper's misprint of "Fl" (F, small L).
    return key.replace("i", "l")


_FULL_KEYS = [(_key(r.full_name), r.canonical) for r in REGISTERS]


def repair_encoding(label: str) -> str:
    """Undo a UTF-8-read-as-CP1252 mangling (``ZÃ¤hler`` → ``Zähler``).

    Only applied when the text carries the tell-tale ``Ã``/``Â`` lead
    characters; a label cut in the middle of a two-byte sequence keeps the
    complete part.
    """
    if "Ã" not in label and "Â" not in label:
        return label
    for codec in ("cp1252", "latin-1"):
        try:
            raw = label.encode(codec)
        except UnicodeEncodeError:
            continue
        fixed = raw.decode("utf-8", errors="ignore")
        if fixed:
            return fixed
    return label


def _match(key: str) -> str | None:
    for full, canonical in _FULL_KEYS:
        if key == full:
            return canonical
    if len(key) < MIN_PREFIX:
        return None
    hits = {canonical for full, canonical in _FULL_KEYS if full.startswith(key)}
    if len(hits) == 1:
        return hits.pop()
    # Exact names shadow longer ones ("Diagnose" vs "Diagnose Info"); a cut
    # that fits several registers stays unknown rather than guessed.
    return None


@lru_cache(maxsize=4096)
def canonical_label(label: str) -> str | None:
    """Canonical register name for any known spelling, else None.

    >>> canonical_label("Summenzä"), canonical_label("ZÃ¤hler 1-Fl"), canonical_label("Zähler 1-FI")
    ('sum_counter', 'counter_1_edge', 'counter_1_edge')
    """
    key = _key(repair_encoding(label))
    if not key:
        return None
    found = _match(key)
    if found is None:
        folded = _fold_i_l(key)
        for full, canonical in _FULL_KEYS:
            if _fold_i_l(full) == folded or (len(folded) >= MIN_PREFIX and _fold_i_l(full).startswith(folded)):
                if found is not None and found != canonical:
                    return None
                found = canonical
    return found


def decode_label(raw: bytes) -> tuple[str, str]:
    """Decode label bytes: UTF-8 if valid, else CP1252 (Latin-1 for its holes).

    Returns the text and the encoding used.
    """
    try:
        return raw.decode("utf-8"), "utf-8"
    except UnicodeDecodeError:
        pass
    try:
        return raw.decode("cp1252"), "cp1252"
    except UnicodeDecodeError:
        return raw.decode("latin-1"), "latin-1"
