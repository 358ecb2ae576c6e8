"""A deterministic, seeded mutator for the fuzz suite, and the properties every output must keep.

``mutate(data, seed)`` turns a shipped sample into damaged input the way the
world damages it: bit flips, inserted and deleted bytes, truncation,
repeated lines, extreme numbers and dates and hostile strings put into
fields, other encodings (UTF-16 with and without BOM, Latin-1), other line
ends (CRLF, CR), gzip (whole, truncated, junk after the end).  The same
seed always gives the same bytes, so a failure is reproduced from the seed
Hypothesis prints.
"""

from __future__ import annotations

import codecs
import gzip
import json
import os
import random
import re
from collections import Counter
from collections.abc import Callable

from hypothesis import HealthCheck, settings

# `pytest --hypothesis-profile long` (tests/conftest.py: 2,000) raises the default above Hypothesis' 100;
# CI keeps each test's small count, the long run multiplies it by default/100 (x20).
LONG = settings().max_examples >= 1000
TRIED: Counter[str] = Counter()  # inputs run per test, written to $TRACKSIDE_FUZZ_STATS by write_stats()


def fuzz_settings(ci_examples: int) -> settings:
    """Small and derandomized (the same inputs every run) in CI; x20 and random in the long run."""
    return settings(
        max_examples=ci_examples * settings().max_examples // 100 if LONG else ci_examples,
        derandomize=not LONG,
        deadline=None,
        database=None,
        suppress_health_check=list(HealthCheck),
    )


# Numbers that break naive int()/float() use: beyond int64, thousands of digits, signed zero, non-finite.
EXTREME_NUMBERS = [
    str(2**64),
    str(2**63),
    str(-(2**63) - 1),
    "9" * 5000,
    "-0",
    "-0.0",
    "nan",
    "NaN",
    "inf",
    "-Infinity",
    "1e308",
    "-1e308",
    "1e-320",
    "1e999",
    "0x7fffffffffffffff",
    "0000000000000000000000000001",
    "1_000",
    "\u0663\u0664",  # Arabic-Indic digits: int() takes them, a log never has them
    "",
    " ",
    "+",
    "-",
    ".",
]
# Dates at and beyond pandas' datetime64[ns] range (1677-09-21 .. 2262-04-11), impossible ones.
EXTREME_DATES = [
    "0001-01-01",
    "1677-09-21",
    "1677-09-20",
    "2262-04-11",
    "2262-04-12",
    "9999-12-31",
    "0000-00-00",
    "2015-02-29",
    "2016-02-29",
    "2015-13-01",
    "2015-10-32",
    "+10000-01-01",
    "1970-01-01",
]
EXTREME_TIMES = [
    "00:00:00",
    "23:59:60",
    "24:00:00",
    "99:99:99",
    "09:32:24.9999999999999",
    "-1:00:00",
    "09:32",
    "0001-01-01T00:00:00Z",
    "1677-09-21T00:12:43.145224191Z",
    "2262-04-11T23:47:16.854775808Z",
    "9999-12-31T23:59:59.999999999+14:00",
]
# Strings that must stay data: Rich markup, terminal escapes (SGR, OSC title, OSC 8 link, C1 CSI),
# bidi overrides and isolates, HTML, NUL, a lone surrogate (written as its invalid UTF-8 bytes).
HOSTILE_STRINGS = [
    "[bold red]PWNED[/]",
    "[/]",
    "[link=http://evil.example]x[/link]",
    "\x1b[31mred\x1b[0m",
    "\x1b]0;owned title\x07",
    "\x1b]8;;http://evil.example\x1b\\link\x1b]8;;\x1b\\",
    "\x9b31m",
    "\u202eevil\u202c",
    "\u2066x\u2069",
    "\u200f\u200e\u061c",
    "<script>alert(1)</script>",
    "</td></tr><img src=x onerror=alert(1)>",
    "\x00",
    "a\x00b",
    "\ud800",
    "\u2028\u2029",
    "\ufeff",
    "%s%n%x",
    "'\"\\",
    "\u00e4\u00f6\u00fc\u1ecb\U0001f686",
    "\r",
    "\t\t\t",
]
LONG_LINE_CHARS = 200_000  # past any line a record can have; the 4 MiB limit itself is tested in test_sources


