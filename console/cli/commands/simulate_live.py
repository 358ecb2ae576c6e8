"""`trackside simulate --live / --mqtt`: the simulator as a live feed (see console/sim/live_run.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from console import exit_codes
from console.cli.common import Console, fail, print_json
from console.plural import count


def run_live_command(
    sim: Any, seconds: float, speed: float, directory: Path | None, mqtt_url: str | None, json_out: bool
) -> int:
    from console.inputs.base import SourceError
    from console.inputs.uri import parse_uri
    from console.safe_text import clean, show_path
    from console.sim.live_run import UplinkPublisher, run_live

    publisher = None
    if mqtt_url is not None:
        try:
            u = parse_uri(mqtt_url if "/" in mqtt_url.split("://", 1)[-1] else mqtt_url + "/up")
        except SourceError as exc:
            raise fail(f"--mqtt: {exc}") from None
        if u.scheme not in ("mqtt", "mqtts"):
            raise fail(f"--mqtt {mqtt_url!r}: expected mqtt://HOST:PORT or mqtts://HOST:PORT")
        try:
            publisher = UplinkPublisher(u.host, u.port, tls=u.scheme == "mqtts")
        except OSError as exc:
            raise fail(f"--mqtt {mqtt_url}: cannot connect ({exc.strerror or exc})") from None
    out = Console(highlight=False, stderr=True)
    if directory is not None:
        out.print(
            f"writing a live run into {show_path(directory)} at {speed:g}× real time (Ctrl-C stops)", markup=False
        )
    if publisher is not None:
        out.print(f"publishing uplinks to {clean(mqtt_url)} (application/trackside/device/+/event/up)", markup=False)
    summary = run_live(sim, seconds, speed, directory, publisher)
    if json_out:
        print_json({"schema": "trackside.simulate-live/1", **summary})
    else:
        out.print(
            f"simulated {summary['simulated_s']:.0f} s in {summary['wall_s']:.0f} s:"
            f" {count(summary['diagnostic_lines'], 'diagnostic line')}, {count(summary['fixes'], 'fix')},"
            f" {count(summary['uplinks'], 'uplink')}",
            markup=False,
        )
    return exit_codes.OK
