"""Renderers: turn analysis results into Rich tables (and, later, reports)."""
