"""The derivation's groups of heads: which heads share a pipeline, and how SQL picks a group's records.

The local engine runs one group, the whole line (:data:`LINE`); the Dask engine one per set of sections that
share heads and one per device for the heads no section uses (:func:`plan_groups`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from console.layout import Layout

LINE = "*"  # the local engine's one group: the whole line
# A head as one text in SQL (device id and counting head), and the same made here.
HEAD_KEY = "concat(device_id, '/', coalesce(counting_head, ''))"


def head_key(device_id: int, name: Any) -> str:
    return f"{int(device_id)}/{name if isinstance(name, str) else ''}"


def group_tag(key: str) -> str:
    """A group's key as a short file-name tag."""
    import hashlib

    return hashlib.sha1(key.encode()).hexdigest()[:8]


def group_where(heads: frozenset[tuple[int, Any]] | None, file_seqs: list[int] | None) -> tuple[str, list[Any]]:
    """A WHERE over ``records`` for a group's heads (None: every head) and some files (None: every file)."""
    conds: list[str] = []
    params: list[Any] = []
    if heads is not None:
        # The devices as constants too: DuckDB then reads only their partitions (device_id is a partition key),
        # not every part of the archive once per group.
        devices = ", ".join(str(d) for d in sorted({int(d) for d, _ in heads})) or "NULL"
        conds.append(f"device_id IN ({devices}) AND {HEAD_KEY} IN (SELECT unnest(?))")
        params.append(sorted({head_key(d, h) for d, h in heads}))
    if file_seqs is not None:
        conds.append("file_seq IN (SELECT unnest(?))")
        params.append(list(file_seqs))
    return " AND ".join(conds), params


def group_key_of(layout: Layout | None) -> Callable[[int, Any], str]:
    """The group a head (device id, name) belongs to: the sections sharing heads it bounds (one section engine
    each), else its device (the heads no section uses).  A head's group depends on the head and the layout
    alone, so whoever meets the head first names its group the same."""
    component: dict[str, str] = {}
    if layout is not None:
        parent: dict[str, str] = {}

        def find(x: str) -> str:
            while parent.setdefault(x, x) != x:
                x = parent[x]
            return x

        for sec in layout.sections:
            names = [b.head for b in sec.bounds]
            for other in names[1:]:
                parent[find(other)] = find(names[0])
            find(names[0])
        members: dict[str, list[str]] = {}
        for name in parent:
            members.setdefault(find(name), []).append(name)
        for names in members.values():
            key = "sections:" + "+".join(sorted(names))
            component.update(dict.fromkeys(names, key))

    def key_of(dev: int, name: Any) -> str:
        group = component.get(name) if isinstance(name, str) else None
        return group or f"device:{int(dev)}"

    return key_of


def plan_groups(layout: Layout | None, heads: Iterable[tuple[int, Any]]) -> dict[str, frozenset[tuple[int, Any]]]:
    """The independent groups of heads: the heads of sections that share heads (one section engine each),
    and per device the heads no section uses.  Each runs a pipeline of its own, in parallel."""
    key_of = group_key_of(layout)
    groups: dict[str, set[tuple[int, Any]]] = {}
    for dev, name in heads:
        groups.setdefault(key_of(dev, name), set()).add((int(dev), name))
    return {k: frozenset(v) for k, v in groups.items()}
