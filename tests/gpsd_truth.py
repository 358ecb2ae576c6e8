"""gpsd's decoding of a capture (its ``.chk``) as the truth our fix table is held to.

The ``.chk`` gpsd's regression suite keeps beside each capture echoes the
NMEA sentences gpsd read (or, for a binary protocol, the NMEA it generated
from it) and the JSON reports that followed.  A fix, for this comparison,
is an *epoch*: a distinct TPV ``time`` for which gpsd reported ``mode`` ≥ 2
with a position.  gpsd reports an epoch several times (after RMC, after GGA,
after VTG …) and on a sentence without speed it fills in a speed it computed
from positions, so an epoch matches when one of our valid rows has its time,
one of gpsd's positions for it (within 1e-6°) and, if both give a speed, one
of gpsd's speeds for it (within 0.01 m/s).  A speed we do not have stays NaN
(we never compute one here); that is not a mismatch.

An epoch is *from NMEA* when the sentence gpsd echoed just before its
report is in the capture itself; otherwise gpsd decoded it from a binary
protocol (UBX, SiRF, TSIP, GREIS, Oncore …), whose content we only skip.

gpsd corrects dates for the GPS week rollover on old receivers (rst39:
an RMC dated 2014 reported in 2033); an epoch whose time of day matches but
whose date differs is counted apart (``date_differs``).
"""

from __future__ import annotations

import json
import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

DAY_NS = 86_400 * 1_000_000_000


@dataclass
class Epoch:
    positions: list[tuple[float, float]] = field(default_factory=list)
    speeds: set[float] = field(default_factory=set)
    from_nmea: bool = False


def gpsd_epochs(log: Path) -> dict[int, Epoch]:
    """gpsd's fix epochs of a capture, by time (ns since the epoch)."""
    data = log.read_bytes()
    epochs: dict[int, Epoch] = {}
    last: bytes | None = None
    for line in log.with_name(log.name + ".chk").read_bytes().split(b"\n"):
        if line.startswith((b"$", b"!")):
            last = line.rstrip(b"\r")
            continue
        if not line.startswith(b"{"):
            continue
        try:
            obj = json.loads(line)
        except ValueError:
            continue
        if obj.get("class") != "TPV" or "time" not in obj or obj.get("mode", 0) < 2 or "lat" not in obj:
            continue
        epoch = epochs.setdefault(pd.Timestamp(obj["time"]).value, Epoch())
        epoch.positions.append((obj["lat"], obj["lon"]))
        if "speed" in obj:
            epoch.speeds.add(obj["speed"])
        if last is not None and last in data:
            epoch.from_nmea = True
    return epochs


def compare_with_gpsd(log: Path, fixes: pd.DataFrame) -> Counter[str]:
    """Counts: ``nmea``/``binary`` epochs, ``nmea_matched``/``binary_matched``, ``…_date_differs``,
    and ``extra``: our valid, dated fixes at a time where gpsd reports no fix at all."""
    valid = fixes[fixes["valid"]]
    times = valid["time"].astype("int64").to_numpy()
    lat, lon, speed = (valid[c].to_numpy() for c in ("lat", "lon", "speed_mps"))
    epochs = gpsd_epochs(log)
    counts: Counter[str] = Counter()

    def matches(i: Any, epoch: Epoch) -> bool:
        near = any(abs(lat[i] - a) <= 1e-6 and abs(lon[i] - b) <= 1e-6 for a, b in epoch.positions)
        fast = math.isnan(speed[i]) or not epoch.speeds or any(abs(speed[i] - s) <= 0.01 for s in epoch.speeds)
        return near and fast

    for ns, epoch in epochs.items():
        kind = "nmea" if epoch.from_nmea else "binary"
        counts[kind] += 1
        if any(matches(i, epoch) for i in np.flatnonzero(times == ns)):
            counts[f"{kind}_matched"] += 1
        elif any(matches(i, epoch) for i in np.flatnonzero(times % DAY_NS == ns % DAY_NS)):
            counts[f"{kind}_matched"] += 1
            counts[f"{kind}_date_differs"] += 1
    known = set(epochs) | {ns % DAY_NS for ns in epochs}
    nat = np.iinfo(np.int64).min
    counts["extra"] = int(sum(1 for t in times if t != nat and t not in known and t % DAY_NS not in known))
    return counts
