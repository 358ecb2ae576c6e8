"""The simulated heads' diagnostic records as their boards write them: one formatter for every reader.

``diagnostic.log`` (:mod:`console.sim.writers`), the growing log of ``simulate --live``
(:mod:`console.sim.live_run`) and the lines the simulator's station console is fed
(:mod:`console.live.simulated`) are made here, so the console reads exactly what the
files hold.  A row is ``(time ns, head, channel, address, label, data)``.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterable, Sequence

import numpy as np

from console.layout import Layout
from console.sim.slow_faults import REGISTERS, HealthRows
from parsers.units import NS

IDENTITY = [
    ("000", "Diagnose I", "2"),
    ("002", "Bezeichnun", "'T'"),
    ("003", "Bezeichnun", "'M'"),
    ("004", "Bezeichnun", "'C'"),
    ("012", "Typennum", "13"),
    ("014", "Gerätestan", "3"),
    ("016", "Seriennum", "4803"),
    ("020", "CRC-Code", "0xD8"),
    ("022", "Software V", "41"),
]
TIME_RESOLUTIONS = {"us": 1_000, "ms": 1_000_000, "s": NS}
Row = tuple[int, str, int, str, str, str]


def naive_time(t_ns: int) -> dt.datetime:
    """ns since the epoch as the boards print it: UTC, without a zone."""
    return dt.datetime(1970, 1, 1) + dt.timedelta(microseconds=t_ns // 1000)


def diag_line(device: int, head: str, ch: int, adr: str, label: str, data: str, t_ns: int, res: str = "us") -> str:
    """One diagnostic record line as a board writes it, its time at resolution ``res`` (us, ms or s)."""
    t = naive_time(t_ns)
    frac = {"us": f".{t:%f}", "ms": f".{t.microsecond // 1000:03d}", "s": ""}[res]
    return (
        f"Diag_id:00002\tID:{device}\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:{head}\tch:{ch}\tAdr:{adr}\t"
        f"Label:{label}\tData:{data}\tDate:{t:%Y-%m-%d}\tTime:{t:%H:%M:%S}{frac}"
    )


def device_ids(layout: Layout) -> dict[str, int]:
    """Each head's device id: the layout's, else 4081, 4082, … in layout order."""
    return {h.id: h.device_id if h.device_id is not None else 4081 + i for i, h in enumerate(layout.heads)}


def identity_rows(layout: Layout, t_ns: int) -> list[Row]:
    """Each device's identity dump, at ``t_ns`` (a run's start)."""
    return [(t_ns, h.id, 1, a, lab, d) for h in layout.heads for a, lab, d in IDENTITY]


def wheel_rows(records: Iterable[tuple[int, str, int, int]]) -> list[Row]:
    """Wheel-sensor onsets (1) and releases (0): (time, head, channel, value) → Radsensor records."""
    return [(t, head, ch, "026", "Radsensor", str(value)) for t, head, ch, value in records]


def heartbeat_rows(beats: Iterable[tuple[int, str]]) -> list[Row]:
    """Each head's status record, (time, head)."""
    return [(t, head, 1, "000", "Diagnose I", "2") for t, head in beats]


def health_register_rows(batches: Sequence[HealthRows], layout: Layout) -> list[Row]:
    """The heads' health registers (console.sim.slow_faults) as diagnostic rows."""
    if not batches:
        return []
    h = HealthRows.concat(list(batches))
    heads = [x.id for x in layout.heads]
    return [
        (t, heads[i], ch, REGISTERS[r][0], REGISTERS[r][1], str(v))
        for t, i, ch, r, v in zip(
            h.t_ns.tolist(), h.head.tolist(), h.channel.tolist(), h.register.tolist(), h.value.tolist(), strict=True
        )
    ]


def health_lines(batches: Sequence[HealthRows], layout: Layout, ids: dict[str, int]) -> tuple[list[int], list[str]]:
    """The health registers as diagnostic lines with microsecond times (as :func:`diag_line` writes
    them), in time order: one prefix per head, channel and register, the times formatted by numpy."""
    h = HealthRows.concat(list(batches))
    order = np.argsort(h.t_ns, kind="stable")
    heads = [x.id for x in layout.heads]
    prefix = {
        (i, ch, r): f"Diag_id:00002\tID:{ids[head]}\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:{head}\tch:{ch}\t"
        f"Adr:{adr}\tLabel:{label}\tData:"
        for i, head in enumerate(heads)
        for ch in (1, 2)
        for r, (adr, label) in enumerate(REGISTERS)
    }
    t = h.t_ns[order]
    stamps = np.datetime_as_string((t // 1000).astype("datetime64[us]"), unit="us").tolist()
    lines = [
        f"{prefix[(i, ch, r)]}{v}\tDate:{d[:10]}\tTime:{d[11:]}"
        for i, ch, r, v, d in zip(
            h.head[order].tolist(),
            h.channel[order].tolist(),
            h.register[order].tolist(),
            h.value[order].tolist(),
            stamps,
            strict=True,
        )
    ]
    return t.tolist(), lines


def in_order_lines(rows: list[Row], ids: dict[str, int]) -> list[str]:
    """Rows as lines in time order, microsecond times (a stable sort: a board's records keep the order it
    saw them in): what a run appends to its log as it goes."""
    rows.sort(key=lambda r: r[0])
    return [diag_line(ids[h], h, ch, adr, lab, d, t) for t, h, ch, adr, lab, d in rows]
