"""The event stream counts held records, and settles the bank at the log's end, a slice of whole heads at
a time (for memory, where a log of a million heads settles half a million of each at once): the events
released are the same, in the same order, whatever the slice's size.

The adversarial log of the memory benchmark (every record a new head: half the heads never close a
passage, so their records are held to the end; the other half end with a point-mode onset still waiting)
and a realistic multi-board log, each streamed with slices of one, a few and the default number of rows,
against the batch path's events.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks.bench_many_devices import write_heads_log
from benchmarks.gen_realistic_diag import generate
from console.analysis.counting.wheels import CountingSettings
from console.analysis.diag_events import DiagEventSettings
from console.analysis.events.detection import DetectionEvent
from console.analysis.passages.speed_settings import SpeedSettings
from console.analysis.sections.stream import EventStream
from console.engine.sinks import EventList
from tests.reads import detection_events, pipeline_sections, whole_job

SPEED = SpeedSettings(spacing_m=0.13, train_length_m=28.6, idle_gap_s=10.0)


def _streamed(path: Path, es: DiagEventSettings, chunk_bytes: int) -> list[DetectionEvent]:
    kept = EventList()
    pipeline_sections([path], SPEED, layout=None, event_settings=es, sink=kept, chunk_bytes=chunk_bytes)
    return kept.events


@pytest.mark.parametrize("kind", ["many heads", "realistic"])
def test_counting_a_slice_of_heads_at_a_time_releases_the_same_events(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, kind: str
) -> None:
    path = tmp_path / "log.log"
    if kind == "many heads":
        write_heads_log(path, 3000)
    else:
        generate(3000, path, boards=4, seed=7, interleave_seed=11)
    es = DiagEventSettings(counting=CountingSettings(isolation_s=5.0), power_gap_s=45.0)
    whole, _ = detection_events(whole_job([path], SPEED, keep_releases=True), None, es)
    assert whole
    released = {}
    for rows in (1, 5, 300, EventStream.slice_records):
        monkeypatch.setattr(EventStream, "slice_records", rows)
        released[rows] = _streamed(path, es, chunk_bytes=20_000)
    for rows, events in released.items():
        assert events == whole, rows
