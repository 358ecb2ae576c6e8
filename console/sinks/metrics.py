"""Prometheus metrics from the live engine's events: ``follow --metrics`` and ``station --live --metrics``.

A sink: :meth:`MetricsSink.consume` takes the event dicts the live engine emits (``type`` passage,
section, crossing, health, source: the JSON lines of ``follow --jsonl``) and keeps the metrics they
say; the sources' statuses (connected, last message, rate, losses) are read when Prometheus scrapes.
Nothing here analyses: every number is one an event or a status already carries.  The exposition
(``prometheus_client``) is served on HOST:PORT only, from its own thread; its own registry, so nothing
else of the process leaks in.  Names follow Prometheus' conventions (``trackside_`` prefix, base units,
``_total`` for counters); docs/monitoring.md lists them with the alert rules.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING, Any

from prometheus_client import CollectorRegistry, Counter, Gauge, disable_created_metrics
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily
from prometheus_client.registry import Collector

from console.analysis.sections.state import SectionState

if TYPE_CHECKING:
    from wsgiref.simple_server import WSGIServer

    from console.inputs.base import SourceStatus
    from console.layout import Layout

SECTION_STATES = tuple(str(s) for s in SectionState)
SEVERITIES = ("info", "warning", "critical")
RULES = ("analog_band", "voltage_margin", "disturbance_rate", "faulty_channel", "single_channel")


class MetricsError(Exception):
    """A ``--metrics`` address that cannot be served (bad form, port taken): one line, exit 2."""


def parse_address(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (``127.0.0.1:9108``, ``[::1]:9108``, ``localhost:9108``) → (host, port)."""
    host, sep, port = text.rpartition(":")
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise MetricsError(f"--metrics {text!r}: expected HOST:PORT, e.g. 127.0.0.1:9108")
    return host, int(port)


class _SourceCollector(Collector):
    """Each source's status, read at scrape time (Source.status() takes the source's own lock)."""

    def __init__(self, statuses: Callable[[], Sequence[SourceStatus]]) -> None:
        self.statuses = statuses

    def collect(self) -> Iterator[Any]:
        label = ["source"]
        connected = GaugeMetricFamily("trackside_source_connected", "1 while the source is connected.", labels=label)
        age = GaugeMetricFamily(
            "trackside_source_last_message_age_seconds",
            "Seconds since the source's last message (absent before the first).",
            labels=label,
        )
        rate = GaugeMetricFamily(
            "trackside_source_messages_per_second", "Messages per second over the last 10 s.", labels=label
        )
        counters = {
            "messages": CounterMetricFamily("trackside_source_messages", "Messages received.", labels=label),
            "lost": CounterMetricFamily("trackside_source_lost", "Messages known lost (sequence gaps).", labels=label),
            "malformed": CounterMetricFamily(
                "trackside_source_malformed", "Messages or lines that could not be read.", labels=label
            ),
            "duplicates": CounterMetricFamily(
                "trackside_source_duplicates", "Duplicate messages merged.", labels=label
            ),
        }
        for s in self.statuses():
            connected.add_metric([s.uri], 1.0 if s.connected else 0.0)
            if s.last_message_age_s is not None:
                age.add_metric([s.uri], s.last_message_age_s)
            rate.add_metric([s.uri], s.rate_per_s)
            for name, family in counters.items():
                family.add_metric([s.uri], float(getattr(s, name)))
        yield connected
        yield age
        yield rate
        yield from counters.values()


