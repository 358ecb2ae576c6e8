"""A realistic multi-board diagnostic export, streamed, with its ground truth.

What a monitoring centre's export looks like, and what the analysis must
survive:

* ``--boards`` evaluation boards (default 40), two counting heads each, all
  interleaved in time order in one file as the exporter writes them;
* each board stamps its records at its own resolution: microseconds,
  milliseconds or whole seconds (``--resolution mixed`` cycles them over the
  boards).  Records that print the same time keep each board's own order,
  but boards interleave at random among themselves (``--interleave-seed``);
* per axle: Radsensor (Adr 026) onset and release on each system, the
  Diagnose register (Adr 024) mirroring them, and the sum counter (Adr 080);
  a status record (Adr 000) every minute while a head is idle;
* trains (the example line's consists) at 20-120 km/h in both directions;
  wheel edge times come from the simulator's own coil model
  (:func:`console.sim.head_reports.coil_edges`), so the truth is the simulator's;
* about one line in 2000 is an extra, damaged line (cut short, a year out of
  range, binary junk): it must be rejected, and it never replaces a record.

The output streams in blocks of simulated time (constant memory); the truth
(axles and passages per head) goes to ``--truth`` as JSON, every passage to
``--passages`` as JSON lines, also streamed.

    python benchmarks/gen_realistic_diag.py 200000 /tmp/real_200k.log --truth /tmp/real_200k.truth.json
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from console.layout import load_layout  # noqa: E402
from console.sim.head_reports import coil_edges  # noqa: E402

NS = 1_000_000_000
RESOLUTIONS = ("us", "ms", "s")
_RES_NS = {"us": 1_000, "ms": 1_000_000, "s": NS}
SPACING_M = 0.13
BLOCK_S = 600  # simulated seconds formatted at a time
HEARTBEAT_S = 60
QUIET_S = 15.0  # no status record this close to a train: passages stay apart
START = dt.datetime(2026, 3, 2, 0, 0, 0)
CORRUPT_EVERY = 2000

# Registers: (address, label).  Labels as the boards write them (UTF-8 umlaut).
RAD, DIAG, SUM, STATUS = 0, 1, 2, 3
REGISTERS = (("026", "Radsensor"), ("024", "Diagnose"), ("080", "Summenzä"), ("000", "Diagnose I"))


@dataclass
class Board:
    device_id: int
    heads: tuple[str, str]
    resolution: str


@dataclass
class HeadState:
    name: str
    board: int
    next_start_s: float
    next_status_s: float
    sum_counter: int = 0
    busy_until_s: float = -1e9
    axles: int = 0
    passages: int = 0


def _boards(n: int, resolution: str) -> list[Board]:
    out = []
    for b in range(n):
        res = RESOLUTIONS[b % 3] if resolution == "mixed" else resolution
        out.append(Board(5001 + b, (f"WS{2 * b + 1}", f"WS{2 * b + 2}"), res))
    return out


def _iso(t_s: float) -> str:
    return (START + dt.timedelta(seconds=t_s)).isoformat(timespec="microseconds")


class Generator:
    """Per head, trains one after another; events gathered and written block by block."""

    def __init__(
        self, boards: list[Board], seed: int, interleave_seed: int, passages: IO[str] | list[dict[str, object]]
    ) -> None:
        self.boards = boards
        self.rng = np.random.default_rng(seed)
        self.mix = np.random.default_rng(interleave_seed)
        layout = load_layout("example")
        self.consists = [(c.id, np.asarray(c.axles_m)) for c in layout.consists]
        self.heads: list[HeadState] = []
        for b, board in enumerate(boards):
            for name in board.heads:
                first = float(self.rng.uniform(5, 120))
                self.heads.append(HeadState(name, b, first, float(self.rng.uniform(0, HEARTBEAT_S))))
        self.passages = passages  # where each true passage goes: a JSON-lines file, or a list
        # Events (time ns, head index, register, channel, data) not yet written: a later block's.
        self.carry: list[tuple[int, int, int, int, str]] = []

    def _passage(self, k: int, h: HeadState) -> list[tuple[int, int, int, int, str]]:
        cid, axles = self.consists[int(self.rng.integers(len(self.consists)))]
        v_kmh = float(self.rng.uniform(20, 120))
        v = v_kmh / 3.6
        d = 1 if self.rng.random() < 0.5 else -1
        run_m = axles[-1] + 10.0
        dur = run_m / v
        x0 = -d * 5.0
        t0 = h.next_start_s
        edges = coil_edges(0.0, SPACING_M, True, axles, d, x0, x0 + d * run_m, t0, t0 + dur)
        edges.sort(key=lambda e: e[0])
        out: list[tuple[int, int, int, int, str]] = []
        releases_seen = 0
        for t, ch, value in edges:
            t_ns = int(float(t) * NS + 0.5)  # a Python float: numpy scalars round slowly
            out.append((t_ns, k, RAD, ch, str(value)))
            out.append((t_ns, k, DIAG, ch, str(value)))
            if value == 0:
                releases_seen += 1
                if releases_seen % 2 == 0:  # the wheel has left both systems: counted
                    h.sum_counter = (h.sum_counter + 1) % 256
                    out.append((t_ns, k, SUM, 1, str(h.sum_counter)))
        first, last = edges[0][0], edges[-1][0]
        h.axles += len(axles)
        h.passages += 1
        self._truth(
            {
                "head": h.name,
                "device_id": self.boards[h.board].device_id,
                "start": _iso(first),
                "end": _iso(last),
                "axles": len(axles),
                "direction": "sys1_to_sys2" if d > 0 else "sys2_to_sys1",
                "speed_kmh": round(v_kmh, 3),
                "consist": cid,
            }
        )
        h.busy_until_s = last
        h.next_start_s = last + float(self.rng.uniform(30, 240))
        return out

    def _truth(self, passage: dict[str, object]) -> None:
        if isinstance(self.passages, list):
            self.passages.append(passage)
        else:
            self.passages.write(json.dumps(passage) + "\n")

    def block(self, t0_s: float, t1_s: float) -> list[tuple[int, int, int, int, str]]:
        """Every event with a time in [t0, t1), in no particular order."""
        events = self.carry
        for k, h in enumerate(self.heads):
            while h.next_start_s < t1_s:
                events += self._passage(k, h)
            while h.next_status_s < t1_s:
                t = h.next_status_s
                h.next_status_s += HEARTBEAT_S
                if t - h.busy_until_s > QUIET_S and h.next_start_s - t > QUIET_S:
                    events.append((round(t * NS), k, STATUS, 1, "2"))
        end = round(t1_s * NS)
        self.carry = [e for e in events if e[0] >= end]
        return [e for e in events if e[0] < end]


def _order(t_ns: np.ndarray, printed: np.ndarray, board: np.ndarray, mix: np.random.Generator) -> np.ndarray:
    """Write order: by printed time; each board keeps its own order, boards interleave at random."""
    own = np.lexsort((t_ns, board, printed))  # groups (printed, board), each in the board's own order
    p, b = printed[own], board[own]
    gid = np.cumsum(np.r_[True, (p[1:] != p[:-1]) | (b[1:] != b[:-1])]) - 1
    u = mix.random(len(t_ns))  # one random key per position of `own`
    # Groups are contiguous in `own`: the k-th member of a group takes the
    # group's k-th smallest key, so sorting by key keeps each board's order.
    key = np.empty(len(t_ns))
    key[own] = u[np.lexsort((u, gid))]
    return np.lexsort((key, printed))


def _time_texts(printed_ns: np.ndarray, res: np.ndarray, cache: dict[int, tuple[str, str]]) -> list[str]:
    out = []
    start_ns = int((START - dt.datetime(1970, 1, 1)).total_seconds()) * NS
    for p, r in zip(printed_ns.tolist(), res.tolist(), strict=True):
        sec, frac = divmod(p, NS)
        texts = cache.get(sec)
        if texts is None:
            t = dt.datetime(1970, 1, 1) + dt.timedelta(seconds=(start_ns // NS) + sec)
            texts = cache[sec] = (f"{t:%Y-%m-%d}", f"{t:%H:%M:%S}")
            if len(cache) > 100_000:
                cache.clear()
        date, hms = texts
        if r == 0:
            out.append(f"{date}\tTime:{hms}.{frac // 1000:06d}")
        elif r == 1:
            out.append(f"{date}\tTime:{hms}.{frac // 1_000_000:03d}")
        else:
            out.append(f"{date}\tTime:{hms}")
    return out


def _corrupt(line: bytes, rng: np.random.Generator) -> bytes:
    """A damaged line that no reader may take for a record."""
    kind = int(rng.integers(3))
    if kind == 0:  # cut before the seconds of its time: never a shorter valid time
        return line[: int(rng.integers(20, len(line) - 16))]
    if kind == 1:  # a year no timestamp holds (a flipped bit does this)
        return line.replace(b"Date:2026", b"Date:0001", 1)
    return bytes(rng.integers(0, 256, int(rng.integers(8, 80)), dtype=np.uint8)).replace(b"\n", b"\x00")


def generate(
    n_records: int,
    path: Path,
    *,
    boards: int = 40,
    resolution: str = "mixed",
    seed: int = 1,
    interleave_seed: int = 0,
    corrupt: bool = True,
    passages_path: Path | None = None,
    corrupt_every: int = CORRUPT_EVERY,
    block_s: int = BLOCK_S,
) -> dict[str, Any]:
    """Write about ``n_records`` records to ``path``; returns the truth document.

    Every true passage goes to ``passages_path`` (JSON lines) when given, else
    into the document's ``passages`` list (small runs).  ``corrupt_every``
    and ``block_s`` (simulated seconds written at a time: the smallest log)
    let tests write small logs dense with damaged lines.
    """
    board_list = _boards(boards, resolution)
    sink = passages_path.open("w", encoding="utf-8") if passages_path else None
    listed: list[dict[str, object]] = []
    try:
        every = corrupt_every if corrupt else 0
        return _generate(n_records, path, board_list, seed, interleave_seed, every, block_s, sink or listed, listed)
    finally:
        if sink is not None:
            sink.close()


def _generate(
    n_records: int,
    path: Path,
    board_list: list[Board],
    seed: int,
    interleave_seed: int,
    corrupt_every: int,
    block_s: int,
    sink: IO[str] | list[dict[str, object]],
    listed: list[dict[str, object]],
) -> dict[str, Any]:
    gen = Generator(board_list, seed, interleave_seed, sink)
    prefixes = {
        (k, reg, ch): (
            f"Diag_id:00002\tID:{board_list[h.board].device_id}\tDevice:IM\tType:013\tGS:GS03\t"
            f"Trackinfo:{h.name}\tch:{ch}\tAdr:{adr}\tLabel:{label}\tData:"
        )
        for k, h in enumerate(gen.heads)
        for reg, (adr, label) in enumerate(REGISTERS)
        for ch in (1, 2)
    }
    head_board = np.array([h.board for h in gen.heads])
    board_res = np.array([RESOLUTIONS.index(b.resolution) for b in board_list])
    res_ns = np.array([_RES_NS[r] for r in RESOLUTIONS])
    junk = np.random.default_rng(seed + 1)
    cache: dict[int, tuple[str, str]] = {}
    written = corrupt_lines = 0
    t0 = 0.0
    with path.open("wb") as f:
        while True:
            if written < n_records:
                events = gen.block(t0, t0 + block_s)
                t0 += block_s
            elif gen.carry:  # the trains still passing: no truth cut short
                events, gen.carry = gen.carry, []
            else:
                break
            if not events:
                continue
            t_ns = np.array([e[0] for e in events], np.int64)
            head = np.array([e[1] for e in events], np.int64)
            board = head_board[head]
            res = board_res[board]
            printed = t_ns - t_ns % res_ns[res]
            order = _order(t_ns, printed, board, gen.mix)
            times = _time_texts(printed[order], res[order], cache)
            lines = []
            for i, tt in zip(order.tolist(), times, strict=True):
                _, k, reg, ch, data = events[i]
                lines.append(f"{prefixes[k, reg, ch]}{data}\tDate:{tt}")
            data_bytes = ("\n".join(lines) + "\n").encode("utf-8")
            if corrupt_every:
                out = []
                cuts = np.flatnonzero(junk.random(len(lines)) < 1 / corrupt_every)
                if len(cuts):
                    encoded = [line.encode("utf-8") for line in lines]
                    for c in sorted(cuts.tolist(), reverse=True):
                        encoded.insert(int(c), _corrupt(encoded[c], junk))
                    corrupt_lines += len(cuts)
                    out = encoded
                    data_bytes = b"\n".join(out) + b"\n"
            f.write(data_bytes)
            written += len(lines)
    per_head = {h.name: h.axles for h in gen.heads}
    passages = {h.name: h.passages for h in gen.heads}
    return {
        "schema": "trackside.realistic_diag_truth/1",
        "records": written,
        "corrupt_lines": corrupt_lines,
        "lines": written + corrupt_lines,
        "boards": [{"device_id": b.device_id, "heads": list(b.heads), "resolution": b.resolution} for b in board_list],
        "axles_per_head": per_head,
        "axles": sum(per_head.values()),
        "passages_per_head": passages,
        **({"passages": listed} if sink is listed else {}),
    }


def iter_resolutions(spec: str) -> Iterator[str]:
    yield from (RESOLUTIONS if spec == "all" else (spec,))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("records", type=int, help="about how many records to write")
    ap.add_argument("out", type=Path)
    ap.add_argument("--truth", type=Path, help="write the ground truth JSON here")
    ap.add_argument("--passages", type=Path, help="write every true passage here (JSON lines)")
    ap.add_argument("--boards", type=int, default=40)
    ap.add_argument("--resolution", choices=(*RESOLUTIONS, "mixed"), default="mixed")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--interleave-seed", type=int, default=0)
    ap.add_argument("--no-corrupt", action="store_true", help="no damaged lines")
    a = ap.parse_args(argv)
    truth = generate(
        a.records,
        a.out,
        boards=a.boards,
        resolution=a.resolution,
        seed=a.seed,
        interleave_seed=a.interleave_seed,
        corrupt=not a.no_corrupt,
        passages_path=a.passages or Path(os.devnull),
    )
    if a.truth:
        a.truth.write_text(json.dumps(truth, indent=1) + "\n", encoding="utf-8")
    print(
        f"{truth['records']:,} records, {truth['corrupt_lines']} damaged lines, "
        f"{truth['axles']:,} axles, {sum(truth['passages_per_head'].values()):,} passages -> {a.out}",
        file=sys.stderr,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
