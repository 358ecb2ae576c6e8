"""Live sources: growing files, gpsd, LoRaWAN uplinks over MQTT, a CAN bus.

A source knows its transport, not railways.  Each one runs in its own thread
and hands *items* to one queue: raw record bytes of a followed log
(:class:`LineBlock`), GNSS fixes (:class:`GnssFix`), CAN frames
(:class:`CanFrame`), count frames read from a followed CAN or frame log
(:class:`FrameRows`) and notes about itself (:class:`SourceNote`).  The live
engine (:mod:`console.live`) turns those into the same tables and events the
batch parsers produce and runs the same analysis core on them.

A source is named by a URI (:func:`open_source`)::

    file:PATH                      follow a growing file (tail -F): a diagnostic, GNSS, CAN or frame log
    gpsd://HOST:PORT[/DEVICE]      a running gpsd, WATCH JSON
    mqtt://HOST:PORT/TOPIC         LoRaWAN uplinks (ChirpStack v4, The Things Stack v3)
    mqtts://HOST:PORT/TOPIC        the same over TLS
    can:INTERFACE[:CHANNEL]        a live CAN bus through python-can
"""

from __future__ import annotations

from console.sources.base import (
    CanFrame,
    FrameRows,
    GnssFix,
    Item,
    LineBlock,
    Source,
    SourceError,
    SourceNote,
    SourceStatus,
)
from console.sources.uri import open_source, parse_uri

__all__ = [
    "CanFrame",
    "FrameRows",
    "GnssFix",
    "Item",
    "LineBlock",
    "Source",
    "SourceError",
    "SourceNote",
    "SourceStatus",
    "open_source",
    "parse_uri",
]
