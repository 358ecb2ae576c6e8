"""Metrics for Prometheus: the sink over the live engine's events, `follow --metrics` scraped by a real
Prometheus on loopback, and the alert rules checked by promtool."""

from __future__ import annotations

import json
import signal
import subprocess
import threading
import time
import urllib.parse
import urllib.request
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from prometheus_client.parser import text_string_to_metric_families
from typer.testing import CliRunner

from console.cli.app import app
from console.inputs.base import SourceStatus
from console.layout import load_layout
from console.sinks.metrics import MetricsSink, parse_address
from tests.live_fixtures import REPO, free_port, need, port_open, stop_process, trackside, wait_until

runner = CliRunner()


def _samples(text: str) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    out = {}
    for fam in text_string_to_metric_families(text):
        for s in fam.samples:
            out[(s.name, tuple(sorted(s.labels.items())))] = s.value
    return out


def _value(samples: dict[tuple[str, tuple[tuple[str, str], ...]], float], name: str, **labels: str) -> float:
    return samples[(name, tuple(sorted(labels.items())))]


def test_the_sink_keeps_what_the_events_and_statuses_say() -> None:
    status = SourceStatus("file:/x.log", True, 2.5, 40.0, 1200, 3, 1, 0, "reading")
    sink = MetricsSink(load_layout("example"), lambda: [status])
    for ev in [
        {"type": "section", "section": "1G", "state": "occupied", "count": 8, "reason": "axles in", "time_ns": 1},
        {"type": "section", "section": "1G", "state": "clear", "count": 0, "reason": "counts balance", "time_ns": 2},
        {"type": "passage", "counting_head": "WS1", "axles": 8, "kind": "train"},
        {"type": "passage", "counting_head": "WS1", "axles": 0, "kind": "status"},
        {"type": "passage", "counting_head": "WS2", "axles": 8, "kind": "train"},
        {"type": "crossing", "crossing": "11+850", "train": "T1", "kind": "on"},
        {"type": "crossing", "crossing": "11+850", "train": "T2", "kind": "on"},
        {
            "type": "crossing",
            "crossing": "11+850",
            "train": "T1",
            "kind": "off",
            "lead_s": 52.5,
            "late": True,
            "warning_time_s": 70.0,
        },
        {"type": "health", "severity": "critical", "rule": "faulty_channel", "counting_head": "WS3"},
        {"type": "source", "kind": "rejected", "file": "x", "line": 3, "reason": "bad"},
    ]:
        sink(ev)
    from prometheus_client import generate_latest

    text = generate_latest(sink.registry).decode()
    s = _samples(text)
    assert _value(s, "trackside_section_state", section="1G", state="clear") == 1
    assert _value(s, "trackside_section_state", section="1G", state="occupied") == 0
    assert _value(s, "trackside_section_state", section="B1", state="preparatory") == 1  # as the live engine starts
    assert _value(s, "trackside_section_axles", section="1G") == 0
    assert _value(s, "trackside_section_changes_total", section="1G", state="occupied") == 1
    assert _value(s, "trackside_head_axles_total", counting_head="WS1") == 8
    assert _value(s, "trackside_passages_total", counting_head="WS1") == 1  # the status dump is no train
    assert _value(s, "trackside_crossing_warning", crossing="11+850") == 1  # T2's is still on
    assert _value(s, "trackside_crossing_last_lead_seconds", crossing="11+850") == 52.5
    assert _value(s, "trackside_crossing_late_warnings_total", crossing="11+850") == 1
    assert _value(s, "trackside_crossing_warning_time_seconds", crossing="12+940") == 60
    assert _value(s, "trackside_health_findings_total", severity="critical", rule="faulty_channel") == 1
    assert _value(s, "trackside_health_findings_total", severity="warning", rule="analog_band") == 0
    assert _value(s, "trackside_rejected_lines_total") == 1
    src = {"source": "file:/x.log"}
    assert _value(s, "trackside_source_connected", **src) == 1
    assert _value(s, "trackside_source_last_message_age_seconds", **src) == 2.5
    assert _value(s, "trackside_source_messages_per_second", **src) == 40
    assert _value(s, "trackside_source_lost_total", **src) == 3
    assert _value(s, "trackside_source_malformed_total", **src) == 1
    # Prometheus' conventions: one prefix, counters end in _total, no _created series.
    names = {name for name, _ in s}
    assert all(n.startswith("trackside_") for n in names)
    assert not any(n.endswith("_created") for n in names)
    for fam in text_string_to_metric_families(text):
        assert (fam.type == "counter") == all(x.name.endswith("_total") for x in fam.samples), fam.name


