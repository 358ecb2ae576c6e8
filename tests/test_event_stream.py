"""The event stream releases the batch path's events, one for one, in the batch path's order.

:class:`console.analysis.sections.stream.EventStream` counts each batch of
closed passages (all heads at once) and releases events below a watermark;
:func:`console.jobs.detection_events` counts the whole log.  Over realistic
multi-board logs (µs, ms and whole-second boards, damaged lines) read in
chunks of any size, with and without a power gap and a short isolation
time, the events released (as objects and as columns) must be the batch
path's list exactly: same events, same order.

One case on its own: a damping of one system alone is known to be lone only
when it ends, but when nothing came before it, its hold falls due
``isolation_s`` after it began.  For a damping longer than that the
confirmation (ACCIDENTAL) is earlier than the pulse's own event, and the
batch path sorts it before everything in between: the stream must hold the
other heads' events from that time on until the pulse has ended.

CI runs a few examples; ``TRACKSIDE_LONG=1`` runs many more.
"""

from __future__ import annotations

import os
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from benchmarks.gen_realistic_diag import generate
from console.analysis.counting.wheels import CountingSettings
from console.analysis.diag_events import DiagEventSettings
from console.analysis.events.detection import EventKind
from console.analysis.passages.speed_settings import SpeedSettings
from console.engine.sinks import EventList
from console.layout import Layout, load_layout
from tests.reads import detection_events, pipeline_sections, whole_job

LONG = bool(os.environ.get("TRACKSIDE_LONG"))
SPEED = SpeedSettings(spacing_m=0.13, train_length_m=28.6, idle_gap_s=10.0)


def _streamed(path: Path, layout: Layout | None, es: DiagEventSettings, chunk_bytes: int) -> list:
    """The events as the pipeline releases them to its sinks (read again with the facts learnt when
    the first read guessed a head's facts wrong)."""
    kept = EventList()
    pipeline_sections([path], SPEED, layout=layout, event_settings=es, sink=kept, chunk_bytes=chunk_bytes)
    return kept.events


@settings(
    max_examples=100 if LONG else 4,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(
    records=st.integers(200, 3000 if LONG else 600),
    boards=st.integers(2, 6),
    seed=st.integers(1, 10_000),
    interleave=st.integers(0, 2**31),
    chunk_bytes=st.integers(64, 50_000),
    power_gap=st.sampled_from([None, 5.0, 45.0]),
    isolation=st.sampled_from([5.0, 60.0]),
)
def test_a_realistic_log_streamed_in_any_chunks_releases_the_batch_events_in_order(
    tmp_path: Path,
    records: int,
    boards: int,
    seed: int,
    interleave: int,
    chunk_bytes: int,
    power_gap: float | None,
    isolation: float,
) -> None:
    path = tmp_path / "real.log"
    generate(records, path, boards=boards, seed=seed, interleave_seed=interleave)
    es = DiagEventSettings(counting=CountingSettings(isolation_s=isolation), power_gap_s=power_gap)
    whole, _ = detection_events(whole_job([path], SPEED, keep_releases=True), None, es)
    assert whole
    assert _streamed(path, None, es, chunk_bytes) == whole


def _line(head: str, ch: int, value: int, when: str, device: int) -> str:
    return (
        f"Diag_id:00002\tID:{device}\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:{head}\tch:{ch}\tAdr:026\t"
        f"Label:Radsensor\tData:{value}\tDate:2026-03-02\tTime:{when}\n"
    )


def test_a_single_system_damped_longer_than_the_isolation_time_keeps_the_batch_order(tmp_path: Path) -> None:
    # WS1's Sys1 alone, 09:00:00.100 - 09:01:30: held (INTERFERENCE) at 09:01:30, its hold confirmed
    # accidental at 09:01:00.100, before the wheels WS2 counts at 09:01:05 and 09:01:20.
    lines = [_line("WS1", 1, 1, "09:00:00.100", 4081), _line("WS1", 1, 0, "09:01:30.000", 4081)]
    for second in range(5, 140, 15):
        at = f"09:{second // 60:02d}:{second % 60:02d}"
        lines += [
            _line("WS2", 1, 1, f"{at}.000", 4082),
            _line("WS2", 2, 1, f"{at}.010", 4082),
            _line("WS2", 1, 0, f"{at}.040", 4082),
            _line("WS2", 2, 0, f"{at}.050", 4082),
        ]
    lines.sort(key=lambda x: x.split("Time:")[1])
    path = tmp_path / "long_damping.log"
    path.write_text("".join(lines), encoding="utf-8")
    layout = load_layout("example")
    es = DiagEventSettings()
    whole, _ = detection_events(whole_job([path], SPEED, keep_releases=True), layout, es)
    accidental = next(i for i, e in enumerate(whole) if e.kind is EventKind.ACCIDENTAL)
    assert whole[accidental + 1].head == "WS2"  # confirmed before WS2's wheels of the next minute
    for chunk_bytes in (200, 1000, 100_000):
        assert _streamed(path, layout, es, chunk_bytes) == whole