class MetricsSink:
    """The metrics of one live run (see the module's doc)."""

    def __init__(self, layout: Layout | None, statuses: Callable[[], Sequence[SourceStatus]] = list) -> None:
        # No `_created` series: they double the exposition and say only when this process made the counter.
        disable_created_metrics()
        self.registry = CollectorRegistry(auto_describe=True)
        r = self.registry
        self._lock = threading.Lock()  # events come from the engine's thread, scrapes from the server's
        self.section_state = Gauge(
            "trackside_section_state",
            "1 for the section's current state, 0 for the others (clear, occupied, disturbed, preparatory).",
            ["section", "state"],
            registry=r,
        )
        self.section_axles = Gauge(
            "trackside_section_axles", "Axles counted into the section and not yet out.", ["section"], registry=r
        )
        self.section_changes = Counter(
            "trackside_section_changes",
            "Section state changes, by the state entered.",
            ["section", "state"],
            registry=r,
        )
        self.head_axles = Counter(
            "trackside_head_axles",
            "Axles counted at the counting head (train passages).",
            ["counting_head"],
            registry=r,
        )
        self.passages = Counter(
            "trackside_passages", "Train passages at the counting head.", ["counting_head"], registry=r
        )
        self.warning = Gauge(
            "trackside_crossing_warning",
            "1 while the crossing's warning is on (for any train).",
            ["crossing"],
            registry=r,
        )
        self.warnings = Counter(
            "trackside_crossing_warnings", "Warnings switched on at the crossing.", ["crossing"], registry=r
        )
        self.alarms = Counter("trackside_crossing_alarms", "Alarms raised at the crossing.", ["crossing"], registry=r)
        self.last_lead = Gauge(
            "trackside_crossing_last_lead_seconds",
            "The last warning's lead: head arrival minus warning on (set when the warning goes off).",
            ["crossing"],
            registry=r,
        )
        self.warning_time = Gauge(
            "trackside_crossing_warning_time_seconds",
            "The warning time the crossing promises road users.",
            ["crossing"],
            registry=r,
        )
        self.late = Counter(
            "trackside_crossing_late_warnings", "Warnings on for less than the warning time.", ["crossing"], registry=r
        )
        self.findings = Counter(
            "trackside_health_findings", "Health findings, by severity and rule.", ["severity", "rule"], registry=r
        )
        self.rejected = Counter(
            "trackside_rejected_lines",
            "Input lines rejected by the parsers (file, line and reason in the log).",
            registry=r,
        )
        r.register(_SourceCollector(statuses))
        self._on: dict[str, set[str]] = {}
        for sev in SEVERITIES:  # present from the start: increase() needs the zero before the first finding
            for rule in RULES:
                self.findings.labels(sev, rule)
        if layout is not None:
            for s in layout.sections:  # the live engine starts every section preparatory
                self._set_state(s.id, str(SectionState.PREPARATORY))
                self.section_axles.labels(s.id).set(0)
            for c in layout.crossings:
                self.warning.labels(c.code).set(0)
                self.warning_time.labels(c.code).set(c.warning_time_s)
                self.warnings.labels(c.code)
                self.late.labels(c.code)
                self.alarms.labels(c.code)
            for h in layout.heads:
                self.head_axles.labels(h.id)
                self.passages.labels(h.id)
        self._server: WSGIServer | None = None
        self._thread: threading.Thread | None = None

    # -- the events ----------------------------------------------------------
    def consume(self, ev: dict[str, Any]) -> None:
        kind = ev.get("type")
        with self._lock:
            if kind == "section":
                self._set_state(str(ev["section"]), str(ev["state"]))
                self.section_axles.labels(str(ev["section"])).set(float(ev["count"]))
                self.section_changes.labels(str(ev["section"]), str(ev["state"])).inc()
            elif kind == "passage":
                head = str(ev.get("counting_head"))
                self.head_axles.labels(head).inc(int(ev.get("axles") or 0))
                if ev.get("kind") != "status":  # a board's status dump makes a passage too; not a train
                    self.passages.labels(head).inc()
            elif kind == "crossing":
                self._crossing(ev)
            elif kind == "health":
                self.findings.labels(str(ev.get("severity")), str(ev.get("rule"))).inc()
            elif kind == "source" and ev.get("kind") == "rejected":
                self.rejected.inc()

    __call__ = consume

    def _set_state(self, section: str, state: str) -> None:
        for s in SECTION_STATES:
            self.section_state.labels(section, s).set(1.0 if s == state else 0.0)

    def _crossing(self, ev: dict[str, Any]) -> None:
        code, train, what = str(ev["crossing"]), str(ev["train"]), ev.get("kind")
        on = self._on.setdefault(code, set())
        if what == "on":
            on.add(train)
            self.warnings.labels(code).inc()
        elif what == "off":
            on.discard(train)
            if ev.get("lead_s") is not None:
                self.last_lead.labels(code).set(float(ev["lead_s"]))
            if ev.get("warning_time_s") is not None:
                self.warning_time.labels(code).set(float(ev["warning_time_s"]))
            if ev.get("late"):
                self.late.labels(code).inc()
        elif what == "alarm":
            self.alarms.labels(code).inc()
        self.warning.labels(code).set(1.0 if on else 0.0)

    # -- the endpoint ---------------------------------------------------------
    def serve(self, address: str) -> tuple[str, int]:
        """Serve ``/metrics`` on HOST:PORT (that address only) from a daemon thread; (host, port) bound."""
        from prometheus_client import start_http_server

        host, port = parse_address(address)
        try:
            self._server, self._thread = start_http_server(port, addr=host, registry=self.registry)
        except OSError as exc:
            raise MetricsError(f"--metrics {address}: cannot listen ({exc.strerror or exc})") from None
        return host, int(self._server.server_port)

    def close(self) -> None:
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
            self._server = None
        if self._thread is not None:
            self._thread.join(5)
            self._thread = None


def forecast_exposition(items: Sequence[Any]) -> bytes:
    """``forecast --textfile``: the forecasts in the exposition format, for node_exporter's textfile collector
    (a cron job's metrics): per series whether it is due and the time left.  The command writes it through
    ``console.output_path`` (atomically, never over a device, a FIFO or the archive's own files)."""
    from prometheus_client import generate_latest

    disable_created_metrics()
    r = CollectorRegistry()
    labels = ["target", "channel", "figure"]
    due = Gauge("trackside_forecast_due", "1 when the series is due for maintenance (or past).", labels, registry=r)
    # Seconds, Prometheus' base unit: promtool flags a `_days` name (it was trackside_forecast_days_left).
    left = Gauge(
        "trackside_forecast_time_left_seconds",
        "Seconds from the archive's last day to the forecast crossing (negative: past).",
        labels,
        registry=r,
    )
    status = Gauge("trackside_forecast_series", "Series forecast, by status.", ["status"], registry=r)
    counts: dict[str, int] = {s: 0 for s in ("past", "due", "watch", "unknown", "ok")}
    for f in items:
        key = (f.target, "" if f.channel is None else str(f.channel), f.figure)
        due.labels(*key).set(1.0 if f.due else 0.0)
        if f.crossing_ns is not None:
            left.labels(*key).set((f.crossing_ns - f.from_ns) / 1e9)
        counts[f.status] = counts.get(f.status, 0) + 1
    for s, n in counts.items():
        status.labels(s).set(n)
    Gauge("trackside_forecast_last_run_timestamp_seconds", "When the forecast ran.", registry=r).set_to_current_time()
    return generate_latest(r)
