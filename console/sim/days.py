"""Multi-day runs (``simulate --days N``): the simulator stepped a day at a time, each day's logs written and let go.

Days are calendar days of the logs' clock (UTC): a day's logs go into ``DIR/YYYY-MM-DD/`` (the way
logs are pulled off a line, a file per day), or, with ``one_log``, are appended to one set of growing
files in ``DIR`` (a device's log as it grows).  Memory holds one day of records, whatever the number
of days.  ``health_only`` steps only the heads' health registers (console.sim.slow_faults): the same
rounds a full run writes, for weeks of hundreds of heads in seconds.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable
from pathlib import Path
from typing import Any

from console.sim.station import StationSim
from console.sim.writers import run_layout_text, write_logs, write_truth
from parsers.units import NS

DAY_S = 86_400.0


def midnight_ns(t_ns: int) -> int:
    """The start of ``t_ns``'s day (UTC)."""
    return t_ns - t_ns % (int(DAY_S) * NS)


def run_days(
    sim: StationSim,
    days: float,
    directory: Path,
    *,
    one_log: bool = False,
    health_only: bool = False,
    on_step: Callable[[float], None] | None = None,
) -> dict[str, Any]:
    """Simulate ``days`` days from the simulator's start, writing each day as it ends; then the truth."""
    total_s = days * DAY_S
    written: dict[str, Any] = {}
    start = sim.cfg.start_ns
    first = True
    while sim.t_s < total_s:
        day_start_ns = midnight_ns(sim.now_ns)
        end_s = min(total_s, (day_start_ns - start) / NS + DAY_S)
        if health_only:
            sim.run_health_only(end_s, on_step=on_step)
        else:
            sim.run(end_s, on_step=on_step, finish=end_s >= total_s)  # the console runs on over midnight
        name = dt.datetime.fromtimestamp(day_start_ns // NS, dt.UTC).strftime("%Y-%m-%d")
        target = directory if one_log else directory / name
        written[name] = write_logs(
            sim, target, since_ns=max(day_start_ns, start), append=one_log and not first, health_only=health_only
        )
        first = False
        sim.all_records.clear()
        sim.heartbeats.clear()
        sim.all_fixes.clear()
        sim.all_received.clear()
        sim.axle_events.clear()
        sim.health_rows.clear()
    (directory / "layout.toml").write_text(run_layout_text(sim), encoding="utf-8")
    return {"days": written, "truth.json": write_truth(sim, directory / "truth.json")}
