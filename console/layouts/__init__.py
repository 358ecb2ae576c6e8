"""Shipped layouts (TOML): ``osong`` and ``example``; see console.layout."""
