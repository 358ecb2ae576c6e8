"""The report as blocks: headings, paragraphs, tables, figures (:func:`outline`; the blocks are
:mod:`console.sinks.report.blocks`).

Built from the JSON document (:func:`console.sinks.report.document.document`); the
Markdown and HTML faces both render these blocks, so the formats cannot
disagree.  Every string in a block is raw text (from a log or not): the
renderers escape all of it for their format.
"""

from __future__ import annotations

import itertools
from typing import Any

from console.plural import count
from console.sinks.report.blocks import (
    Block,
    Bullets,
    Cell,
    Figure,
    Heading,
    Lazy,
    Para,
    Styled,
    num_or_dash,
    table_block,
)
from console.sinks.report.forecast import forecast_part
from console.sinks.report.model import FAILING, UNSAFE
from console.sinks.report.trends import trends_part

TIMELINE_ROWS_SHOWN = 400
REJECTIONS_SHOWN = 20
STATE_MARKS = {"clear": "·", "occupied": "#", "disturbed": "!", "preparatory": "?"}
SEVERITY_MARKS = {"critical": "!!", "warning": "!", "info": "·"}
_ARROWS = {"sys1_to_sys2": "1→2", "sys2_to_sys1": "2→1", "mixed": "mixed"}


def show_time(text: str | None) -> str:
    """ISO 8601 → ``2026-03-02 08:00:00.500`` (milliseconds when the time has a fraction); None → ``–``."""
    if not text:
        return "–"
    day, _, clock = text.removesuffix("Z").partition("T")  # JSON times are UTC (timefmt.iso)
    whole, _, frac = clock.partition(".")
    ms = (frac + "000")[:3]
    return f"{day} {whole}" + (f".{ms}" if ms != "000" else "")


def _clock(text: str | None, day: str | None) -> str:
    """A time of day when the table's day is known, else the full time."""
    shown = show_time(text)
    return shown[11:] if day and text and text.startswith(day) else shown


def _one_day(values: list[str | None]) -> str | None:
    days = {v[:10] for v in values if v}
    return days.pop() if len(days) == 1 else None


def _state(state: str) -> Styled:
    return Styled(f"{STATE_MARKS.get(state, '')} {state}".strip(), f"state-{state}")


def _severity(sev: str) -> Styled:
    return Styled(f"{SEVERITY_MARKS.get(sev, '')} {sev}".strip(), f"sev-{sev}")


def _safety_part(doc: dict[str, Any]) -> list[Block]:
    s = doc["safety"]
    out: list[Block] = [
        Heading(2, "1. Safety violations and failing items", "safety"),
        Para(
            (
                "Unsafe: a level-crossing safety violation (the road open with the train on it), a train seen "
                "parted, or a critical health finding (a head that may stop detecting). Failing: a section that "
                "ended disturbed (fail-safe, but trains wait for a reset), a refused reset, a crossing warning held "
                "on after the "
                "train arrived, "
                "a warning-level health finding.",
            )
        ),
    ]
    if not s["items"]:
        out.append(Para((Styled("Nothing unsafe or failing.", "ok"),)))
        return out
    rows: list[list[Cell]] = [
        [
            Styled("UNSAFE" if a["class"] == UNSAFE else "failing", a["class"]),
            _severity(a["severity"]),
            a["topic"],
            a["subject"],
            show_time(a["time"]),
            a["message"],
        ]
        for a in s["items"]
    ]
    cols = [("Class", False), ("Severity", False), ("Topic", False), ("Subject", False), ("Time", False)]
    out.append(table_block([*cols, ("What", False)], rows))
    return out