def test_metric_addresses(tmp_path: Path) -> None:
    assert parse_address("127.0.0.1:9108") == ("127.0.0.1", 9108)
    assert parse_address("[::1]:9108") == ("::1", 9108)
    for bad in ("9108", "127.0.0.1:", "127.0.0.1:x", ":9108", "127.0.0.1:70000"):
        res = runner.invoke(app, ["follow", str(tmp_path / "x.log"), "--metrics", bad, "--duration", "0"])
        assert res.exit_code == 2 and "HOST:PORT" in res.output, (bad, res.output)
    res = runner.invoke(app, ["station", "--metrics", "127.0.0.1:9108"])
    assert res.exit_code == 2 and "--metrics goes with --live" in res.output


def test_a_taken_port_is_one_line(tmp_path: Path) -> None:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        res = subprocess.run(
            trackside("follow", str(tmp_path / "x.log"), "--metrics", f"127.0.0.1:{port}", "--duration", "1"),
            capture_output=True,
            text=True,
            timeout=60,
        )
    assert res.returncode == 2 and "cannot listen" in res.stderr and res.stderr.count("\n") == 1


def test_the_station_view_feeds_the_sink(tmp_path: Path) -> None:
    from console.inputs.uri import open_source
    from console.tui.live_source import LiveSource

    log = tmp_path / "d.log"
    log.write_bytes((REPO / "sample_logs" / "example_station.log").read_bytes())
    sink = MetricsSink(load_layout("example"))
    source = LiveSource(load_layout("example"), [open_source(f"file:{log}", from_start=True)], sink=sink)
    try:
        assert wait_until(
            lambda: source.advance(1.0) is not None and sink.head_axles.labels("WS1")._value.get() > 0, 30, 0.2
        )
    finally:
        source.stop()


def test_the_alert_rules_pass_promtool() -> None:
    promtool = need("promtool")
    res = subprocess.run(
        [promtool, "check", "rules", str(REPO / "docs" / "alerts.yml")], capture_output=True, text=True
    )
    assert res.returncode == 0, res.stdout + res.stderr
    assert "SUCCESS: 5 rules found" in res.stdout


@pytest.mark.parametrize(
    ("days_left", "says"),
    [
        ("5.4", "crosses its threshold within the forecast's horizon, or already has: 5.4 days left."),
        # Due by the trend's interval alone (its central line does not worsen): no crossing, no days_left series.
        (
            None,
            "crosses its threshold within the forecast's horizon, or already has: no date yet (the trend's interval"
            " reaches the threshold within the horizon; `trackside forecast --head WS2` shows it).",
        ),
    ],
)
def test_the_forecast_alert_says_the_days_left_or_that_there_is_no_date(
    tmp_path: Path, days_left: str | None, says: str
) -> None:
    """A due series without a crossing date (forecast --textfile writes no days_left for it) was described as
    "…or already has:  days left."."""
    promtool = need("promtool")
    labels = 'target="WS2",channel="2",figure="analog_margin"'
    series = f"      - series: 'trackside_forecast_due{{{labels}}}'\n        values: '1x5'\n"
    if days_left is not None:
        seconds = float(days_left) * 86400  # the textfile's series is in seconds; the alert says days
        series += f"      - series: 'trackside_forecast_time_left_seconds{{{labels}}}'\n        values: '{seconds}x5'\n"
    (tmp_path / "test.yml").write_text(
        f"rule_files:\n  - {REPO / 'docs' / 'alerts.yml'}\nevaluation_interval: 1m\ntests:\n  - interval: 1m\n"
        f"    input_series:\n{series}"
        "    alert_rule_test:\n      - eval_time: 2m\n        alertname: TracksideForecastDue\n"
        "        exp_alerts:\n          - exp_labels:\n"
        "              {severity: warning, target: WS2, channel: '2', figure: analog_margin}\n"
        "            exp_annotations:\n              summary: 'WS2 is due for maintenance (analog_margin)'\n"
        f'              description: "The analog_margin of WS2 Sys2 {says}"\n',
        encoding="utf-8",
    )
    res = subprocess.run([promtool, "test", "rules", str(tmp_path / "test.yml")], capture_output=True, text=True)
    assert res.returncode == 0, res.stdout + res.stderr


# --------------------------------------------------------------------------- a real Prometheus


