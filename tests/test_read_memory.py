"""console.memory.big_read_memory: the allocator settings a big read runs under, and only a big read."""

from __future__ import annotations

from pathlib import Path

import pytest

from console import memory


@pytest.fixture
def thresholds(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    seen: list[int] = []
    monkeypatch.setattr(memory, "fixed_mmap_threshold", seen.append)
    return seen


def _sparse(path: Path, size: int) -> Path:
    with path.open("wb") as f:
        f.truncate(size)  # no data written: the size is what the settings are chosen by
    return path


def test_a_big_read_maps_blocks_from_the_threshold_asked(tmp_path: Path, thresholds: list[int]) -> None:
    big = _sparse(tmp_path / "big.log", memory.BIG_READ_BYTES)
    with memory.big_read_memory([big]):
        pass
    with memory.big_read_memory([big], 1 << 20):
        pass
    assert thresholds == [128 << 10, 1 << 20]


def test_a_small_read_keeps_the_allocator_as_it_is(tmp_path: Path, thresholds: list[int]) -> None:
    small = _sparse(tmp_path / "small.log", memory.BIG_READ_BYTES // 2 - 1)
    with memory.big_read_memory([small, small], 1 << 20):
        pass
    assert thresholds == []