def _inputs_part(doc: dict[str, Any]) -> list[Block]:
    inp = doc["inputs"]
    out: list[Block] = [Heading(2, "2. Inputs and parse report", "inputs")]
    rows: list[list[Cell]] = []
    for f in inp["files"]:
        rows.append(
            [
                f["file"],
                f["format"],
                "yes" if f["read"] else Styled("no", "muted"),
                num_or_dash(f["lines_read"], "{:,}"),
                num_or_dash(f["records"], "{:,}"),
                num_or_dash(f["blank"], "{:,}"),
                Styled(num_or_dash(f["rejected"], "{:,}"), "bad" if f["rejected"] else ""),
                f["note"],
            ]
        )
    t = inp["totals"]
    rows.append(
        [
            Styled("total", "strong"),
            "",
            f"{t['read']} of {t['files']}",
            f"{t['lines_read']:,}",
            f"{t['records']:,}",
            f"{t['blank']:,}",
            f"{t['rejected']:,}",
            "",
        ]
    )
    cols = [("File", False), ("Format", False), ("Read", False), ("Lines", True), ("Records", True)]
    out.append(table_block([*cols, ("Blank", True), ("Rejected", True), ("Note", False)], rows))
    rej = inp["rejections"]
    if t["rejected"]:
        shown = rej[:REJECTIONS_SHOWN]
        out.append(Heading(3, f"Rejected lines (first {len(shown)} of {t['rejected']:,})", "rejections"))
        out.append(
            table_block(
                [("File", False), ("Line", True), ("Reason", False), ("Text", False)],
                [[r["file"], str(r["line"]), r["reason"], r["text"]] for r in shown],
                "The JSON report lists up to 1,000 rejected lines per input kind.",
            )
        )
        reasons = ", ".join(f"{k} {v:,}" for k, v in inp["rejected_by_reason"].items())
        out.append(Para(("Rejected by reason: ", reasons + ".")))
    if inp["unknown_labels"]:
        labels = ", ".join(f"{k} ({v:,})" for k, v in inp["unknown_labels"].items())
        out.append(Para(("Unknown labels, kept verbatim (records): ", labels + ".")))
    if doc["warnings"]:
        out.append(Heading(3, "Warnings", "warnings"))
        out.append(Bullets(tuple(doc["warnings"])))
    return out


def _devices_part(doc: dict[str, Any]) -> list[Block]:
    out: list[Block] = [Heading(2, "3. Device inventory", "devices")]
    if doc["devices"]:
        out.append(Heading(3, "Axle-counter devices (diagnostic logs)", "diag-devices"))
        rows: list[list[Cell]] = []
        for d in doc["devices"]:
            ident = [
                ("designation", ""),
                ("type_number", "type "),
                ("hardware_state", "hw "),
                ("serial_number", "serial "),
                ("software_version", "sw "),
                ("crc", "CRC "),
            ]
            rows.append(
                [
                    str(d["device_id"]),
                    f"{d['device']} / {d['type']} / {d['gs']}",
                    ", ".join(d["counting_heads"]),
                    ", ".join(str(c) for c in d["channels"]),
                    ", ".join(f"{p}{d[k]}" for k, p in ident if d[k] is not None) or "–",
                    f"{d['records']:,}",
                    show_time(d["first"]),
                    show_time(d["last"]),
                ]
            )
        cols = [("Device", True), ("Device / Type / GS", False), ("Counting heads", False), ("Channels", False)]
        out.append(
            table_block([*cols, ("Identity", False), ("Records", True), ("First", False), ("Last", False)], rows)
        )
    if doc["sensors"]:
        out.append(Heading(3, "Intelligent sensors (frames and CAN)", "sensors"))
        rows = [
            [
                s["sensor"],
                f"{s['frames']:,}",
                show_time(s["first"]),
                show_time(s["last"]),
                str(s["axles_up"]),
                str(s["axles_down"]),
                str(s["channel_faults"]),
                str(s["count_errors"]),
                str(s["contact_losses"]),
            ]
            for s in doc["sensors"]
        ]
        cols = [("Sensor", False), ("Frames", True), ("First", False), ("Last", False), ("Axles up", True)]
        cols += [("Axles down", True), ("Faults", True), ("Count errors", True), ("Contact losses", True)]
        out.append(table_block(cols, rows))
    if doc["gnss_units"]:
        out.append(Heading(3, "GNSS units (times UTC)", "gnss-units"))
        rows = [
            [
                u["device"],
                u["role"] or "–",
                ", ".join(u["sources"]),
                f"{u['fixes']:,}",
                f"{u['valid']:,}",
                show_time(u["first"]),
                show_time(u["last"]),
            ]
            for u in doc["gnss_units"]
        ]
        cols = [("Device", False), ("Role", False), ("Sources", False), ("Fixes", True), ("Valid", True)]
        out.append(table_block([*cols, ("First", False), ("Last", False)], rows))
    if not (doc["devices"] or doc["sensors"] or doc["gnss_units"]):
        out.append(Para(("No devices: no diagnostic log, frame file or GNSS telemetry was read.",)))
    return out


