"""The line's facts and the analysis settings every passage figure is computed with."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from console.analysis.counting.wheels import PairingSettings
from console.analysis.head_table import Heads, head_names

if TYPE_CHECKING:
    from console.layout import Layout


@dataclass(frozen=True)
class SpeedSettings:
    """Line facts and analysis settings (defaults: the Osong tram test line, seed 003)."""

    spacing_m: float = 0.13
    train_length_m: float = 28.6
    # Longer than the 6 s a tram takes over WS4 in the paper, shorter than
    # any headway between two trams.
    idle_gap_s: float = 10.0
    pair_window_s: float = PairingSettings.pair_window_s
    # Above this, a "whole-train speed" is an artefact, not a train.
    max_speed_kmh: float = 400.0
    # Heads (by their Trackinfo name) whose Sys1–Sys2 spacing is not ``spacing_m``: a line of WS4 heads at
    # 0.13 m and a newer type at 0.15 m reads 15 % fast at the one or slow at the other with one spacing.
    head_spacing_m: tuple[tuple[str, float], ...] = ()

    @classmethod
    def of_layout(
        cls,
        layout: Layout | None,
        spacing_m: float | None = None,
        train_length_m: float | None = None,
        idle_gap_s: float = 10.0,
    ) -> SpeedSettings:
        """The line's facts from its layout unless given: each head's spacing (``spacing_m`` given sets one
        for every head), the first consist's length."""
        consist = layout.consist() if layout is not None else None
        per_head: tuple[tuple[str, float], ...] = ()
        if spacing_m is None and layout is not None:
            spacing_m = layout.spacing_m()
            per_head = tuple((h.id, h.spacing_m) for h in layout.heads if h.spacing_m != spacing_m)
        return cls(
            spacing_m=spacing_m if spacing_m is not None else cls.spacing_m,
            train_length_m=train_length_m
            if train_length_m is not None
            else (consist.length_m if consist is not None else cls.train_length_m),
            idle_gap_s=idle_gap_s,
            head_spacing_m=per_head,
        )

    def to_json(self) -> dict[str, Any]:
        """The settings as every JSON document gives them (``head_spacing_m``: the heads not at ``spacing_m``)."""
        return {
            "spacing_m": self.spacing_m,
            "head_spacing_m": dict(self.head_spacing_m),
            "train_length_m": self.train_length_m,
            "idle_gap_s": self.idle_gap_s,
            "pair_window_s": round(self.pair_window_s, 6),
        }

    def spacing_by_head(self, heads: Heads) -> np.ndarray | None:
        """Per head key, the head's spacing in metres; None: ``spacing_m`` for every head."""
        if not self.head_spacing_m:
            return None
        own = dict(self.head_spacing_m)
        return np.array([own.get(n, self.spacing_m) for n in head_names(heads)], np.float64)