def _encode(text: str) -> bytes:
    return text.encode("utf-8", errors="surrogatepass")


# A field is the value after ':' or '=' or between delimiters.
_FIELD_RE = re.compile(rb"(?<=[:=,;\t ])[^:=,;\t \r\n]+")


def _replace_field(data: bytes, rng: random.Random) -> bytes:
    fields = list(_FIELD_RE.finditer(data[:200_000]))
    if not fields:
        return data
    m = rng.choice(fields)
    pool = rng.choice([EXTREME_NUMBERS, EXTREME_DATES, EXTREME_TIMES, HOSTILE_STRINGS])
    return data[: m.start()] + _encode(rng.choice(pool)) + data[m.end() :]


def _bit_flips(data: bytes, rng: random.Random) -> bytes:
    if not data:
        return data
    out = bytearray(data)
    for _ in range(rng.randint(1, 8)):
        i = rng.randrange(len(out))
        out[i] ^= 1 << rng.randrange(8)
    return bytes(out)


def _insert(data: bytes, rng: random.Random) -> bytes:
    i = rng.randint(0, len(data))
    choice = rng.random()
    if choice < 0.4:
        piece = bytes(rng.randrange(256) for _ in range(rng.randint(1, 16)))
    elif choice < 0.9:
        piece = _encode(rng.choice(HOSTILE_STRINGS))
    else:
        piece = b"\n" + b"A" * LONG_LINE_CHARS + b"\n"
    return data[:i] + piece + data[i:]


def _delete(data: bytes, rng: random.Random) -> bytes:
    if not data:
        return data
    i = rng.randrange(len(data))
    return data[:i] + data[i + rng.randint(1, 64) :]


def _truncate(data: bytes, rng: random.Random) -> bytes:
    return data[: rng.randint(0, len(data))]


def _repeat_line(data: bytes, rng: random.Random) -> bytes:
    lines = data.split(b"\n")
    i = rng.randrange(len(lines))
    lines[i:i] = [lines[i]] * rng.randint(1, 50)
    return b"\n".join(lines)


def _line_ends(data: bytes, rng: random.Random) -> bytes:
    end = rng.choice([b"\r\n", b"\r", b"\n\r"])
    return data.replace(b"\r\n", b"\n").replace(b"\n", end)


def _reencode(data: bytes, rng: random.Random) -> bytes:
    text = data.decode("utf-8", errors="replace")
    encoding = rng.choice(["utf-16-le", "utf-16-be", "latin-1", "cp1252"])
    body = text.encode(encoding, errors="replace")
    if encoding.startswith("utf-16") and rng.random() < 0.5:
        body = (codecs.BOM_UTF16_LE if encoding.endswith("le") else codecs.BOM_UTF16_BE) + body
    elif rng.random() < 0.2:
        body = codecs.BOM_UTF8 + data
    return body


def _gzip(data: bytes, rng: random.Random) -> bytes:
    packed = gzip.compress(data, compresslevel=1, mtime=0)
    choice = rng.random()
    if choice < 0.4:
        return packed
    if choice < 0.7:
        return packed[: rng.randint(2, len(packed))]  # truncated
    if choice < 0.85:
        return packed + bytes(rng.randrange(256) for _ in range(rng.randint(1, 20)))  # junk after the end
    flipped = bytearray(packed)
    flipped[rng.randrange(10, len(flipped)) if len(flipped) > 10 else 0] ^= 0x40
    return bytes(flipped)


# Content damage first; encoding, line ends and compression wrap what it gives.
CONTENT_MUTATIONS: list[Callable[[bytes, random.Random], bytes]] = [
    _replace_field,
    _replace_field,
    _replace_field,
    _bit_flips,
    _insert,
    _delete,
    _truncate,
    _repeat_line,
]
WRAPPERS: list[Callable[[bytes, random.Random], bytes]] = [_line_ends, _reencode, _gzip]


