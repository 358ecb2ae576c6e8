"""trackside ato."""

from __future__ import annotations

import json
import sys
from typing import Annotated

import typer

from console import exit_codes
from console.cli.common import Console, fail, guard
from console.cli.options import JsonOpt


def ato(
    controller: Annotated[
        str, typer.Option("--controller", metavar="pid|fuzzy|fuzzy-d|all", help="pid, fuzzy, fuzzy-d or all.")
    ] = "all",
    plant: Annotated[
        str,
        typer.Option(
            "--plant", metavar="force|linear|both", help="force (our train model), linear (the paper's G(s)) or both."
        ),
    ] = "force",
    fuzzy_d_reading: Annotated[
        str,
        typer.Option(
            "--fuzzy-d-reading",
            metavar="output-gain|normalised|both",
            help="Fuzzy-D's eq. 6: output-gain (K multiplies SpeedT-scale output, as printed), normalised "
            "(K only rescales a [-1, 1] output and cancels) or both.",
        ),
    ] = "both",
    plot: Annotated[bool, typer.Option("--plot", help="Draw speed against distance in the terminal.")] = False,
    json_out: JsonOpt = False,
) -> None:
    """Automatic train operation run of Nguyen Van Tiem (TCSJ 2020): PID, fuzzy and Fuzzy-D beside its figures."""

    def body() -> int:
        from console.sim.ato import run_all
        from console.sim.control import CONTROLLER_NAMES, FUZZY_D_READINGS
        from console.sinks.tables.ato_view import ato_json, ato_plot, ato_table

        names = list(CONTROLLER_NAMES) if controller == "all" else [controller]
        if any(n not in CONTROLLER_NAMES for n in names):
            raise fail(f"--controller: expected pid, fuzzy, fuzzy-d or all, found {controller!r}")
        plants = ["force", "linear"] if plant == "both" else [plant]
        if any(p not in ("force", "linear") for p in plants):
            raise fail(f"--plant: expected force, linear or both, found {plant!r}")
        readings = list(FUZZY_D_READINGS) if fuzzy_d_reading == "both" else [fuzzy_d_reading]
        if any(r not in FUZZY_D_READINGS for r in readings):
            raise fail(f"--fuzzy-d-reading: expected output-gain, normalised or both, found {fuzzy_d_reading!r}")
        results = run_all(plants, names=names, fuzzy_d_readings=readings)
        if json_out:
            # An object with its schema, as every JSON document of trackside's (earlier versions printed the bare list).
            doc = {"schema": "trackside.ato/1", "runs": ato_json(results)}
            sys.stdout.write(json.dumps(doc, ensure_ascii=True, allow_nan=False) + "\n")
        else:
            out = Console(highlight=False)
            out.print(ato_table(results))
            if plot:
                for p in plants:
                    out.print(ato_plot(results, width=min(out.width, 100), height=20, plant=p))
        return exit_codes.OK

    raise typer.Exit(guard(body))
