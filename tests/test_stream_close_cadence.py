"""A read of files closes passages every few chunks (``FILE_CLOSE_EVERY_CHUNKS``) and analyses them on a worker
thread, a live source after every chunk, at once: the passages and the late records are the same either way,
only in fewer batches."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from benchmarks.gen_realistic_diag import generate
from console.analysis.passages.speed_settings import SpeedSettings
from console.analysis.passages.stream import PassageStream, concat_passages, take_passages
from parsers.diag.read import DiagReader


def _streamed(path: Path, every: int, chunk_bytes: int, aside: bool = False) -> tuple[dict[str, np.ndarray], int, int]:
    """The passages (by head, then start), their number of batches, and the late records."""
    reader = DiagReader([path], chunk_bytes=chunk_bytes)
    stream = PassageStream(reader.registry, SpeedSettings(), close_every_chunks=every, analyse_aside=aside)
    parts = []
    for chunk in reader.chunks():
        parts += [stream.add(chunk), *stream.closed_parts()]
    parts += [stream.finish(), *stream.closed_parts(wait=True)]
    batches = [p.passages for p in parts if p is not None and p.passages is not None]
    cols = concat_passages(batches)
    assert cols is not None
    return take_passages(cols, np.lexsort((cols["start_ns"], cols["head"]))), len(batches), stream.late_records


@pytest.mark.parametrize(("resolution", "seed"), [("mixed", 3), ("s", 4), ("us", 5)])
def test_closing_every_few_chunks_gives_the_passages_of_every_chunk(tmp_path: Path, resolution: str, seed: int) -> None:
    path = tmp_path / "log.log"
    generate(20_000, path, boards=6, resolution=resolution, seed=seed)
    each, n_each, late_each = _streamed(path, 1, 40_000)
    fourth, n_fourth, late_fourth = _streamed(path, 4, 40_000)
    aside, n_aside, late_aside = _streamed(path, 4, 40_000, aside=True)
    assert n_aside == n_fourth < n_each  # the cadence was taken: fewer batches
    assert late_each == late_fourth == late_aside == 0
    for other in (fourth, aside):
        assert each.keys() == other.keys()
        for c in each:
            np.testing.assert_array_equal(each[c], other[c], err_msg=c)
