"""Sensor and channel health: the findings, and forecasts of when a figure will cross its threshold."""
