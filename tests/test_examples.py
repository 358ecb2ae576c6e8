"""Every example a user is shown runs: the commands of the README's ``sh`` blocks and the examples at the end
of every ``trackside COMMAND --help``, word for word, in a temporary directory holding a copy of
``sample_logs/``.  Each must end with exit 0, or with the code a trailing ``# exit N`` documents.

The examples of one page run in order in one directory (``ingest`` makes the archive ``query`` reads).
Those that need a server, a live source, a terminal or a long run are listed in :data:`NOT_RUN` with why.
"""

from __future__ import annotations

import functools
import os
import re
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from console.cli.examples import APP_EXAMPLES, EXAMPLES

ROOT = Path(__file__).resolve().parent.parent
BIN = Path(sys.executable).parent
TRACKSIDE = str(BIN / "trackside")


def _commands() -> tuple[str, ...]:
    import typer

    from console.cli.app import app

    group = typer.main.get_command(app)
    return tuple(group.commands)  # type: ignore[attr-defined]


COMMANDS = _commands()  # every command the app has: each must have examples
# An example containing the key is not run here, for the reason given.
NOT_RUN = {
    "pip install": "installs the package: run by .ci/run, and by hand in a fresh venv before a release",
    "trackside station": "the interactive station view needs a terminal (tests/test_station_tui.py drives it)",
    "file:/var/log/": "follows a log of a live system until Ctrl-C",
    "gpsd://": "needs a running gpsd (tests/test_live_gpsd.py starts one through gpsfake)",
}
SLOW = {
    "--engine dask": "starts a Dask cluster (half a minute on 2 cores; tests/test_fleet_*.py cover the engine)",
    "--live --speed 60": "writes a live run for 10 s of wall time (tests/test_live_sim.py covers it)",
}
EXIT = re.compile(r"#\s*exit (\d+)")


def readme_examples() -> list[str]:
    """The command lines of the README's ``sh`` blocks (``\\`` continuations joined)."""
    text = (ROOT / "README.md").read_text("utf-8")
    out = []
    for block in re.findall(r"^```sh\n(.*?)^```", text, re.M | re.S):
        joined = re.sub(r"\\\n\s*", "", block)
        out += [line.strip() for line in joined.splitlines() if line.strip()]
    return out


@functools.cache  # one real run of each help; two tests read it
def help_text(command: str | None) -> str:
    args = [TRACKSIDE, *([command] if command else []), "--help"]
    env = {**os.environ, "COLUMNS": "100"}
    out = subprocess.run(args, capture_output=True, text=True, timeout=60, env=env, check=True)
    return out.stdout


def help_examples(command: str | None) -> list[str]:
    """The lines after a help's ``Examples`` heading: each must be a whole command on a line of its own."""
    text = help_text(command)
    assert "Examples" in text, f"trackside {command or ''} --help has no examples"
    tail = text.split("Examples", 1)[1].splitlines()[1:]
    return [line.strip() for line in tail if line.strip()]


def _reason(example: str) -> str | None:
    for key, why in NOT_RUN.items():
        if key in example:
            return why
    if not os.environ.get("TRACKSIDE_SLOW_TESTS"):
        for key, why in SLOW.items():
            if key in example:
                return why + "; TRACKSIDE_SLOW_TESTS=1 runs it"
    if " jq " in example and shutil.which("jq") is None:
        return "jq is not installed (Debian's jq; .ci/run installs it)"
    return None


def run_example(example: str, cwd: Path) -> None:
    why = _reason(example)
    if why is not None:
        pytest.skip(why)
    expected = EXIT.search(example)
    env = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}", "COLUMNS": "100"}
    env.pop("TRACKSIDE_ARCHIVE", None)
    proc = subprocess.run(
        ["bash", "-c", example], cwd=cwd, capture_output=True, text=True, timeout=300, env=env, check=False
    )
    want = int(expected.group(1)) if expected else 0
    assert proc.returncode == want, f"{example}\nexit {proc.returncode}\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}"
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr, proc.stderr


@pytest.fixture(scope="module")
def readme_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("readme")
    shutil.copytree(ROOT / "sample_logs", d / "sample_logs")
    return d


@pytest.fixture(scope="module")
def help_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("help")
    shutil.copytree(ROOT / "sample_logs", d / "sample_logs")
    return d


README = readme_examples()
# What each --help shows (checked against the help text below): no help is run to collect the tests.
HELP = [(c, e) for c in COMMANDS for e in EXAMPLES.get(c, ())]


def test_the_readme_keeps_its_two_quick_start_commands() -> None:
    # .ci/run runs the second one; the first is what a new user types.
    assert README[:2] == [
        "pip install . && trackside analyze sample_logs/osong_*.log",
        'pip install -e ".[test]" && python -m pytest',
    ]


def test_every_command_has_examples() -> None:
    assert set(EXAMPLES) == set(COMMANDS)


@pytest.mark.parametrize("command", [None, *COMMANDS])
def test_every_help_ends_with_two_or_three_examples_one_per_line(command: str | None) -> None:
    examples = help_examples(command)
    assert 2 <= len(examples) <= 3, examples
    # Shown whole, one per line (none wrapped onto a second line), as the module lists them.
    assert examples == list(EXAMPLES.get(command, ()) if command else APP_EXAMPLES)


