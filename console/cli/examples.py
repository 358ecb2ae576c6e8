"""The examples at the end of each command's ``--help``: two or three command lines a person can paste.

They run from a checkout (they read ``sample_logs/``), in order: ``ingest``'s archive ``arc`` is the one
``query`` reads.  A trailing ``# exit N`` is the exit code the line ends with.  ``tests/test_examples.py``
runs every one of them (those needing a server, a terminal or minutes are listed there, with why not).
"""

from __future__ import annotations

EXAMPLES: dict[str, tuple[str, ...]] = {
    "analyze": (
        "trackside analyze sample_logs/osong_*.log",
        "trackside analyze sample_logs/example_station.log --layout example",
        "trackside analyze --jsonl sample_logs/ws4_subsecond.log | jq -c 'select(.type == \"passage\")'",
    ),
    "speeds": (
        "trackside speeds sample_logs/ws4_subsecond.log",
        "trackside speeds --json sample_logs/osong_*.log",
        "trackside speeds sample_logs/example_station.log --layout example",
    ),
    "sections": (
        "trackside sections sample_logs/example_station.log --layout example",
        "trackside sections sample_logs/example_station.log --layout example --reset B1@2026-03-02T09:30",
        'trackside sections sample_logs/example_station.log --layout example --jsonl | grep \'"type":"section"\'',
    ),
    "health": (
        "trackside health sample_logs/ws4_health.log",
        "trackside health --voltages sample_logs/am_thuong_2021-06-06_voltages.csv",
        "trackside health sample_logs/ws4_health.log --fail-on critical   # exit 1: a critical finding",
    ),
    "frames": (
        "trackside frames sample_logs/sensor_frames.txt",
        "trackside frames sample_logs/can_counts.log sample_logs/can_counts.asc --json",
    ),
    "approach": (
        "trackside approach sample_logs/osong_*.log --layout osong",
        "trackside approach sample_logs/example_station.log --layout example",
        "trackside approach sample_logs/example_station.log --layout example --head WS3 --distance 800",
    ),
    "gnss": (
        "trackside gnss sample_logs/gnss_devices.csv",
        "trackside gnss --json sample_logs/co_nhu_van_2026_centre_table.tsv",
    ),
    "crossing": (
        "trackside crossing sample_logs/crossing_example.csv --layout example",
        "trackside crossing sample_logs/crossing_example.csv --layout example --train A=A-head,A-eot,120 --json",
        'trackside crossing sample_logs/crossing_example.csv --layout example --jsonl | grep \'"type":"event"\'',
    ),
    "simulate": (
        "trackside simulate -o run --duration 30m --seed 7",
        "trackside simulate -o faulty --duration 20m --fault dead_channel:WS3:5m",
        "trackside simulate -o weeks --days 3 --health-only --fault analog_drift:WS3:0s",
    ),
    "ato": (
        "trackside ato",
        "trackside ato --controller fuzzy-d --plant linear --json",
    ),
    "station": (
        "trackside station --speed 50",
        "trackside station --replay sample_logs/example_station.log",
        "trackside station --serve --port 8000",
    ),
    "report": (
        "trackside report sample_logs/example_station.log --layout example --format html -o report.html",
        "trackside report sample_logs --layout example --format json --fail-on critical   # exit 1: a critical finding",
    ),
    "follow": (
        "trackside follow sample_logs/example_station.log --from-start --layout example --idle-exit 2",
        "cat sample_logs/example_station.log | trackside follow - --layout example --jsonl",
        "trackside follow 'gpsd://127.0.0.1:2947?role=head&train=1' 'gpsd://127.0.0.1:2948?role=eot&train=1'",
    ),
    "ingest": (
        "trackside ingest sample_logs --archive arc --layout example",
        "trackside ingest sample_logs --archive arc --engine dask --workers 2",
    ),
    "query": (
        "trackside query --list-presets",
        "trackside query --archive arc --preset axles-per-head-per-day --format csv",
        'trackside query --archive arc "SELECT counting_head, count(*) AS records FROM records GROUP BY ALL"',
    ),
    "layout": (
        "trackside layout example",
        "trackside layout example --plot line.png",
        "trackside layout my_line.toml --strict --json   # exit 2: there is no my_line.toml here",
    ),
    "verify": (
        "trackside verify --archive arc",
        "trackside verify --archive arc --deep --json",
    ),
    "forecast": (
        "trackside forecast --archive arc --all",
        "trackside forecast --archive arc --horizon 45d --head WS5 --json",
        "trackside forecast --archive arc --textfile trackside.prom",
    ),
}
# The top-level help's.
APP_EXAMPLES = (
    "trackside analyze sample_logs/osong_*.log",
    "trackside simulate -o run --duration 30m && trackside report run -o run.html --format html",
    "trackside analyze --help",
)


def epilog(examples: tuple[str, ...], before: str = "") -> str:
    """The help's closing text: ``before``, then the examples one per line (Click's ``\\b`` keeps them unwrapped)."""
    lines = "\n".join(f"  {e}" for e in examples)
    return (f"{before}\n\n" if before else "") + f"Examples (from a checkout: they read sample_logs/):\n\n\b\n{lines}"
