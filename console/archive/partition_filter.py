"""The partition keys (days, devices) a query fixes, read from DuckDB's parse of it where that is certain: the
connection made for that query (console.archive.views) lists only those partitions' parts."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from console.archive.duck import engine
from console.archive.tables import TABLES

if TYPE_CHECKING:
    import duckdb


def partition_filter(con: duckdb.DuckDBPyConnection, sql: str) -> dict[str, dict[str, str]]:
    """The partition keys a query fixes, per table: ``{"records": {"day": "2026-03-02", "device_id": "5001"}}``.

    Only when it is certain, from DuckDB's own parse of the query: one SELECT whose only reference
    to the table is its FROM (no join, no CTE, no other mention anywhere, subqueries included), and
    ``day = DATE '…'`` / ``day = '…'`` or ``device_id = <integer>`` among the top-level AND terms of
    its WHERE.  Anything else gives nothing (every part is listed, as without this).
    """
    import json

    try:
        doc = json.loads(con.execute("SELECT json_serialize_sql(?)", [sql]).fetchone()[0])  # type: ignore[index]
    except (engine().Error, TypeError, ValueError):
        return {}
    statements = doc.get("statements") or []
    if doc.get("error") or len(statements) != 1:
        return {}
    node = statements[0].get("node") or {}
    source = node.get("from_table") or {}
    table = str(source.get("table_name", "")).lower()
    keys = TABLES.get(table) if source.get("type") == "BASE_TABLE" and not source.get("schema_name") else None
    if not keys or node.get("type") != "SELECT_NODE" or (node.get("cte_map") or {}).get("map"):
        return {}
    if _mentions(doc, table) != 1:
        return {}
    found: dict[str, str] = {}
    for term in _and_terms(node.get("where_clause")):
        if term.get("type") != "COMPARE_EQUAL":
            continue
        for col, other in ((term.get("left"), term.get("right")), (term.get("right"), term.get("left"))):
            name = _column_name(col, table, source.get("alias", ""))
            value = _key_value(name, other) if name in keys else None
            if name is not None and value is not None:
                found[name] = value
    return {table: found} if found else {}


def _mentions(node: object, table: str) -> int:
    """How many times the parsed query refers to ``table`` (as a table, anywhere)."""
    if isinstance(node, list):
        return sum(_mentions(x, table) for x in node)
    if not isinstance(node, dict):
        return 0
    here = int(node.get("type") == "BASE_TABLE" and str(node.get("table_name", "")).lower() == table)
    return here + sum(_mentions(v, table) for v in node.values())


def _and_terms(expr: object) -> list[dict[str, Any]]:
    if not isinstance(expr, dict):
        return []
    if expr.get("type") == "CONJUNCTION_AND":
        return [t for child in expr.get("children") or [] for t in _and_terms(child)]
    return [expr]


def _column_name(expr: object, table: str, alias: str) -> str | None:
    """``day``, ``records.day`` or ``r.day`` (the FROM's alias) as ``day``; anything else None."""
    if not isinstance(expr, dict) or expr.get("type") != "COLUMN_REF":
        return None
    names = [str(n) for n in expr.get("column_names") or []]
    if len(names) == 1 or (len(names) == 2 and names[0].lower() in {table, alias.lower()} - {""}):
        return names[-1].lower()
    return None


def _key_value(key: str, expr: object) -> str | None:
    """The partition directory's value for ``key = expr``, when expr is a literal of the key's type."""
    import datetime as dt

    if isinstance(expr, dict) and expr.get("type") == "OPERATOR_CAST":
        type_name = str((expr.get("type_expr") or {}).get("type_name", "")).upper()
        if key != "day" or type_name != "DATE":
            return None
        expr = expr.get("child")
    if not isinstance(expr, dict) or expr.get("type") != "VALUE_CONSTANT":
        return None
    literal = expr.get("literal") or {}
    text = str(literal.get("text", ""))
    if key == "day" and literal.get("kind") == "STRING" and len(text) == 10:
        try:
            return dt.date.fromisoformat(text).isoformat()
        except ValueError:
            return None
    if key == "device_id" and literal.get("kind") == "INTEGER" and text.lstrip("-").isdigit():
        return str(int(text))
    return None
