"""The GNSS unit table (a row per device: its fixes, valid fixes, span, roles and sources) as flat columns.

What the report shows of the fixes, without them: a file may hold a million devices, so the table is
grouped reductions into arrays, the device names kept flat and put in their natural order here.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from console.inputs.recognise import NUMBER_PARTS
from console.sinks.report.unit_codes import first_last_ns, sorted_codes, sorted_name_codes, sorted_positions

if TYPE_CHECKING:  # pandas is imported where it is used (see console.sinks.report.model)
    import pandas as pd


def _natural_order(names: pd.Index | Sequence[str]) -> np.ndarray:
    """Positions of ``names`` in :func:`natural_key` order (ties keep their order), one sort key
    string per name: runs of digits length-prefixed, so that plain string order is the natural one."""
    return sorted_positions(names, lambda x: NUMBER_PARTS.sub(_padded_number, str(x).casefold()))


def _padded_number(m: re.Match[str]) -> str:
    digits = m.group().lstrip("0") or "0"
    # "\x00" sorts the number before any letter, as natural_key's int part before a text part.
    return f"\x00{len(digits):06d}{digits}"


def _value_sets(code: np.ndarray, values: pd.Series, n: int) -> tuple[np.ndarray, list[str]]:
    """Per device, the set of ``values`` it has, as a bit mask over the distinct values (few: roles,
    sources), and those values: flat, not a set object per device."""
    vcode, vnames = sorted_codes(values)
    if len(vnames) > 64:  # never for roles or sources; keep the first 64 rather than fail
        vcode = np.where(vcode < 64, vcode, 63)
    # The narrowest mask that holds them (a byte per device for the few roles or sources).
    bits = next(t for t in (np.uint8, np.uint16, np.uint32, np.uint64) if np.iinfo(t).bits >= len(vnames))
    mask = np.zeros(n, bits)
    np.bitwise_or.at(mask, code, np.left_shift(bits(1), vcode.astype(bits)))
    return mask, [str(v) for v in vnames[:64]]


@dataclass
class GnssUnits:
    """The GNSS unit table as flat columns, one entry per device (``names`` in string order), and the
    devices' natural order: what the report shows of the fixes, without them."""

    names: pd.Index | Sequence[str]
    order: np.ndarray  # positions in ``names``, in natural_key order
    count: np.ndarray
    n_valid: np.ndarray
    first_ns: np.ndarray
    last_ns: np.ndarray
    roles: np.ndarray  # bit masks over role_names
    role_names: list[str]
    sources: np.ndarray  # bit masks over source_names
    source_names: list[str]


def gnss_units_of_columns(
    device_codes: np.ndarray,
    device_names: Sequence[str],
    valid: np.ndarray,
    time_ns: np.ndarray,
    role: np.ndarray,
    source: np.ndarray,
) -> GnssUnits:
    """:class:`GnssUnits` of the fix columns it reads (:class:`~parsers.gnss.fix_table.FixColumns`' fields
    of those names; ``role``/``source`` codes into ROLES/SOURCES): the device names stay flat."""
    import pandas as pd

    from parsers.gnss.fix_table import ROLES, SOURCES

    code, names = sorted_name_codes(device_codes, device_names)
    role_column = pd.Series(pd.Categorical.from_codes(role, dtype=pd.CategoricalDtype(list(ROLES))))
    source_column = pd.Series(pd.Categorical.from_codes(source, dtype=pd.CategoricalDtype(list(SOURCES))))
    return units_of_codes(code, names, valid.astype(bool), time_ns, role_column, source_column)


def units_of_codes(
    code: np.ndarray,
    names: pd.Index | Sequence[str],
    valid: np.ndarray,
    times_ns: np.ndarray,
    role_column: pd.Series,
    source_column: pd.Series,
) -> GnssUnits:
    """:class:`GnssUnits` of the fixes as columns: ``code`` (each fix's device, a position in ``names``), validity,
    times (ns) and the role and source columns."""
    n = len(names)
    # The natural order first: its sort keys (~30 MB a million devices) are made before the columns below.
    order = _natural_order(names).astype(np.int32)
    # Counts as int32 (a device's fixes are rows of one table) and positions too: kept until written.
    count = np.bincount(code, minlength=n).astype(np.int32)
    n_valid = np.bincount(code, weights=valid, minlength=n).astype(np.int32)
    first, last = first_last_ns(code, times_ns, n)
    roles, role_names = _value_sets(code, role_column, n)
    sources, source_names = _value_sets(code, source_column, n)
    return GnssUnits(names, order, count, n_valid, first, last, roles, role_names, sources, source_names)