class Prometheus:
    """Debian's prometheus binary on 127.0.0.1:port with its own config and storage (never the system service)."""

    def __init__(self, workdir: Path, target_port: int) -> None:
        self.binary = need("prometheus")
        self.port = free_port()
        self.conf = workdir / "prometheus.yml"
        self.conf.write_text(
            "global:\n  scrape_interval: 1s\n  evaluation_interval: 1s\n"
            f"rule_files:\n  - {REPO / 'docs' / 'alerts.yml'}\n"
            "scrape_configs:\n  - job_name: trackside\n"
            f"    static_configs:\n      - targets: ['127.0.0.1:{target_port}']\n",
            encoding="utf-8",
        )
        self.proc = subprocess.Popen(
            [
                self.binary,
                f"--config.file={self.conf}",
                f"--storage.tsdb.path={workdir / 'tsdb'}",
                f"--web.listen-address=127.0.0.1:{self.port}",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        if not wait_until(lambda: self._ready(), 30, 0.2):
            self.stop()
            pytest.fail("prometheus did not become ready")

    def _ready(self) -> bool:
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{self.port}/-/ready", timeout=1) as r:
                return bool(r.status == 200)
        except OSError:
            return False

    def api(self, path: str, **params: str) -> Any:
        url = f"http://127.0.0.1:{self.port}/api/v1/{path}?{urllib.parse.urlencode(params)}"
        with urllib.request.urlopen(url, timeout=5) as r:
            doc = json.load(r)
        assert doc["status"] == "success", doc
        return doc["data"]

    def query(self, expr: str) -> dict[str, float]:
        """Instant vector: the series' first distinguishing label → value."""
        out = {}
        for r in self.api("query", query=expr)["result"]:
            labels = {k: v for k, v in r["metric"].items() if k not in ("__name__", "job", "instance")}
            out[",".join(f"{k}={v}" for k, v in sorted(labels.items()))] = float(r["value"][1])
        return out

    def stop(self) -> None:
        stop_process(self.proc)


@pytest.fixture
def followed_run(tmp_path: Path) -> Iterator[tuple[subprocess.Popen[str], list[str], int]]:
    """`follow --metrics` on a simulated live run's growing files; its JSON lines collected as they come."""
    run = tmp_path / "run"
    (run / "nmea").mkdir(parents=True)
    port = free_port()
    follow = subprocess.Popen(
        trackside(
            "follow",
            f"file:{run / 'diagnostic.log'}",
            f"file:{run / 'nmea' / 'T1-head.nmea'}",
            f"file:{run / 'nmea' / 'T1-eot.nmea'}",
            "--from-start",
            "--layout",
            "example",
            "--jsonl",
            "--metrics",
            f"127.0.0.1:{port}",
        ),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    lines: list[str] = []
    assert follow.stdout is not None
    reader = threading.Thread(target=lambda: lines.extend(iter(follow.stdout.readline, "")), daemon=True)  # type: ignore[union-attr]
    reader.start()
    try:
        assert wait_until(lambda: port_open(port), 30), "follow did not serve its metrics"
        yield follow, lines, port
    finally:
        if follow.poll() is None:
            follow.send_signal(signal.SIGTERM)
            try:
                follow.wait(15)
            except subprocess.TimeoutExpired:
                follow.kill()
                follow.wait(5)


@pytest.mark.timeout(240)
def test_prometheus_reads_the_section_changes_and_axle_counts_of_a_live_run(
    tmp_path: Path, followed_run: tuple[subprocess.Popen[str], list[str], int]
) -> None:
    follow, lines, port = followed_run
    prom = Prometheus(tmp_path, port)
    try:
        assert wait_until(lambda: prom.query("up") == {"": 1.0}, 30, 0.5), "prometheus does not scrape follow"
        t0 = time.time()
        sim = subprocess.run(
            trackside(
                "simulate",
                "-o",
                str(tmp_path / "run"),
                "--live",
                "--speed",
                "60",
                "--duration",
                "10m",
                "--trains-per-hour",
                "12",
            ),
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert sim.returncode == 0, sim.stderr
        # follow has read everything once its output stops growing; then the scrapes catch up.
        n = [-1]

        def settled() -> bool:
            done, n[0] = len(lines) == n[0], len(lines)
            return done

        assert wait_until(settled, 60, 3.0)
        events = [json.loads(x) for x in list(lines)]
        axles: Counter[str] = Counter()
        for e in events:
            if e["type"] == "passage":
                axles[e["counting_head"]] += int(e["axles"])
        changes = [e for e in events if e["type"] == "section"]
        assert sum(axles.values()) > 0 and changes, "the simulated run gave no train"
        expected = {f"counting_head={h}": float(n) for h, n in axles.items() if n}

        def axles_seen() -> bool:
            got = prom.query("trackside_head_axles_total > 0")
            return got == expected

        assert wait_until(axles_seen, 20, 0.5), (prom.query("trackside_head_axles_total > 0"), expected)
        # A section's change, as Prometheus recorded it over time: the state the follower reported last,
        # after a different one before it.
        last = changes[-1]
        sid, state = last["section"], last["state"]
        series = prom.api(
            "query_range",
            query=f'trackside_section_state{{section="{sid}",state="{state}"}}',
            start=str(t0 - 5),
            end=str(time.time()),
            step="1",
        )["result"]
        values = [float(v) for _, v in series[0]["values"]]
        assert values[0] == 0.0 and values[-1] == 1.0, values
        counted = Counter((e["section"], e["state"]) for e in changes)
        got = prom.query("trackside_section_changes_total")
        assert got == {f"section={s},state={st}": float(k) for (s, st), k in counted.items()}
    finally:
        prom.stop()
    follow.send_signal(signal.SIGTERM)
    assert follow.wait(30) == 143  # a service stopping: the summary, then 143
