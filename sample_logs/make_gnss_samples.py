"""Write gnss_devices.csv and gnss_devices.jsonl: one train's two GNSS units, two formats.

Train VN0001 runs along a straight line from 20.6° N, 105.9° E on a true
course of 20°, on 2026-01-19 from 10:05:00 UTC (17:05 in Vietnam, the hour of
Co Nhu Van's Table 1, TCSJ 2026).  Its head unit ``head1`` reports at even seconds, its
end-of-train unit ``eot1``, 400 m behind along the line, at odd seconds:
every 2 s each, for 3 minutes (91 fixes each).  The train runs at 15.5 m/s
(55.8 km/h) for 90 s, then 15.0 m/s (54.0 km/h); speeds chosen so that m/s
and km/h are both exact decimals.  At 10:06:41 the EOT unit has no fix (no
position, valid false).

The same fixes are written twice: CSV with ``Z`` times and speed in m/s,
JSON lines with ``+07:00`` times and speed in km/h; both parse to the same
table.  Positions along the line come from geographiclib (WGS-84 geodesic),
to 7 decimals (about 1 cm).  Deterministic:

    python sample_logs/make_gnss_samples.py
"""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

from geographiclib.geodesic import Geodesic

HERE = Path(__file__).resolve().parent
START = dt.datetime(2026, 1, 19, 10, 5, 0, tzinfo=dt.UTC)
LOCAL = dt.timezone(dt.timedelta(hours=7))
ORIGIN = (20.6, 105.9)
COURSE_DEG = 20.0
TRAIN_LENGTH_M = 400.0
DURATION_S = 180
EOT_OUTAGE_S = 101  # seconds after START: the EOT unit has no fix
UNITS = (("head1", "head", 0, 0.0), ("eot1", "eot", 1, TRAIN_LENGTH_M))  # device, role, time offset s, metres behind


def speed_mps(t: float) -> float:
    return 15.5 if t < 90 else 15.0


def travelled_m(t: float) -> float:
    """Metres the train's head has run since START."""
    return 15.5 * min(t, 90.0) + 15.0 * max(t - 90.0, 0.0)


def fixes() -> list[dict[str, object]]:
    """All fixes, in time order: time, device, role, lat, lon, speed_mps, course_deg, valid."""
    out: list[dict[str, object]] = []
    for t in range(DURATION_S + 2):
        for device, role, offset, behind in UNITS:
            if t % 2 != offset or t - offset > DURATION_S:
                continue
            where = Geodesic.WGS84.Direct(*ORIGIN, COURSE_DEG, travelled_m(t) - behind)
            valid = not (device == "eot1" and t == EOT_OUTAGE_S)
            out.append(
                {
                    "time": START + dt.timedelta(seconds=t),
                    "device": device,
                    "role": role,
                    "lat": round(where["lat2"], 7) if valid else None,
                    "lon": round(where["lon2"], 7) if valid else None,
                    "speed_mps": speed_mps(t) if valid else None,
                    "course_deg": COURSE_DEG if valid else None,
                    "valid": valid,
                }
            )
    return out


def _cell(value: object) -> str:
    return "" if value is None else str(value).lower() if isinstance(value, bool) else str(value)


def write_csv(path: Path, rows: list[dict[str, object]]) -> None:
    lines = ["# train VN0001: head1 (head) and eot1 (end of train); written by make_gnss_samples.py"]
    lines.append("time,device,role,lat,lon,speed,course_deg,valid")
    for r in rows:
        time = r["time"]
        assert isinstance(time, dt.datetime)
        stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ")
        cells = [r["device"], r["role"], r["lat"], r["lon"], r["speed_mps"], r["course_deg"], r["valid"]]
        lines.append(",".join([stamp, *map(_cell, cells)]))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def write_jsonl(path: Path, rows: list[dict[str, object]]) -> None:
    lines = ["# train VN0001: head1 (head) and eot1 (end of train); written by make_gnss_samples.py"]
    for r in rows:
        time = r["time"]
        assert isinstance(time, dt.datetime)
        speed = r["speed_mps"]
        obj = {
            "time": time.astimezone(LOCAL).isoformat(),
            "device": r["device"],
            "role": r["role"],
            "lat": r["lat"],
            "lon": r["lon"],
            "speed_kmh": None if not isinstance(speed, float) else round(speed * 3.6, 1),
            "course": r["course_deg"],
            "valid": r["valid"],
        }
        lines.append(json.dumps(obj, ensure_ascii=False))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def main() -> None:
    rows = fixes()
    write_csv(HERE / "gnss_devices.csv", rows)
    write_jsonl(HERE / "gnss_devices.jsonl", rows)
    print(f"{len(rows)} fixes → gnss_devices.csv, gnss_devices.jsonl")


if __name__ == "__main__":
    main()
