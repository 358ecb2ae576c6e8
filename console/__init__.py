"""trackside: terminal console and log analyzer for railway train detection."""

__version__ = "0.1.0"
