"""No module of console or parsers imports another module's private name (``from X import _name``).

A name with a leading underscore is its module's own business: a second module that needs it makes it
public (and gives it a docstring), so that what a module offers can be read off its names.  import-linter
checks modules and packages, not names (pyproject.toml's contracts), hence this check.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("console", "parsers")


def private_imports(source: str, module: str) -> list[str]:
    """``line: from X import _name`` for every private project name the source imports from another module."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.ImportFrom):
            continue
        if node.level:  # relative: resolved against the importing module's package
            base = module.split(".")[: -node.level]
            origin = ".".join([*base, node.module] if node.module else base)
        else:
            origin = node.module or ""
        if origin.split(".")[0] not in PACKAGES:
            continue  # another library's private names are its business (and rare)
        for alias in node.names:
            private = alias.name.startswith("_") and not (alias.name.startswith("__") and alias.name.endswith("__"))
            if private:
                out.append(f"{node.lineno}: from {origin} import {alias.name}")
    return out


def test_the_check_sees_a_private_import_and_lets_dunders_and_aliases_pass() -> None:
    source = (
        "from console.analysis.timefmt import _fraction\n"
        "from console import __version__\n"
        "from parsers.gnss.fields import cells_of as _cells\n"
        "from numpy import _private\n"
        "from .fields import _split_fields\n"
    )
    assert private_imports(source, "parsers.diag.registry") == [
        "1: from console.analysis.timefmt import _fraction",
        "5: from parsers.diag.fields import _split_fields",
    ]


@pytest.mark.parametrize("package", PACKAGES)
def test_no_private_name_is_imported_across_modules(package: str) -> None:
    found = []
    for path in sorted((ROOT / package).rglob("*.py")):
        rel = path.relative_to(ROOT)
        module = ".".join(rel.with_suffix("").parts).removesuffix(".__init__")
        found += [f"{rel}:{hit}" for hit in private_imports(path.read_text(encoding="utf-8"), module)]
    assert not found, "private names imported from another module (make them public):\n" + "\n".join(found)
