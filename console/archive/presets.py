"""Named queries for `trackside query --preset NAME` (documented in README and docs/archive.md)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Preset:
    doc: str
    sql: str


PRESETS: dict[str, Preset] = {
    "axles-per-head-per-day": Preset(
        "axles counted per counting head per day, both directions",
        """
        SELECT day, device_id, counting_head, count(*) AS axles,
               count(*) FILTER (WHERE direction = 'sys1_to_sys2') AS axles_sys1_first,
               count(*) FILTER (WHERE direction = 'sys2_to_sys1') AS axles_sys2_first
        FROM axles GROUP BY ALL ORDER BY day, device_id, counting_head
        """,
    ),
    "late-warnings": Preset(
        "level-crossing warnings that came late (short of the warning time) or broke a safety rule",
        """
        SELECT crossing, train, t_on, t_head_arrival, lead_s, warning_time_s, late_by_s, late_cause, violations
        FROM crossing_timelines WHERE late ORDER BY t_head_arrival
        """,
    ),
    "failing-sensors": Preset(
        "health findings of warning or critical severity, per head and channel, worst first",
        """
        SELECT severity, rule, counting_head, channel, count(*) AS findings, min(message) AS example
        FROM health_findings WHERE severity IN ('warning', 'critical')
        GROUP BY severity, rule, counting_head, channel
        ORDER BY severity = 'critical' DESC, findings DESC, counting_head, channel
        """,
    ),
    "due-for-maintenance": Preset(
        "heads, channels and GNSS units whose health figure crosses its threshold within 30 days (or has), by date",
        """
        SELECT target AS head_or_unit, channel, figure, status, crossing, earliest, latest, days_left,
               last_value, threshold, unit
        FROM forecasts WHERE due ORDER BY coalesce(crossing, earliest), earliest, target, figure
        """,
    ),
}
