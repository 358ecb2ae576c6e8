"""trackside layout."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from console import exit_codes
from console.cli.common import fail, guard, load_layout, print_json
from console.cli.options import JsonOpt


def layout(
    spec: Annotated[
        str,
        typer.Argument(
            metavar="LAYOUT", help="Layout TOML file, or a shipped one: osong, example.", show_default=False
        ),
    ],
    plot: Annotated[
        Path | None,
        typer.Option(
            "--plot",
            metavar="FILE",
            help="Also draw the line along its chainage (sections, heads, crossings, platforms; the speed allowed "
            "below) to FILE, .png or .svg.",
            show_default=False,
        ),
    ] = None,
    strict: Annotated[
        bool, typer.Option("--strict", help="Exit 1 when a check warns (for a layout kept under CI).")
    ] = False,
    json_out: JsonOpt = False,
) -> None:
    """A layout as the analyses read it: heads in chainage order with the sections they bound, sections with
    the heads an up train enters and leaves them by, crossings with the section they lie in. Then checks that
    loading cannot refuse, as warnings: section signs against chainage order, one-sign sections, heads and
    crossings beyond the track, a crossing whose lat/lon and chainage disagree."""

    def body() -> int:
        from console.analysis.layout_checks import WARNING, check_layout, layout_document
        from console.sinks.report.layout_plot import PLOT_SUFFIXES

        target = None
        if plot is not None:
            from console.output_path import OutputError, check_output_file

            if plot.suffix.lower() not in PLOT_SUFFIXES:
                raise fail(f"--plot {plot}: the file name must end in .png or .svg (the drawing's format)")
            from console.layout import BUILTIN

            layout_file = [] if spec in BUILTIN else [Path(spec)]
            try:  # before any work: never a layout nor a device replaced
                target = check_output_file(plot, layout_file, what="plot")
            except OutputError as exc:
                raise fail(f"--plot {exc}") from None
        lay = load_layout(spec, warn=False)  # it lists them itself
        findings = check_layout(lay)
        if target is not None:
            from console.output_path import open_output
            from console.sinks.report.layout_plot import layout_plot

            data = layout_plot(lay, findings, plot.suffix.lower().lstrip(".") if plot is not None else "png")
            try:
                with open_output(target) as f:
                    f.write(data)
            except OSError as exc:
                raise fail(f"--plot {plot}: cannot write ({exc.strerror or exc})") from None
        if json_out:
            print_json(layout_document(lay, findings))
        else:
            from console.cli.common import Console
            from console.sinks.tables.layout_tables import layout_view

            out = Console(highlight=False)
            for part in layout_view(lay, findings):
                out.print(part, soft_wrap=True)
        warned = any(f.level == WARNING for f in findings)
        return exit_codes.FINDINGS if strict and warned else exit_codes.OK

    raise typer.Exit(guard(body))
