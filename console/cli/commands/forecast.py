"""trackside forecast: when each head's and unit's health figures will cross their thresholds."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated

import typer

from console import exit_codes
from console.cli.commands.ingest import ArchiveOpt
from console.cli.common import Console, fail, guard, load_layout, one_json_form, print_document
from console.cli.options import JsonOpt, RecordsJsonlOpt
from console.output_path import STDOUT


def forecast(
    archive: ArchiveOpt = None,
    horizon: Annotated[
        str,
        typer.Option(
            "--horizon",
            metavar="DURATION",
            help="Due: crossing within this time of the archive's last day (30d, 45d…).",
        ),
    ] = "30d",
    head: Annotated[
        str | None,
        typer.Option("--head", metavar="HEAD", help="Only this counting head (or GNSS unit).", show_default=False),
    ] = None,
    layout: Annotated[
        str | None,
        typer.Option(
            "--layout",
            metavar="LAYOUT",
            help="Layout for the analog bands [default: the one the archive was ingested with].",
            show_default=False,
        ),
    ] = None,
    trend_days: Annotated[
        int,
        typer.Option(
            "--trend-days", metavar="N", help="Fit the trend on this many last days of figures.", min=3, max=3650
        ),
    ] = 14,
    show_all: Annotated[bool, typer.Option("--all", help="Also list every series, not only the due ones.")] = False,
    fail_on_due: Annotated[bool, typer.Option("--fail-on-due", help="Exit 1 when anything is due (for cron).")] = False,
    textfile: Annotated[
        Path | None,
        typer.Option(
            "--textfile",
            metavar="FILE",
            help="Also write the forecasts as Prometheus metrics to this file (node_exporter's textfile collector).",
            show_default=False,
        ),
    ] = None,
    json_out: JsonOpt = False,
    jsonl: RecordsJsonlOpt = False,
) -> None:
    """Forecast, from the archive's daily health figures, when each head, channel and GNSS unit will cross
    its threshold: analog values leaving their band, disturbance rates reaching the warning level, units
    losing a quarter of their reports.  Lists what is due for maintenance, by date.
    """
    from console.archive.store import ArchiveError, archive_dir

    root = archive_dir(archive)

    def body() -> int:
        one_json_form(json_out, jsonl)
        from console.analysis.timefmt import parse_duration
        from console.output_path import OutputError, check_output_file, check_outside, open_output

        target = None
        if textfile is not None and os.fsdecode(textfile) == STDOUT:
            # Standard output carries the forecast; "-" would be a file of that name, found by nobody.
            raise fail(
                "--textfile -: give the metrics file's name (node_exporter reads a directory; /dev/stdout: here)"
            )
        if textfile is not None:
            try:  # before any work: never a device replaced, nor a file among the archive's own
                target = check_output_file(textfile, [], what="metrics file")
                check_outside(textfile, root, what="metrics file")
            except OutputError as exc:
                raise fail(f"--textfile {exc}") from None

        try:
            import scipy.stats  # noqa: F401 - the trend's library, an optional extra
        except ImportError:
            raise fail("forecast needs scipy: pip install 'trackside[forecast]'") from None
        from console.analysis.health.forecast import ForecastSettings, due_list
        from console.archive.health_days import archive_forecasts
        from console.archive.reader import Window, names_a_unit
        from console.archive.views import require_archive

        # A bare number would be seconds (as simulate's --duration takes it): for a horizon in days, a slip.
        unitless = horizon.strip().replace(".", "", 1).isdecimal()
        try:
            horizon_days = parse_duration(horizon) / 86_400.0
        except ValueError:
            unitless = True
        if unitless:
            raise fail(f"--horizon {horizon!r}: expected a time with its unit, e.g. 30d (days) or 12h (hours)")
        if not 0 < horizon_days <= 3650:
            raise fail("--horizon: between 1s and 3650d")
        try:
            manifest = require_archive(root)
            spec = layout if layout is not None else manifest.derived.get("layout")
            lay = load_layout(spec) if spec else None
            settings = ForecastSettings(horizon_days=horizon_days, fit_days=trend_days)
            err = Console(stderr=True, highlight=False)
            if err.is_terminal:  # what it is reading, on a terminal (a big archive takes a while)
                with err.status("reading the archive") as status:
                    items, _ = archive_forecasts(
                        root, manifest, Window(head=head), lay, settings, say=lambda text: status.update(text)
                    )
            else:
                items, _ = archive_forecasts(root, manifest, Window(head=head), lay, settings)
            if head is not None and not items and not names_a_unit(root, manifest, head):
                # "Nothing is due" of a name the archive never saw (a typo) would read as good news.
                raise fail(f"--head {head}: no counting head or GNSS unit of that name in the archive")
        except ArchiveError as exc:
            raise fail(str(exc)) from None
        due = due_list(items)
        if target is not None:
            from console.sinks.metrics import forecast_exposition

            try:
                with open_output(target) as f:
                    f.write(forecast_exposition(items))
            except OSError as exc:
                raise fail(f"--textfile {textfile}: cannot write ({exc.strerror or exc})") from None
        if json_out or jsonl:
            print_document(
                {
                    "schema": "trackside.forecast/1",
                    "horizon_days": horizon_days,
                    "trend_days": trend_days,
                    "layout": lay.source if lay is not None else None,
                    "counts": {
                        s: sum(1 for f in items if f.status == s) for s in ("past", "due", "watch", "unknown", "ok")
                    },
                    "due": [f.to_dict() for f in due],
                    "forecasts": [f.to_dict() for f in items],
                },
                {"due": "due", "forecasts": "forecast"} if jsonl else None,
            )
        else:
            from console.sinks.tables.forecast_tables import forecast_view

            Console(highlight=False).print(forecast_view(items, due, horizon_days, show_all))
        return exit_codes.FINDINGS if fail_on_due and due else exit_codes.OK

    raise typer.Exit(guard(body))
