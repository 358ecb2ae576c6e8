"""DuckDB as the archive uses it: its compiled engine (:func:`engine`), and what every connection and session is
set to."""

from __future__ import annotations

import importlib
from typing import Any

# Every connection: no extension fetched or loaded behind the user's back.
DUCKDB_CONFIG: dict[str, Any] = {"autoinstall_known_extensions": False, "autoload_known_extensions": False}
# Every session (a connection, a cursor): no progress bar. DuckDB draws it on standard output after two seconds
# of a query, where it would land inside the JSON or CSV written there.
NO_PROGRESS_BAR = "SET enable_progress_bar = false"


def engine() -> Any:
    """DuckDB's compiled engine: the ``_duckdb`` module where DuckDB ships it apart (2.x), else the package.

    Connecting, running a statement and fetching its rows as Python values need only the engine; the package's
    Python layer (relations, expressions) takes ~60 ms to import, a fifth of a short ``trackside query``.  Its
    connections are the package's own class, which importing the package completes (``sql``, Arrow results).
    """
    try:
        return importlib.import_module("_duckdb")
    except ImportError:  # DuckDB 1.x: the engine is inside the package
        return importlib.import_module("duckdb")
