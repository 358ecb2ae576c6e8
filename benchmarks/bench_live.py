"""Live-source targets: latency, station update, idle CPU, sustained rate with bounded memory.

    python benchmarks/bench_live.py latency-file            # line appended → event on stdout
    python benchmarks/bench_live.py latency-mqtt            # message published → event on stdout (needs mosquitto)
    python benchmarks/bench_live.py latency-can             # CAN frame (virtual bus) → passage event
    python benchmarks/bench_live.py station -n 100          # line appended → station view redrawn, painted
    python benchmarks/bench_live.py idle-cpu --seconds 30   # follow with nothing arriving
    python benchmarks/bench_live.py idle-station --seconds 30   # the live station view, nothing arriving
    python benchmarks/bench_live.py rate --rate 2000 --seconds 600   # sustained input, RSS sampled
    python benchmarks/bench_live.py rate-can --rate 2000 --seconds 180  # CAN frames (virtual bus, in-process)

Targets (issue "Live"): latency median ≤ 50 ms and p99 ≤ 200 ms; station view
updated within 250 ms; idle CPU ≤ 2 %; 2,000 records/s for 10 minutes with
bounded memory.

What "event" means: a diagnostic line that starts a new run at its counting
head (the previous record is more than the idle gap + order slack older)
closes the previous run, and ``follow --jsonl`` prints its passage; the
latency is from that line's write to the passage line read from follow's
stdout.  For MQTT, each uplink skips one frame counter, so each one makes
``follow`` print a ``lost`` source event at once.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

CLI = "import sys; from console.cli.app import app; sys.argv[0] = 'trackside'; app()"
T0 = 1_772_438_400  # 2026-03-02 08:00:00


def diag_line(head: int, t_s: float, adr: str = "000", label: str = "Diagnose I", data: str = "2", ch: int = 1) -> str:
    import datetime as dt

    t = dt.datetime(1970, 1, 1) + dt.timedelta(seconds=t_s)
    return (
        f"Diag_id:00002\tID:{4080 + head}\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:WS{head}\tch:{ch}\tAdr:{adr}\t"
        f"Label:{label}\tData:{data}\tDate:{t:%Y-%m-%d}\tTime:{t:%H:%M:%S}.{t.microsecond // 1000:03d}\n"
    )


def percentiles(values: list[float]) -> str:
    v = sorted(values)
    p99 = v[min(len(v) - 1, round(0.99 * (len(v) - 1)))]
    return f"n={len(v)} median={statistics.median(v) * 1000:.1f} ms p99={p99 * 1000:.1f} ms max={v[-1] * 1000:.1f} ms"


def start_follow(*args: str) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [sys.executable, "-c", CLI, "follow", "--jsonl", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        bufsize=1,
    )
    assert proc.stdout is not None
    first = proc.stdout.readline()
    if '"connected"' not in first:
        raise SystemExit(f"follow did not start: {first!r} {proc.stderr.read() if proc.stderr else ''}")
    return proc


def stop(proc: subprocess.Popen[str]) -> str:
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=30)
    return out


def latency_file(n: int, gap_s: float) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "live.log"
        log.write_text("")
        proc = start_follow(f"file:{log}", "--from-start", "--include-status")  # status records: their passages
        assert proc.stdout is not None
        sent: dict[str, float] = {}
        got: list[float] = []
        with log.open("a") as f:
            for k in range(n + 1):
                t_s = T0 + k * 13.5  # > idle gap 10 s + order slack 2 s: each line closes the previous run
                now = time.perf_counter()
                f.write(diag_line(1, t_s))
                f.flush()
                if k:
                    sent[time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(T0 + (k - 1) * 13.5))] = now
                    line = proc.stdout.readline()
                    ev = json.loads(line)
                    while ev.get("type") == "source":  # the follower's note on what the file is read as
                        line = proc.stdout.readline()
                        ev = json.loads(line)
                    arrived = time.perf_counter()
                    if ev.get("type") != "passage":
                        raise SystemExit(f"expected a passage, got {line!r}")
                    got.append(arrived - sent[ev["start"][:19]])
                time.sleep(gap_s)
        stop(proc)
    print(f"latency file → passage on stdout: {percentiles(got)}")


def latency_mqtt(n: int, gap_s: float) -> None:
    import paho.mqtt.client as mqtt

    from parsers.gnss.lora import UnitReport, chirpstack_topic, chirpstack_uplink, encode_payload
    from tests.live_fixtures import Mosquitto

    with tempfile.TemporaryDirectory() as tmp:
        broker = Mosquitto(Path(tmp))
        broker.start()
        try:
            proc = start_follow(f"{broker.url}/application/+/device/+/event/up")
            assert proc.stdout is not None
            pub = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2)
            pub.connect("127.0.0.1", broker.port)
            pub.loop_start()
            eui = "70b3d5e75e000100"
            payload = encode_payload(UnitReport("head", 1, 20.75, 105.9, 10.0, 180.0, 90.0, T0 * 10**9))
            got = []
            for k in range(n):
                doc = json.dumps(chirpstack_uplink(eui, 2 * k, payload, time.time_ns()))
                t = time.perf_counter()
                pub.publish(chirpstack_topic(eui), doc, qos=0)
                if k:
                    while True:
                        ev = json.loads(proc.stdout.readline())
                        if ev.get("kind") == "lost":
                            break
                    got.append(time.perf_counter() - t)
                time.sleep(gap_s)
            pub.loop_stop()
            pub.disconnect()
            stop(proc)
        finally:
            broker.stop()
    print(f"latency mqtt publish → event on stdout: {percentiles(got)}")


def station(n: int) -> None:
    """Line appended → the station view redrawn with its passage and painted (headless Textual app).

    The app's ``refresh_views`` is wrapped to note when a redraw shows a longer event log, and
    ``call_after_refresh`` when that redraw has been painted.  Lines are written at random gaps
    (0.15-0.45 s, so they do not phase-lock with the status timer), and the test loop only sleeps:
    Pilot's ``pause`` waits for every widget's message queue and would slow the app it measures.
    """
    import asyncio
    import random

    from console.inputs.uri import open_source
    from console.layout import load_layout
    from console.tui.live_app import LiveStationApp
    from console.tui.live_source import LiveSource

    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "live.log"
        log.write_text("")
        src = LiveSource(load_layout("example"), [open_source(f"file:{log}", from_start=True)])
        app = LiveStationApp(src)
        painted: list[tuple[float, int]] = []  # (when painted, event-log length drawn)
        redrawn: list[tuple[float, int]] = []  # (when refresh_views returned, event-log length)
        redraw_s: list[float] = []
        refresh = app.refresh_views

        def timed_refresh() -> None:
            t = time.perf_counter()
            refresh()
            redraw_s.append(time.perf_counter() - t)
            shown = len(app.model.log)
            redrawn.append((time.perf_counter(), shown))
            app.call_after_refresh(lambda: painted.append((time.perf_counter(), shown)))

        app.refresh_views = timed_refresh  # type: ignore[method-assign]
        writes: list[tuple[float, int]] = []  # (when written, log length before)
        rng = random.Random(14)

        async def run() -> None:
            async with app.run_test(size=(160, 50)):
                await asyncio.sleep(1.0)
                with log.open("a") as f:
                    for k in range(n + 1):
                        before = len(app.model.log)
                        t = time.perf_counter()
                        f.write(diag_line(2, T0 + k * 13.5))
                        f.flush()
                        if k:  # the first line opens a run; each next one closes the previous: a passage
                            writes.append((t, before))
                        await asyncio.sleep(rng.uniform(0.15, 0.45))
                await asyncio.sleep(1.0)

        asyncio.run(run())
        src.stop()
    for what, marks in (("redrawn (widgets updated)", redrawn), ("painted", painted)):
        got = []
        for t, before in writes:
            shown = [p for p, length in marks if p > t and length > before]
            if not shown:
                raise SystemExit(f"a passage was never {what} (line written at {t:.3f})")
            got.append(shown[0] - t)
        print(f"line appended → station view {what} with its passage: {percentiles(got)}")
    print(f"  one redraw (refresh_views): {percentiles(redraw_s)}; advances: {getattr(app, 'advances', 'n/a')}")


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process (psutil's cpu_times; /proc when psutil is absent)."""
    try:
        import psutil
    except ImportError:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    t = psutil.Process(pid).cpu_times()
    return float(t.user + t.system)


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def idle_cpu(seconds: float) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "live.log"
        log.write_text(diag_line(1, T0))
        proc = start_follow(f"file:{log}", "--from-start", "--layout", "example")
        time.sleep(2)  # settle after start-up
        c0, t0 = cpu_seconds(proc.pid), time.monotonic()
        time.sleep(seconds)
        c1, t1 = cpu_seconds(proc.pid), time.monotonic()
        stop(proc)
    print(f"idle CPU of follow over {t1 - t0:.0f} s: {100 * (c1 - c0) / (t1 - t0):.2f} %")


