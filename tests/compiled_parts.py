"""Tests of a compiled part against its numpy path: skipped where the part was not built, failed on CI."""

from __future__ import annotations

import os
import shutil
import sysconfig
from pathlib import Path

import pytest


def needs_compiled(module: object | None, name: str) -> pytest.MarkDecorator:
    """The mark of a test module comparing the compiled part ``name`` (``module``: it, or None where it was not
    built) with its numpy path: skipped without it.  CI installs a C compiler and this Python's headers: a
    package built without the part there means the build broke, and that fails the module at once."""
    compiler = shutil.which("cc") or shutil.which("gcc")
    headers = (Path(sysconfig.get_paths()["include"]) / "Python.h").is_file()
    if module is None and os.environ.get("CI") and compiler and headers:
        raise AssertionError(f"{name} was not built, though a C compiler is present ({compiler})")
    return pytest.mark.skipif(
        module is None, reason=f"{name} is not built (no C compiler at install): only the numpy path runs"
    )