@pytest.mark.parametrize("command", [None, *COMMANDS])
def test_usage_lines_name_no_python_types(command: str | None) -> None:
    text = help_text(command)
    leaks = re.findall(r"<[a-z][a-z_ ]*(?:\[[^\]]*\])?>|\{[a-z_]+\}|list\[", text)
    assert not leaks, leaks


def test_every_option_says_what_it_does() -> None:
    # simulate --trains-per-hour showed only "[default: 6.0; 0.1<=x<=60]".
    import typer

    from console.cli.app import app

    group = typer.main.get_command(app)
    bare = [
        f"{name} {'/'.join(p.opts)}"
        for name, command in group.commands.items()  # type: ignore[attr-defined]
        for p in command.params
        if p.param_type_name == "option" and not (p.help or "").strip()
    ]
    assert not bare, bare


@pytest.mark.parametrize("example", README)
def test_readme_example_runs(example: str, readme_dir: Path) -> None:
    run_example(example, readme_dir)


@pytest.mark.parametrize(("command", "example"), HELP)
def test_help_example_runs(command: str, example: str, help_dir: Path) -> None:
    run_example(example, help_dir)


def test_links_of_the_readme_and_docs_resolve() -> None:
    # Material moved out of the README must be where its links say.
    broken = []
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text("utf-8")):
            if "://" in target:
                continue
            if not (page.parent / target).exists():
                broken.append(f"{page.relative_to(ROOT)}: {target}")
    assert not broken, broken


# The `sh` blocks of docs/*.md run as the README's do, page by page in a directory of their own (in order:
# archive.md's ingest makes the archive its queries read).  What a page shows for a server, a cluster or a
# benchmark's own data is not run here, for the reason given; `text` and bare blocks are output, not commands.
DOC_NOT_RUN = {
    "/srv/": "a server's paths (archive.md's and scaling.md's outline of a deployment)",
    "broker.example": "needs a TLS MQTT broker (tests/test_live_mqtts.py starts one)",
    "ruff check": "the linters run on the checkout, not on a copy of sample_logs (.ci/run runs them)",
    "benchmarks": "benchmarks run by hand on data they generate (docs/development.md)",
    "r3m.log": "measured runs on the benchmark logs (hundreds of MB, not shipped)",
    "r12m.log": "measured runs on the benchmark logs (hundreds of MB, not shipped)",
    "--archive ing3": "the archive the measured runs made of r3m.log",
}


def doc_examples() -> list[tuple[str, str]]:
    """(page, command line) of every ``sh`` block of docs/*.md (``\\`` continuations joined)."""
    out = []
    for page in sorted((ROOT / "docs").glob("*.md")):
        text = page.read_text("utf-8")
        for block in re.findall(r"^```sh\n(.*?)^```", text, re.M | re.S):
            joined = re.sub(r"\\\n\s*", "", block)
            out += [(page.name, line.strip()) for line in joined.splitlines() if line.strip()]
    return out


DOCS = doc_examples()


@pytest.fixture(scope="module")
def doc_dir(tmp_path_factory: pytest.TempPathFactory) -> Callable[[str], Path]:
    """A page's directory, holding a copy of sample_logs/: made at its first example, kept for the rest."""
    made: dict[str, Path] = {}

    def get(page: str) -> Path:
        if page not in made:
            made[page] = tmp_path_factory.mktemp(page.replace(".", "_"))
            shutil.copytree(ROOT / "sample_logs", made[page] / "sample_logs")
        return made[page]

    return get


def test_the_docs_pages_show_commands_that_run() -> None:
    assert {page for page, _ in DOCS} >= {"archive.md", "development.md", "scaling.md"}
    assert any(example.startswith("trackside query --archive arc") for _, example in DOCS)


@pytest.mark.parametrize(("page", "example"), DOCS)
def test_docs_example_runs(page: str, example: str, doc_dir: Callable[[str], Path]) -> None:
    for key, why in DOC_NOT_RUN.items():
        if key in example:
            pytest.skip(why)
    run_example(example, doc_dir(page))


def test_the_readme_synopsis_names_every_option() -> None:
    # It had left out speeds --layout, forecast --layout and forecast --fail-on-due.
    import typer

    from console.cli.app import app

    block = (ROOT / "README.md").read_text("utf-8").split("## Commands", 1)[1].split("```", 2)[1]
    synopsis: dict[str, str] = {}
    command = ""
    for line in block.splitlines():
        m = re.match(r"trackside (\w+)", line)
        command = m.group(1) if m else command
        synopsis[command] = synopsis.get(command, "") + line
    group = typer.main.get_command(app)
    missing = [
        f"{name} {'/'.join(p.opts)}"
        for name, cmd in group.commands.items()  # type: ignore[attr-defined]
        for p in cmd.params
        if p.param_type_name == "option"
        and p.opts != ["--help"]
        and not any(re.search(rf"(?<![\w-]){re.escape(o)}(?![\w-])", synopsis.get(name, "")) for o in p.opts)
    ]
    assert not missing, missing