def mutate(data: bytes, seed: int, max_ops: int = 3) -> bytes:
    """Damaged ``data``: 1..max_ops content mutations, then maybe a new encoding, line ends or gzip."""
    rng = random.Random(seed)
    for _ in range(rng.randint(1, max_ops)):
        data = rng.choice(CONTENT_MUTATIONS)(data, rng)
    if rng.random() < 0.4:
        data = rng.choice(WRAPPERS)(data, rng)
    return data


def describe(seed: int, max_ops: int = 3) -> str:
    """The mutations a seed applies, for a failure message."""
    rng = random.Random(seed)
    names = []
    for _ in range(rng.randint(1, max_ops)):
        names.append(rng.choice(CONTENT_MUTATIONS).__name__.lstrip("_"))
    return "+".join(names)


# ------------------------------------------------------------------ properties

# What may never reach a reader raw: C0 controls but tab/LF, DEL, C1, bidi controls, surrogates, line separators,
# invisible characters.
UNSAFE_CHARS = re.compile(
    r"[\x00-\x08\x0b-\x1f\x7f-\x9f\u061c\u180e\u200b-\u200f\u2028-\u202e\u2060-\u206f\ufeff\ud800-\udfff\U000e0000-\U000e007f]"
)
# In text output only SGR escapes (colours) are allowed; CliRunner output is not a terminal, so none appear.
SGR = re.compile(r"\x1b\[[0-9;]*m")


def unsafe_in(text: str) -> list[str]:
    """The unsafe characters in text meant for a terminal (SGR colour escapes allowed)."""
    return sorted({repr(m.group()) for m in UNSAFE_CHARS.finditer(SGR.sub("", text))})


def write_stats() -> None:
    """Append the inputs tried per test to the file named by $TRACKSIDE_FUZZ_STATS (the long run's tally)."""
    target = os.environ.get("TRACKSIDE_FUZZ_STATS")
    if target and TRIED:
        with open(target, "a", encoding="utf-8") as f:
            for test, n in sorted(TRIED.items()):
                f.write(f"{n}\t{test}\n")
        TRIED.clear()


EXTREME_VALUES = [*EXTREME_NUMBERS, *EXTREME_DATES, *EXTREME_TIMES, *HOSTILE_STRINGS]


def field_variants(data: bytes, keep_lines: int = 3, record_lines: int = 2) -> bytes:
    """The sample's first ``keep_lines`` lines (comments, header, a good record) as they are, then
    ``record_lines`` record lines repeated with each field in turn replaced by each extreme value:
    one line per (field, value), so one parse covers them all."""
    lines = data.split(b"\n")
    out = lines[:keep_lines]
    for line in lines[keep_lines : keep_lines + record_lines]:
        line = line.removesuffix(b"\r")
        spans = {m.span() for regex in (_FIELD_RE, _CELL_RE) for m in regex.finditer(line)}
        for start, end in sorted(spans):
            for value in EXTREME_VALUES:
                out.append(line[:start] + _encode(value).replace(b"\n", b" ") + line[end:])
        out.extend(_json_variants(line))
    return b"\n".join(out) + b"\n"


_CELL_RE = re.compile(rb"(?:(?<=[,;\t ])|^)[^,;\t \r\n]+")  # a whole cell: an ISO time keeps its colons


def _json_variants(line: bytes) -> list[bytes]:
    """A JSON-lines record with each value in turn replaced by each extreme value (as a string and raw)."""
    try:
        doc = json.loads(line)
    except ValueError:
        return []
    if not isinstance(doc, dict):
        return []
    out = []
    for key in doc:
        for value in EXTREME_VALUES:
            as_string = json.dumps({**doc, key: value}, ensure_ascii=False).encode("utf-8", errors="surrogatepass")
            out.append(as_string.replace(b"\n", b" "))
        for raw in ("1e999", "-0", str(2**64), "9" * 400, "null", "[]", "{}", "true"):
            out.append(json.dumps({**doc, key: None}).encode().replace(b"null", raw.encode(), 1))
    return out