def _passages_part(doc: dict[str, Any]) -> list[Block]:
    s = doc["settings"]
    out: list[Block] = [
        Heading(2, "4. Passages and speeds", "passages"),
        Para(
            (
                "Speeds in km/h. Per-second: the paper's method, coil spacing × records in the first detection "
                "second (the records counted in brackets). Whole train: (train length + spacing) / the entering "
                "system's first detection → the leaving system's last. Per axle: spacing / each wheel's "
                f"Sys1→Sys2 delay (logs with sub-second times), here the mean. Spacing {_spacing_text(s)}, "
                f"train length {s['train_length_m']} m; a gap of {s['idle_gap_s']:g} s ends a passage.",
            )
        ),
    ]
    if not doc["passages"]:
        out.append(Para(("No passages: no wheel detection in the diagnostic logs.",)))
    else:
        out.append(Figure("speeds"))
        passages = doc["passages"]
        cols = [("Head", False), ("Start", False), ("Dur s", True), ("Axles", True), ("Dir", False)]
        cols += [("Per-second", True), ("Whole train", True), ("Per-axle mean", True), ("Kind", False)]
        out.append(table_block(cols, Lazy(lambda: (_passage_row(p) for p in passages))))
    notes = []
    if doc["status_bursts"]:
        n = doc["status_bursts"]
        notes.append(
            f"{count(n, 'status-only record burst', sep=True)} (no wheel)"
            f" {'is' if n == 1 else 'are'} counted, not listed."
        )
    if doc["overlap_records"]:
        n = doc["overlap_records"]
        notes.append(
            f"{count(n, 'record', sep=True)} {'repeats' if n == 1 else 'repeat'} another file's second"
            f" and {'was' if n == 1 else 'were'} counted once."
        )
    if doc["unpaired_detections"]:
        notes.append(
            f"{count(doc['unpaired_detections'], 'wheel detection', sep=True)} on one system only (not axles)."
        )
    if notes:
        out.append(Para((" ".join(notes),)))
    return out


def _passage_row(p: dict[str, Any]) -> list[Cell]:
    per_sec = num_or_dash(p["speed_kmh_per_second_method"])
    if p["records_in_detection_second"] is not None:
        per_sec += f" ({p['records_in_detection_second']})"
    return [
        p["counting_head"],
        show_time(p["start"]),
        num_or_dash(p["duration_s"], "{:.2f}"),
        "–" if p["axles_unknown_reason"] else str(p["axles"]),  # no onset pair possible: the reason says why
        _ARROWS.get(p["direction"] or "", "–"),
        per_sec,
        num_or_dash(p["speed_kmh_whole_train"], "{:.2f}"),
        num_or_dash(p["speed_kmh_per_axle_mean"]),
        Styled(p["kind"], "muted" if p["kind"] != "train" else ""),
    ]


