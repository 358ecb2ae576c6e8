"""The compiled tokenizer (parsers/diag/compiled_tokens.c) and the numpy one cut every input alike.

Both tokenizers run over the same bytes: their tokens are compared field by field, and whole reads
through each are compared record by record and rejection by rejection (file, line, reason, text).
The inputs: the realistic multi-board generator (µs, ms and whole-second boards, dense with damaged
lines), every sample log, hand-made edge cases, and random lines and bytes.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from benchmarks.gen_realistic_diag import generate
from parsers.diag import read as diag_read
from parsers.diag.gather import gather_compiled, gather_numpy
from parsers.diag.tokens import tokenize_compiled
from parsers.diag.tokens_numpy import tokenize_numpy
from parsers.sources import Chunk
from tests.compiled_parts import needs_compiled
from tests.conftest import SAMPLES, record

try:
    from parsers.diag import compiled_tokens
except ImportError:  # pragma: no cover - depends on the build
    compiled_tokens = None  # type: ignore[assignment]

pytestmark = needs_compiled(compiled_tokens, "parsers.diag.compiled_tokens")

_PER_LINE = ("starts", "ends", "blank")
_PER_FAST_LINE = ("fast", "reg_idx", "val_idx", "time_ok")
_PER_GOOD_TIME = ("tod_ns", "subsecond")  # meaningful where the time was read


def _assert_same_tokens(data: bytes) -> None:
    chunk = Chunk(memoryview(bytearray(data)), final=True)
    want = tokenize_numpy(chunk)
    got = tokenize_compiled(chunk)
    for name in _PER_LINE + _PER_FAST_LINE:
        assert np.array_equal(getattr(got, name), getattr(want, name)), name
    ok = want.time_ok
    for name in _PER_GOOD_TIME:
        assert np.array_equal(getattr(got, name)[ok], getattr(want, name)[ok]), name
    assert got.reg_dict == want.reg_dict
    assert got.val_dict == want.val_dict


def _read_both(
    paths: list[Path], monkeypatch: pytest.MonkeyPatch, **kwargs: object
) -> list[tuple[pd.DataFrame, dict[str, object], list[dict[str, object]]]]:
    out: list[tuple[pd.DataFrame, dict[str, object], list[dict[str, object]]]] = []
    paths_by_kind = (
        (tokenize_numpy, gather_numpy),
        (tokenize_compiled, gather_compiled),
    )
    for tokenize, gather in paths_by_kind:
        with monkeypatch.context() as m:
            m.setattr(diag_read, "_tokenize", tokenize)
            m.setattr(diag_read, "_gather", gather)
            df, report = diag_read.read_diag(paths, **kwargs)
        out.append((df, report.to_dict(), [r.to_dict() for r in report.rejections]))
    return out


def _assert_same_reads(paths: list[Path], monkeypatch: pytest.MonkeyPatch, **kwargs: object) -> int:
    (df_n, rep_n, rej_n), (df_c, rep_c, rej_c) = _read_both(paths, monkeypatch, **kwargs)
    assert df_c.equals(df_n)
    assert rej_c == rej_n
    assert rep_c == rep_n
    return len(df_n)


@pytest.mark.parametrize("resolution", ["mixed", "s", "ms", "us"])
def test_realistic_logs_read_alike(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, resolution: str) -> None:
    log = tmp_path / "real.log"
    generate(6000, log, boards=6, resolution=resolution, seed=3, corrupt_every=40, block_s=120)
    data = log.read_bytes()
    _assert_same_tokens(data)
    # Small chunks: many chunk boundaries, a pool of workers, and lines cut across reads.
    records = _assert_same_reads([log], monkeypatch, chunk_bytes=64 << 10, max_line_bytes=4096)
    assert records > 5000
    _, report = diag_read.read_diag([log])
    assert report.rejected > 50  # the damaged lines were there to be compared


@pytest.mark.parametrize("resolution", ["mixed", "s"])
def test_clean_logs_read_alike(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, resolution: str) -> None:
    """Chunks without a damaged line: every fast line gathered, none selected out."""
    log = tmp_path / "clean.log"
    generate(6000, log, boards=6, resolution=resolution, seed=4, corrupt=False, block_s=120)
    assert _assert_same_reads([log], monkeypatch, chunk_bytes=64 << 10) > 5000


def test_sample_logs_read_alike(monkeypatch: pytest.MonkeyPatch) -> None:
    files = sorted(p for p in SAMPLES.iterdir() if p.is_file())
    for path in files:
        _assert_same_tokens(path.read_bytes() + b"\n")
    assert _assert_same_reads(files, monkeypatch) > 1000


def test_edge_cases_read_alike(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    lines = [
        record(),
        record(time="09:32:24.1"),
        record(time="09:32:24.123456789"),
        record(time="09:32:24.1234567890"),  # ten digits
        record(time="09:32:24."),
        record(time="23:59:59.999999"),
        record(time="24:00:00"),
        record(time="09:60:00.5"),
        record(time="9:32:24"),
        record(time="09:32:24,125"),
        record(time="0a:32:24.125"),
        record(time="09:32:24.12a"),
        record(data="0xD8"),
        record(data="'T'"),
        record(data="x" * 40),
        record(date="31.10.2015"),
        record(date="0001-01-01"),
        record(ch=99),
        record(label=""),
        record() + "\r",
        record(time="09:32:24.125") + "  \r",
        record() + "     ",  # more trailing blanks than the four trimmed
        record() + "\tExtra:1",
        record().replace("\tTime", " Time"),
        record().replace("\tDate", "\t\tDate"),
        record().replace("Time:", "Tim:"),
        record()[:63],
        record()[:64],
        "",
        "   ",
        "\t" * 11,
        "\t" * 70,
        "Time:09:32:24\tTime:09:32:24\tTime:09:32:24\tTime:09:32:24\tTime:09:32:24\t",
    ]
    text = "\n".join(lines)
    for data in (text + "\n", text + "\n" + record()[:50]):  # the last line with and without its newline
        log = tmp_path / "edge.log"
        log.write_bytes(data.encode("utf-8"))
        _assert_same_tokens(data.encode("utf-8") if data.endswith("\n") else data.encode("utf-8") + b"\n")
        _assert_same_reads([log], monkeypatch)


_LINE_PIECES = st.sampled_from(
    [
        record(),
        record(time="09:32:24.125"),
        record(time="09:32:24.125250"),
        record(data="0x1F", time="00:00:00.000000001"),
        "\t",
        "Time:",
        "Date:2015-10-31",
        ":",
        ".",
        "0",
        " ",
        "\r",
        "ä",
    ]
)


@st.composite
def _lines(draw: st.DrawFn) -> bytes:
    """A record cut, joined, spliced or replaced by random bytes."""
    kind = draw(st.integers(0, 3))
    if kind == 0:
        return draw(st.binary(max_size=120)).replace(b"\n", b"")
    line = "".join(draw(st.lists(_LINE_PIECES, min_size=1, max_size=3))).encode("utf-8")
    if kind == 2 and line:
        at = draw(st.integers(0, len(line) - 1))
        line = line[:at] + draw(st.binary(max_size=3)).replace(b"\n", b"") + line[at + 1 :]
    elif kind == 3 and line:
        line = line[: draw(st.integers(0, len(line)))]
    return line


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(lines=st.lists(_lines(), min_size=1, max_size=40), newline=st.booleans())
def test_random_lines_read_alike(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, lines: list[bytes], newline: bool
) -> None:
    data = b"\n".join(lines) + (b"\n" if newline else b"")
    _assert_same_tokens(data if data.endswith(b"\n") else data + b"\n")
    log = tmp_path / "random.log"
    log.write_bytes(data)
    _assert_same_reads([log], monkeypatch, chunk_bytes=512)


@settings(max_examples=100, deadline=None)
@given(data=st.binary(min_size=1, max_size=600))
def test_random_bytes_tokenize_alike(data: bytes) -> None:
    _assert_same_tokens(data if data.endswith(b"\n") else data + b"\n")


def test_compiled_tokenizer_rejects_data_without_newline() -> None:
    assert compiled_tokens is not None
    with pytest.raises(ValueError, match="newline"):
        compiled_tokens.tokenize(b"no newline")
    with pytest.raises(ValueError, match="newline"):
        compiled_tokens.tokenize(b"")


def test_pure_switch_chooses_the_numpy_tokenizer() -> None:
    probe = "from parsers.diag import read; print(read.compiled_tokenizer())"
    env = {k: v for k, v in os.environ.items() if k != "TRACKSIDE_PURE"}
    compiled = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True)
    pure = subprocess.run(
        [sys.executable, "-c", probe], env={**env, "TRACKSIDE_PURE": "1"}, capture_output=True, text=True, check=True
    )
    assert (compiled.stdout.strip(), pure.stdout.strip()) == ("True", "False")


def test_analyze_json_alike_through_the_command(tmp_path: Path) -> None:
    log = tmp_path / "real.log"
    generate(4000, log, boards=4, resolution="mixed", seed=5, corrupt_every=60, block_s=120)
    trackside = Path(sys.executable).with_name("trackside")
    env = {k: v for k, v in os.environ.items() if k != "TRACKSIDE_PURE"}
    outs = [
        subprocess.run(
            [str(trackside), "analyze", "--json", str(log)], env=e, capture_output=True, timeout=120, check=False
        )
        for e in (env, {**env, "TRACKSIDE_PURE": "1"})
    ]
    assert outs[0].returncode == outs[1].returncode == 0, outs[0].stderr
    assert outs[0].stdout == outs[1].stdout
    assert b'"records"' in outs[0].stdout
