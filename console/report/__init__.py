"""`trackside report`: every analysis of a set of inputs in one document (Markdown, HTML or JSON).

* :mod:`.collect` — inputs (files, directories) → :class:`.model.ReportData`;
* :mod:`.model` — the JSON document (schema ``trackside.report/1``) and the outline;
* :mod:`.markdown`, :mod:`.html` (with :mod:`.svg`) — the faces;
* :mod:`.write` — atomic writes; :mod:`.command` — :func:`run_report`, exit codes.
"""

from console.report.command import FORMATS, render, run_report
from console.report.model import SCHEMA

__all__ = ["FORMATS", "SCHEMA", "render", "run_report"]