def _sections_part(doc: dict[str, Any]) -> list[Block]:
    out: list[Block] = [Heading(2, "5. Sections", "sections")]
    sec = doc["sections"]
    if sec is None:
        out.append(Para((doc["notes"].get("sections", "No section states."),)))
        return out
    source = {"diagnostic": "the diagnostic logs", "frames": "the sensor and CAN frames"}.get(
        sec["events_from"] or "", "no events"
    )
    out.append(
        Para(
            (
                "Each section starts preparatory (? state unknown until a sweep train has run in and out): "
                f"the log does not say the line was empty. Detection events from {source}. "
                "Marks: · clear, # occupied, ! disturbed, ? preparatory.",
            )
        )
    )
    out.append(Figure("sections"))
    out.append(Heading(3, "States at the end of the data", "section-states"))
    rows: list[list[Cell]] = [
        [s["section"], _state(s["state"]), str(s["count"]), str(s["count_in"]), str(s["count_out"]), s["reason"]]
        for s in sec["final"]
    ]
    cols = [("Section", False), ("State", False), ("Count", True), ("In", True), ("Out", True), ("Why", False)]
    out.append(table_block(cols, rows))
    tl = sec["timeline"]
    shown = list(itertools.islice(tl, TIMELINE_ROWS_SHOWN))
    out.append(Heading(3, f"State timeline ({count(len(tl), 'change', sep=True)})", "section-timeline"))
    rows = [[show_time(r["time"]), r["section"], _state(r["state"]), str(r["count"]), r["reason"]] for r in shown]
    note = f"First {len(shown)} of {len(tl):,} changes; the JSON report lists all." if len(tl) > len(shown) else ""
    cols = [("Time", False), ("Section", False), ("State", False), ("Count", True), ("Why", False)]
    out.append(table_block(cols, rows, note))
    out.append(Heading(3, f"Count ledger ({count(len(sec['ledger']), 'axle', sep=True)} counted)", "ledger"))
    if sec["ledger_summary"]:
        rows = [
            [
                r["section"],
                r["head"],
                str(r["count_in"]),
                str(r["count_out"]),
                show_time(r["first"]),
                show_time(r["last"]),
            ]
            for r in sec["ledger_summary"]
        ]
        cols = [("Section", False), ("Head", False), ("In", True), ("Out", True), ("First", False), ("Last", False)]
        out.append(
            table_block(cols, rows, "Axles counted in and out of each section at each head; the JSON lists each.")
        )
    else:
        out.append(Para(("No axle was counted into or out of a section.",)))
    out.append(Heading(3, "Reset requests", "resets"))
    if sec["resets"]:
        rows = [
            [
                show_time(r["time"]),
                r["section"],
                Styled("accepted", "ok") if r["accepted"] else Styled("refused", "bad"),
                r["reason"],
            ]
            for r in sec["resets"]
        ]
        out.append(table_block([("Time", False), ("Section", False), ("Result", False), ("Why", False)], rows))
    else:
        out.append(Para(("No reset requests in the data.",)))
    return out


def _health_part(doc: dict[str, Any]) -> list[Block]:
    h = doc["health"]
    c = h["counts"]
    out: list[Block] = [
        Heading(2, "6. Health findings", "health"),
        Para((f"{c['critical']} critical, {c['warning']} warning, {c['info']} info (critical first).",)),
    ]
    if h["findings"]:
        rows: list[list[Cell]] = [
            [
                _severity(f["severity"]),
                f["counting_head"] or "–",
                "–" if f["channel"] is None else f"Sys{f['channel']}",
                f["rule"],
                show_time(f["time"]),
                f["message"],
            ]
            for f in h["findings"]
        ]
        cols = [("Severity", False), ("Head / sensor", False), ("Channel", False), ("Rule", False)]
        out.append(table_block([*cols, ("Since", False), ("Finding", False)], rows))
    out.append(Heading(3, "Analog values per channel", "analog"))
    if h["analog"]:
        out.append(Figure("analog"))
        rows = [
            [
                a["counting_head"],
                f"Sys{a['channel']}",
                f"{a['address']:03d}",
                f"{a['values']:,}",
                num_or_dash(a["min"], "{:.0f}"),
                num_or_dash(a["mean"], "{:.0f}"),
                num_or_dash(a["max"], "{:.0f}"),
                show_time(a["first"]),
                show_time(a["last"]),
            ]
            for a in h["analog"]
        ]
        cols = [("Head", False), ("Channel", False), ("Adr", False), ("Values", True), ("Min", True)]
        cols += [("Mean", True), ("Max", True), ("First", False), ("Last", False)]
        out.append(table_block(cols, rows))
    else:
        out.append(Para(("No analog receiver values (Analogwert registers) in the diagnostic logs.",)))
    return out


