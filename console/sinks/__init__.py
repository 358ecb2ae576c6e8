"""Sinks: what the live engine's events go to besides the screen (metrics for Prometheus)."""