def rate(records_per_s: int, seconds: float) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "live.log"
        log.write_text("")
        proc = start_follow(f"file:{log}", "--from-start", "--layout", "example")
        assert proc.stdout is not None
        events = [0]

        last_line = [""]

        def drain() -> None:
            assert proc.stdout is not None
            for line in proc.stdout:
                events[0] += 1
                last_line[0] = line

        reader = threading.Thread(target=drain, daemon=True)
        reader.start()
        written = 0
        samples: list[tuple[float, float]] = []
        start = time.monotonic()
        next_sample = start
        with log.open("a") as f:
            k = 0
            while (tick := time.monotonic()) - start < seconds:
                # Written by the clock, not by ticks: a tick the writer was late for is caught up on the next.
                due = min(round((tick - start) * records_per_s), round(seconds * records_per_s))
                lines = []
                while k < due:
                    t_s = T0 + k * (1.0 / records_per_s)
                    # One head at a time for 5 s, like trains passing: each head then rests 15 s,
                    # more than the idle gap, so its passages close and memory is given back.
                    head = 1 + int(k / records_per_s // 5) % 4
                    value = "1" if k % 4 < 2 else "0"
                    lines.append(diag_line(head, t_s, "026", "Radsensor", value, ch=1 + k % 2))
                    k += 1
                f.write("".join(lines))
                f.flush()
                written += len(lines)
                if tick >= next_sample:
                    samples.append((tick - start, rss_mb(proc.pid)))
                    next_sample += 10
                time.sleep(max(0.0, 0.1 - (time.monotonic() - tick)))
        write_s = time.monotonic() - start
        time.sleep(3)
        cpu = cpu_seconds(proc.pid)
        elapsed = time.monotonic() - start
        t_int = time.monotonic()
        proc.send_signal(signal.SIGINT)
        proc.wait(600)
        exit_s = time.monotonic() - t_int  # long if follow had fallen behind (its queue drains first)
        reader.join(10)
    rss = [r for _, r in samples]
    summary = json.loads(last_line[0]) if last_line[0].startswith("{") else {}
    lines_read = sum(f["lines_read"] for f in summary.get("files", []))
    print(
        f"rate: {written} records written in {write_s:.0f} s ({written / write_s:.0f}/s), {lines_read} lines read by"
        f" follow; exit {exit_s:.1f} s after Ctrl-C; {events[0]} events; follow CPU {cpu:.1f} s"
        f" ({100 * cpu / elapsed:.0f} %); RSS MB first/median/max/last:"
        f" {rss[0]:.0f}/{statistics.median(rss):.0f}/{max(rss):.0f}/{rss[-1]:.0f}"
    )
    half = [r for t, r in samples if t >= write_s / 2] or rss[-1:]
    per_min = [f"{r:.0f}" for t, r in samples if round(t) % 60 == 0]
    print(f"  RSS each minute (MB): {' '.join(per_min)}; second half max-min {max(half) - min(half):.1f} MB")


def rate_can(frames_per_s: int, seconds: float) -> None:
    """CAN count frames on python-can's virtual bus (in this process) into the live engine, by the clock.

    Two sensors count trains of 8 axles then send the check byte, endlessly.  Reports whether the
    engine kept up (frames sent but not yet taken, sampled every 0.1 s) and this process's RSS.
    """
    import tomllib
    import uuid

    import can

    from console.inputs.uri import open_source
    from console.layout import layout_from_dict
    from console.live.engine import LiveEngine, run_sources
    from tests.test_live_can import LAYOUT

    lay = layout_from_dict(tomllib.loads(LAYOUT), "bench")
    channel = f"bench-{uuid.uuid4().hex[:8]}"
    src = open_source(f"can:virtual:{channel}")
    engine = LiveEngine(lay, lambda _ev: None)
    done = threading.Event()
    runner = threading.Thread(target=run_sources, args=(engine, [src]), kwargs={"until": done.is_set})
    runner.start()
    while not src.status().connected:
        time.sleep(0.05)
    bus = can.Bus(interface="virtual", channel=channel)
    seq = {7: 0, 8: 0}
    total = {7: 0, 8: 0}
    backlog: list[int] = []
    rss: list[float] = []
    k = 0
    start = time.monotonic()
    while (now := time.monotonic()) - start < seconds:
        while k < round((now - start) * frames_per_s):
            node, c = 7 + k % 2, (k // 2) % 10
            seq[node] = (seq[node] + 1) % 256
            total[node] += c < 8
            status, byte2 = (0, c + 1) if c < 8 else (3, 0xA5)
            data = [status, byte2, total[node] & 0xFF, (total[node] >> 8) & 0xFF, seq[node]]
            bus.send(can.Message(arbitration_id=0x180 + node, data=data, is_extended_id=False))
            k += 1
        backlog.append(k - engine.frames.stats.frames)
        if len(backlog) % 100 == 1:
            rss.append(rss_mb(os.getpid()))
        time.sleep(0.1)
    sent_s = time.monotonic() - start
    t_end = time.monotonic()
    while engine.frames.stats.count_frames < k and time.monotonic() - t_end < 60:
        time.sleep(0.01)
    drain_s = time.monotonic() - t_end
    done.set()
    runner.join(30)
    bus.shutdown()
    st = engine.frames.stats
    print(
        f"can rate: {k} frames sent in {sent_s:.0f} s ({k / sent_s:.0f}/s), {st.count_frames} analysed,"
        f" {st.events} events, {st.passages} passages; not yet taken: median {statistics.median(backlog):.0f},"
        f" max {max(backlog)} frames; all analysed {drain_s * 1000:.0f} ms after the last;"
        f" RSS MB first/max/last {rss[0]:.0f}/{max(rss):.0f}/{rss[-1]:.0f}"
    )


def idle_station(seconds: float) -> None:
    """The live station view (headless, in this process) on a file where nothing arrives: CPU used."""
    import asyncio

    from console.inputs.uri import open_source
    from console.layout import load_layout
    from console.tui.live_app import LiveStationApp
    from console.tui.live_source import LiveSource

    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "live.log"
        log.write_text(diag_line(1, T0))
        src = LiveSource(load_layout("example"), [open_source(f"file:{log}", from_start=True)])
        app = LiveStationApp(src)
        got: list[float] = []

        async def run() -> None:
            async with app.run_test(size=(160, 50)):
                await asyncio.sleep(2)  # settle after start-up
                c0, t0 = cpu_seconds(os.getpid()), time.monotonic()
                await asyncio.sleep(seconds)
                got.append(100 * (cpu_seconds(os.getpid()) - c0) / (time.monotonic() - t0))

        asyncio.run(run())
        src.stop()
    print(f"idle CPU of the live station view (headless) over {seconds:.0f} s: {got[0]:.2f} %")


def latency_can(n: int, gap_s: float) -> None:
    """CAN frame sent (virtual bus, in this process) → the live engine's passage event.

    One axle frame, then the check byte that clears the sensor: the passage is emitted when that
    clear is analysed.  The latency is from sending the check-byte frame to the emit call.
    """
    import tomllib
    import uuid

    import can

    from console.inputs.uri import open_source
    from console.layout import layout_from_dict
    from console.live.engine import LiveEngine, run_sources
    from tests.test_live_can import LAYOUT

    passages: list[float] = []

    def emit(ev: dict[str, object]) -> None:
        if ev["type"] == "passage":
            passages.append(time.perf_counter())

    channel = f"bench-{uuid.uuid4().hex[:8]}"
    src = open_source(f"can:virtual:{channel}")
    engine = LiveEngine(layout_from_dict(tomllib.loads(LAYOUT), "bench"), emit)
    done = threading.Event()
    runner = threading.Thread(target=run_sources, args=(engine, [src]), kwargs={"until": done.is_set})
    runner.start()
    while not src.status().connected:
        time.sleep(0.05)
    bus = can.Bus(interface="virtual", channel=channel)
    got: list[float] = []
    seq = total = 0
    for _ in range(n):
        seq, total = (seq + 1) % 256, total + 1
        bus.send(
            can.Message(arbitration_id=0x187, data=[0, 1, total & 0xFF, total >> 8 & 0xFF, seq], is_extended_id=False)
        )
        time.sleep(gap_s)
        seq, before = (seq + 1) % 256, len(passages)
        t = time.perf_counter()
        bus.send(
            can.Message(
                arbitration_id=0x187, data=[3, 0xA5, total & 0xFF, total >> 8 & 0xFF, seq], is_extended_id=False
            )
        )
        while len(passages) == before and time.perf_counter() - t < 5:
            time.sleep(0.0005)
        if len(passages) > before:
            got.append(passages[before] - t)
        time.sleep(gap_s)
    done.set()
    runner.join(10)
    bus.shutdown()
    print(f"latency can frame → passage event: {percentiles(got)}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    what = ["latency-file", "latency-mqtt", "latency-can", "station", "idle-cpu", "idle-station", "rate", "rate-can"]
    ap.add_argument("what", choices=what)
    ap.add_argument("-n", type=int, default=200)
    ap.add_argument("--gap", type=float, default=0.02, help="seconds between two appends/publishes")
    ap.add_argument("--seconds", type=float, default=30)
    ap.add_argument("--rate", type=int, default=2000)
    a = ap.parse_args()
    if a.what == "latency-file":
        latency_file(a.n, a.gap)
    elif a.what == "latency-mqtt":
        if not (shutil.which("mosquitto") or Path("/usr/sbin/mosquitto").exists()):
            raise SystemExit("mosquitto is not installed")
        latency_mqtt(a.n, a.gap)
    elif a.what == "latency-can":
        latency_can(a.n, max(a.gap, 0.03))
    elif a.what == "station":
        station(a.n)
    elif a.what == "idle-cpu":
        idle_cpu(a.seconds)
    elif a.what == "idle-station":
        idle_station(a.seconds)
    elif a.what == "rate-can":
        rate_can(a.rate, a.seconds)
    else:
        rate(a.rate, a.seconds)


if __name__ == "__main__":
    main()
