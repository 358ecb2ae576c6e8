"""Sinks: where the pipeline's results go: the report (Markdown, HTML, JSON), the terminal tables, metrics."""