def _crossings_part(doc: dict[str, Any]) -> list[Block]:
    out: list[Block] = [Heading(2, "7. Level crossings", "crossings")]
    cr = doc["crossings"]
    if cr is None:
        out.append(Para((doc["notes"].get("crossings", "No level-crossing timelines."),)))
        return out
    tls = cr["timelines"]
    day = _one_day([r[k] for r in tls for k in ("t_on", "t_head_arrival", "t_tail_clear", "t_off")])
    out.append(
        Para(
            (
                f"Times UTC (GNSS){f', on {day}' if day else ''}. Lead = head arrival − warning on; excess = "
                "warning off − tail clear (road closed for nothing). Baseline: a fixed-time switch-off at head "
                "arrival + length / speed + 10 s; 'early' where it would have opened the road with the train on it. "
                f"{cr['violations']} timeline(s) with a safety violation.",
            )
        )
    )
    if not tls:
        out.append(Para(("No train reached a crossing in the telemetry.",)))
    else:
        out.append(Figure("crossings"))
        rows: list[list[Cell]] = []
        for r in tls:
            if r["baseline_early_s"]:
                base: Cell = Styled(f"{r['baseline_early_s']:.0f} s early", "warn")
            elif r["baseline_excess_s"] is not None:
                base = f"+{r['baseline_excess_s']:.0f} s"
            else:
                base = "–"
            rows.append(
                [
                    r["crossing"],
                    r["train"],
                    _clock(r["t_on"], day),
                    _clock(r["t_head_arrival"], day),
                    _clock(r["t_tail_clear"], day),
                    _clock(r["t_off"], day) if r["t_off"] else Styled("held on", "warn"),
                    num_or_dash(r["lead_time_s"], "{:.0f}"),
                    num_or_dash(r["excess_warning_s"], "{:.0f}"),
                    base,
                    Styled("; ".join(r["violations"]), "unsafe") if r["violations"] else "none",
                ]
            )
        cols = [("Crossing", False), ("Train", False), ("On", False), ("Head arrival", False)]
        cols += [("Tail clear", False), ("Off", False), ("Lead s", True), ("Excess s", True)]
        out.append(table_block([*cols, ("Baseline", False), ("Violations", False)], rows))
        out.append(Heading(3, "Why the warning came on and went off", "crossing-why"))
        rows = [[r["crossing"], r["train"], r["reason_on"] or "–", r["reason_off"] or "–"] for r in tls]
        out.append(table_block([("Crossing", False), ("Train", False), ("On", False), ("Off", False)], rows))
        spared = [r for r in tls if r.get("spare")]
        if spared:
            out.append(Heading(3, "Spare warning: physics and doubt", "crossing-spare"))
            out.append(
                Para(
                    (
                        "Spare = lead − the crossing's warning time. Physics: what the unit's bounds (a train "
                        "may accelerate at the line's rate to the line speed; the guard distance) cost a unit "
                        "that knew the motion, judged in hindsight from all the fixes. Doubt: the rest, by cause "
                        "(no speed in the export, stale units, position jumps, sparse fixes).",
                    )
                )
            )
            rows = []
            for r in spared:
                sp = r["spare"]
                causes = ", ".join(f"{k} {v:.0f} s" for k, v in sp["doubt_by_cause_s"].items() if v >= 0.5)
                rows.append(
                    [
                        r["crossing"],
                        r["train"],
                        num_or_dash(r["lead_time_s"], "{:.0f}"),
                        num_or_dash(r["warning_time_s"], "{:.0f}"),
                        num_or_dash(sp["spare_s"], "{:.0f}"),
                        num_or_dash(sp["physics_s"], "{:.0f}"),
                        num_or_dash(sp["doubt_s"], "{:.0f}"),
                        causes or "–",
                        str(r["released_warnings"]) if r["released_warnings"] else "–",
                    ]
                )
            cols = [("Crossing", False), ("Train", False), ("Lead s", True), ("Required s", True), ("Spare s", True)]
            cols += [("Physics s", True), ("Doubt s", True), ("Doubt by cause", False), ("Released", True)]
            out.append(table_block(cols, rows))
    alarms = [e for e in cr["events"] if e["kind"] == "alarm"]
    if alarms:
        out.append(Heading(3, f"Alarms ({len(alarms)})", "crossing-alarms"))
        rows = [[show_time(e["time"]), e["crossing"], e["train"], e["reason"]] for e in alarms]
        out.append(table_block([("Time", False), ("Crossing", False), ("Train", False), ("Alarm", False)], rows))
    if cr["trains"]:
        out.append(Heading(3, "Trains followed", "crossing-trains"))
        rows = [
            [t["train"], ", ".join(t["head"]), ", ".join(t["eot"]), num_or_dash(t["length_m"])] for t in cr["trains"]
        ]
        out.append(
            table_block([("Train", False), ("Head units", False), ("EOT units", False), ("Length m", True)], rows)
        )
    out += _integrity_part(cr.get("integrity") or [], day)
    return out


