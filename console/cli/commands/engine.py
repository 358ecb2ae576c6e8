"""The fleet engine options of ``ingest`` and ``report --archive``, checked and failed in one line."""

from __future__ import annotations

import typer

from console.fleet.options import EngineSpec


def checked_spec(engine: str, workers: int | None, scheduler: str | None) -> EngineSpec:
    """The engine the options name; a bad combination, or ``--engine dask`` without dask: one line, exit 2."""
    from console.cli.common import fail
    from console.fleet.cluster import require_dask
    from console.fleet.options import EngineUsageError, engine_spec

    try:
        spec = engine_spec(engine, workers, scheduler)
        if spec.kind == "dask":
            require_dask()
    except EngineUsageError as exc:
        raise fail(str(exc)) from None
    return spec


def engine_failure(exc: Exception) -> typer.Exit:
    """A :class:`~console.fleet.options.FleetError` (cluster unreachable, workers dying): its line, exit 2."""
    from console.cli.common import fail

    return fail(str(exc))
