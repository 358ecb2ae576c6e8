"""Device inventory from the identity registers of a diagnostic log.

Each evaluation board reports who it is in a block of registers: the
designation one character per ``Bezeichnung`` register (Adr 002–011, e.g.
'T','M','C',' '…), the type number, hardware state, serial number, software
version and configuration CRC.  The latest value of each register wins.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

IDENTITY_LABELS = (
    "designation",
    "type_number",
    "hardware_state",
    "serial_number",
    "software_version",
    "crc_code",
)


@dataclass(frozen=True)
class IdentityValue:
    """The latest value seen for one identity register of a device."""

    canonical: str
    address: int
    value: int
    kind: str  # decimal | hex | char
    text: str  # as written in the log


@dataclass
class DeviceInventory:
    device_id: int
    device: str
    type: str
    gs: str
    diag_ids: list[int]
    counting_heads: list[str]
    channels: list[int]
    records: int
    first_ns: int
    last_ns: int
    designation: str | None = None
    type_number: str | None = None
    hardware_state: str | None = None
    serial_number: str | None = None
    software_version: str | None = None
    crc: str | None = None
    identity: list[IdentityValue] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        from console.analysis.timefmt import iso

        return {
            "device_id": self.device_id,
            "device": self.device,
            "type": self.type,
            "gs": self.gs,
            "diag_ids": self.diag_ids,
            "counting_heads": self.counting_heads,
            "channels": self.channels,
            "records": self.records,
            "first": iso(self.first_ns),
            "last": iso(self.last_ns),
            "designation": self.designation,
            "type_number": self.type_number,
            "hardware_state": self.hardware_state,
            "serial_number": self.serial_number,
            "software_version": self.software_version,
            "crc": self.crc,
        }


def _scalar(values: list[IdentityValue]) -> str | None:
    if not values:
        return None
    v = values[0]
    return v.text if v.kind == "hex" else str(v.value) if v.kind == "decimal" else chr(v.value)


def apply_identity(inv: DeviceInventory, values: list[IdentityValue]) -> None:
    """Fill the inventory's identity fields from its registers' latest values, most recently read first (of
    registers with the same name and address on several heads, the first given is taken)."""
    inv.identity = sorted(values, key=lambda v: (v.canonical, v.address))
    by: dict[str, list[IdentityValue]] = {}
    for v in inv.identity:
        by.setdefault(v.canonical, []).append(v)
    chars = [chr(v.value) for v in by.get("designation", []) if v.kind == "char"]
    inv.designation = "".join(chars).strip() or None if chars else None
    inv.type_number = _scalar(by.get("type_number", []))
    inv.hardware_state = _scalar(by.get("hardware_state", []))
    inv.software_version = _scalar(by.get("software_version", []))
    inv.crc = _scalar(by.get("crc_code", []))
    serial = by.get("serial_number", [])
    numeric = [v for v in serial if v.kind != "char"]
    if numeric:
        # The numeric register is the serial; character registers beside it
        # are padding ('0','0' at Adr 029/030 in the paper's excerpt).
        inv.serial_number = str(numeric[0].value)
    elif serial:
        inv.serial_number = "".join(chr(v.value) for v in serial).strip() or None