def _integrity_part(timelines: list[dict[str, Any]], day: str | None) -> list[Block]:
    out: list[Block] = [Heading(3, "Train integrity", "crossing-integrity")]
    out.append(
        Para(
            (
                "Whole: the EOT unit rides a train length behind the head at the head's speed. Doubtful: a unit "
                "stale, or one fix out of line. Parted: the EOT fell behind and slowed (two fixes in a row, or one "
                "both behind and slower), or a counting head short of the consist's axles with the section behind "
                "it left occupied. Every change with its evidence.",
            )
        )
    )
    if not timelines:
        out.append(Para(("No train could be judged: no train had both a head and an EOT unit reporting.",)))
        return out
    rows: list[list[Cell]] = []
    for tl in timelines:
        for ch in tl["changes"]:
            state: Cell = Styled(ch["state"], "unsafe") if ch["state"] == "parted" else ch["state"]
            rows.append(
                [tl["train"], _clock(ch["time"], day), state, ", ".join(ch["witnesses"]), "; ".join(ch["evidence"])]
            )
    cols = [("Train", False), ("Time", False), ("State", False), ("Witness", False), ("Evidence", False)]
    out.append(table_block(cols, rows))
    return out


def outline(doc: dict[str, Any]) -> list[Block]:
    """The report as blocks, in the order every format shows them."""
    s = doc["safety"]
    t = doc["inputs"]["totals"]
    verdict = doc["verdict"]
    summary = {
        UNSAFE: f"{s['unsafe']} unsafe, {s['failing']} failing",
        FAILING: f"{s['failing']} failing, nothing unsafe",
        "ok": "nothing unsafe or failing",
    }[verdict]
    blocks: list[Block] = [
        Heading(1, "trackside report", "top"),
        Para(
            (
                f"Layout: {doc['layout'] or 'none'}. Inputs: {count(t['files'], 'file')}, {t['read']} read. "
                f"trackside {doc['trackside_version']}, schema {doc['schema']}.",
            )
        ),
        *([Para((f"About: {doc['scope']}.",))] if doc.get("scope") else []),
        Para((Styled(f"Verdict: {verdict.upper()}", f"verdict-{verdict}"), f" ({summary}).")),
    ]
    for part in (_safety_part, _inputs_part, _devices_part, _passages_part, _sections_part, _health_part):
        blocks += part(doc)
    blocks += _crossings_part(doc)
    blocks += trends_part(doc)  # only a report from the archive has them
    blocks += forecast_part(doc)
    return blocks


def _spacing_text(settings: dict[str, Any]) -> str:
    """``0.13 m``, or with the heads of another spacing: ``0.13 m (WS1 0.2 m)``."""
    own = settings.get("head_spacing_m") or {}
    others = ", ".join(f"{head} {m:g} m" for head, m in own.items())
    return f"{settings['spacing_m']:g} m" + (f" ({others})" if others else "")
