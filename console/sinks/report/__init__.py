"""`trackside report`: every analysis of a set of inputs in one document (Markdown, HTML or JSON).

* :mod:`.collect` — inputs (files, directories) → :class:`.model.ReportData`;
* :mod:`.spooled` — a diagnostic log's passages and section history, kept on disk as it is read;
* :mod:`.model` — what a report holds and its safety classes;
* :mod:`.document` — the JSON document (schema ``trackside.report/1``) and the outline, with
  :mod:`.gnss_units` and :mod:`.analog` (the GNSS unit table, the analog values);
* :mod:`.markdown`, :mod:`.html` (with :mod:`.svg`), :mod:`.jsonwrite` — the faces, written piece by piece;
* :mod:`.write` — atomic writes; :mod:`.command` — :func:`run_report`, exit codes.
"""

from console.sinks.report.command import FORMATS, render, run_report
from console.sinks.report.document import SCHEMA

__all__ = ["FORMATS", "SCHEMA", "render", "run_report"]
