"""The archive's tables: their names and partition keys, the columns an empty one has, the types its views cast to."""

from __future__ import annotations

# Every table the archive knows, with the partition keys in its part paths.
TABLES: dict[str, tuple[str, ...]] = {
    "records": ("day", "device_id"),
    "fixes": (),
    "frames": (),
    "voltages": (),
    "passages": (),
    "axles": (),
    "section_states": (),
    "count_ledger": (),
    "crossing_timelines": (),
    "health_findings": (),
    "rejected": (),
    "ingests": (),
}
HIVE_TYPES = {"day": "DATE", "device_id": "INTEGER"}
# An empty table still has the columns the presets and scripts name (the
# derived tables' full columns come from the analyses, once there are rows).
_T = "TIMESTAMP_NS"
EMPTY_COLUMNS: dict[str, tuple[tuple[str, str], ...]] = {
    # Every column of a record part (an archive of GNSS fixes or frames alone has none, and the trends and
    # the forecast still query them).
    "records": (
        ("time", _T),
        ("diag_id", "INTEGER"),
        ("device", "VARCHAR"),
        ("type", "VARCHAR"),
        ("gs", "VARCHAR"),
        ("counting_head", "VARCHAR"),
        ("channel", "TINYINT"),
        ("address", "SMALLINT"),
        ("label", "VARCHAR"),
        ("label_canonical", "VARCHAR"),
        ("label_encoding", "VARCHAR"),
        ("data", "VARCHAR"),
        ("value", "BIGINT"),
        ("data_kind", "VARCHAR"),
        ("subsecond", "BOOLEAN"),
        ("file", "VARCHAR"),
        ("file_seq", "INTEGER"),
        ("line", "BIGINT"),
        ("day", "DATE"),
        ("device_id", "INTEGER"),
    ),
    "axles": (
        ("time", _T),
        ("day", "DATE"),
        ("device_id", "INTEGER"),
        ("counting_head", "VARCHAR"),
        ("direction", "VARCHAR"),
        ("speed_kmh", "DOUBLE"),
    ),
    "passages": (
        ("start", _T),
        ("day", "DATE"),
        ("device_id", "INTEGER"),
        ("counting_head", "VARCHAR"),
        ("axles", "BIGINT"),
    ),
    "crossing_timelines": (
        ("crossing", "VARCHAR"),
        ("train", "VARCHAR"),
        ("t_on", _T),
        ("t_head_arrival", _T),
        ("lead_s", "DOUBLE"),
        ("warning_time_s", "DOUBLE"),
        ("late_by_s", "DOUBLE"),
        ("late_cause", "VARCHAR"),
        ("violations", "VARCHAR"),
        ("late", "BOOLEAN"),
    ),
    "health_findings": (
        ("severity", "VARCHAR"),
        ("rule", "VARCHAR"),
        ("counting_head", "VARCHAR"),
        ("channel", "TINYINT"),
        ("message", "VARCHAR"),
        ("time_ns", "BIGINT"),
        ("time", _T),
    ),
    "section_states": (("time", _T), ("day", "DATE"), ("section", "VARCHAR"), ("state", "VARCHAR")),
    "count_ledger": (("time", _T), ("day", "DATE"), ("section", "VARCHAR"), ("head", "VARCHAR"), ("delta", "BIGINT")),
    "rejected": (
        ("file", "VARCHAR"),
        ("file_seq", "BIGINT"),
        ("line", "BIGINT"),
        ("reason", "VARCHAR"),
        ("text", "VARCHAR"),
    ),
    "ingests": (("generation", "BIGINT"), ("path", "VARCHAR"), ("action", "VARCHAR"), ("note", "VARCHAR")),
}


# The one type of each kind of value, whatever the parts hold: times are TIMESTAMP_NS (the logs' times, UTC),
# integers are integers.  Parts written before trackside 0.1 held zone-aware fix times, finding times as text
# and nullable integers as floats; the views cast them (and every new part is written with these types).
COLUMN_TYPES: dict[str, dict[str, str]] = {
    "fixes": {"time": _T},
    "health_findings": {"time": _T, "time_ns": "BIGINT", "channel": "TINYINT"},
    "passages": {"detection_second_ns": "BIGINT", "records_in_detection_second": "BIGINT"},
}
