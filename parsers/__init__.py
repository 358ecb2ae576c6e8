"""Parsers: bytes → typed tables and events. Formats only, no railway inference."""
