"""Source URIs → source objects (the transports are imported only when used)."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import parse_qs, unquote, urlsplit

from console.inputs.base import Source, SourceError

SCHEMES = ("file", "gpsd", "mqtt", "mqtts", "can")
DEFAULT_PORTS = {"gpsd": 2947, "mqtt": 1883, "mqtts": 8883}
_URI_SCHEME = re.compile(r"[A-Za-z][A-Za-z0-9+.-]+")  # RFC 3986's, two letters at least (C:\ is a drive)


@dataclass(frozen=True)
class SourceURI:
    scheme: str
    path: str = ""  # file path, gpsd device, MQTT topic
    host: str = ""
    port: int = 0
    interface: str = ""  # CAN: python-can interface (socketcan, virtual…)
    channel: str = ""  # CAN channel (vcan0, a virtual bus name)
    username: str | None = None
    password: str | None = None
    role: str = ""  # gpsd: ?role=head|eot (the receiver's place on the train)
    train: str = ""  # gpsd: ?train=ID
    ca_file: str = ""  # mqtts: ?ca=PATH, the CA bundle that signed the broker's certificate


def parse_uri(text: str) -> SourceURI:
    """``file:PATH``, ``gpsd://H:P[/DEV]``, ``mqtt[s]://H:P/TOPIC[?ca=PATH]``, ``can:IFACE[:CHANNEL]``.

    ``mqtts://`` verifies the broker's certificate against the system's CAs,
    or against ``?ca=PATH`` (a PEM bundle: a private or self-signed CA).

    A bare path (no scheme) is a file, so ``trackside follow app.log`` works; ``-`` (or ``file:-``) is
    standard input.
    """
    scheme, sep, rest = text.partition(":")
    unknown = sep and rest.startswith("//") and scheme not in SCHEMES and _URI_SCHEME.fullmatch(scheme)
    if unknown and not Path(text).exists():  # mqqt://…, http://…: not a path whose directory is missing
        raise SourceError(
            f"{text}: unknown source type {scheme!r}: expected a file (PATH or file:PATH), - (standard input), "
            "gpsd://HOST:PORT, mqtt://HOST:PORT/TOPIC, mqtts://HOST:PORT/TOPIC or can:INTERFACE[:CHANNEL]"
        )
    if not sep or scheme not in SCHEMES or (len(scheme) == 1 and rest.startswith("\\")):
        return SourceURI("file", path=text)
    if scheme == "file":
        path = rest[2:] if rest.startswith("//") else rest
        if not path:
            raise SourceError(f"{text}: expected file:PATH")
        return SourceURI("file", path=unquote(path) if rest.startswith("//") else path)
    if scheme == "can":
        iface, _, channel = rest.partition(":")
        if not iface:
            raise SourceError(f"{text}: expected can:INTERFACE[:CHANNEL], e.g. can:socketcan:vcan0")
        return SourceURI("can", interface=iface, channel=channel)
    parts = urlsplit(text)
    if not parts.hostname:
        raise SourceError(f"{text}: expected {scheme}://HOST:PORT/…")
    try:
        port = parts.port or DEFAULT_PORTS[scheme]
    except ValueError:
        raise SourceError(f"{text}: the port is not a number 0-65535") from None
    path = unquote(parts.path.lstrip("/"))
    query_text = parts.query
    if scheme in ("mqtt", "mqtts"):
        if "#" in text:
            # MQTT's multi-level wildcard, not a URL fragment (urlsplit took it, and its ?options, off the topic).
            after, _, fragment_query = parts.fragment.partition("?")
            path += "#" + unquote(after)
            query_text = query_text or fragment_query
        if ("#" in path and not (path == "#" or path.endswith("/#"))) or path.count("#") > 1:
            raise SourceError(f"{text}: the wildcard # stands for whole levels at the topic's end (…/up/#)")
        if not path:
            raise SourceError(f"{text}: expected a topic, e.g. {scheme}://HOST:PORT/application/+/device/+/event/up")
    if scheme == "gpsd" and path:
        path = "/" + path  # a device path
    query = {k: v[-1] for k, v in parse_qs(query_text).items()}
    role = query.get("role", "")
    if role not in ("", "head", "eot"):
        raise SourceError(f"{text}: role must be head or eot, found {role!r}")
    ca_file = query.get("ca", "")
    if ca_file and scheme != "mqtts":
        raise SourceError(f"{text}: ?ca= is for mqtts:// (TLS) only")
    return SourceURI(
        scheme,
        path=path,
        host=parts.hostname,
        port=port,
        username=parts.username,
        password=parts.password,
        role=role,
        train=query.get("train", ""),
        ca_file=ca_file,
    )


def open_source(text: str, *, from_start: bool = False, force_polling: bool = False) -> Source:
    """A (not yet started) source for a URI; :class:`SourceError` if it cannot be one."""
    u = parse_uri(text)
    if u.scheme == "file":
        from console.inputs.stream import STDIN, StreamSource, is_stream

        if u.path == STDIN or is_stream(Path(u.path)):  # a pipe, a FIFO, a device: read as it comes
            return StreamSource(text, Path(u.path))
        from console.inputs.follow import FileSource

        return FileSource(text, Path(u.path), from_start=from_start, force_polling=force_polling)
    if u.scheme == "gpsd":
        from console.inputs.gpsd import GpsdSource

        return GpsdSource(text, u.host, u.port, u.path or None, role=u.role, train=u.train)
    if u.scheme in ("mqtt", "mqtts"):
        from console.inputs.mqtt import MqttSource

        return MqttSource(
            text,
            u.host,
            u.port,
            u.path,
            tls=u.scheme == "mqtts",
            ca_file=u.ca_file or None,
            username=u.username,
            password=u.password,
        )
    from console.inputs.can_bus import CanSource

    return CanSource(text, u.interface, u.channel)


def open_sources(texts: list[str], *, from_start: bool = False, force_polling: bool = False) -> list[Source]:
    """Sources for URIs, each checked (:meth:`Source.check`); :class:`SourceError` for the first that cannot
    be one.  A stream is read once: standard input, or one FIFO, given twice would share its lines out."""
    sources = [open_source(t, from_start=from_start, force_polling=force_polling) for t in texts]
    from console.inputs.stream import StreamSource

    streams: dict[tuple[int, int], str] = {}
    for s in sources:
        if isinstance(s, StreamSource):
            ident = s.identity()
            if ident in streams:
                twice = "standard input given twice" if s.is_stdin else f"the same stream as {streams[ident]}"
                raise SourceError(f"{s.uri}: {twice}")
            streams[ident] = s.uri
    for s in sources:
        s.check()
    return sources
