"""Helpers and fixtures for the live-source tests: real servers on loopback, bounded waits.

gpsd (through gpsfake) and mosquitto run as real processes bound to
127.0.0.1 on a free port; a test that needs one skips, saying which binary
is missing, only when it is not installed (``.ci/run`` installs Debian's
gpsd, gpsd-clients and mosquitto best effort).  Every wait is bounded.
"""

from __future__ import annotations

import contextlib
import json
import os
import random
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from prometheus_client.parser import text_string_to_metric_families

REPO = Path(__file__).resolve().parent.parent
NMEA_DIR = Path("/work/shared/data/nmea")
if not NMEA_DIR.is_dir():
    NMEA_DIR = REPO.parent / "shared" / "data" / "nmea"


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def restartable_port() -> int:
    """A free loopback port for a server a test stops and starts again on the same port.

    A port the kernel handed out (:func:`free_port`) is in its ephemeral range, from which every
    ``bind(0)`` and every outgoing connection of the other test workers draw too: while the server is
    down one of them can take it, and the test then talks to a stranger.  This port is below that
    range, where the kernel never looks, in a block of its own for each pytest-xdist worker."""
    try:
        low = int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return free_port()
    worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw")
    block = 500
    first = max(1024, low - block * 16) + block * (int(worker) % 16 if worker.isdigit() else 0)
    candidates = range(first, min(first + block, low))  # empty where the ephemeral range starts low
    for port in random.sample(candidates, k=len(candidates)):
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    return free_port()  # all taken: no better than the kernel's choice


def wait_until(cond: Callable[[], bool], timeout_s: float = 10.0, step_s: float = 0.02) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(step_s)
    return cond()


def lines_read(metrics_port: int) -> int:
    """Messages (lines, for a file) that a `follow --metrics 127.0.0.1:PORT` has read so far, all sources; 0 while
    its metrics are not served yet."""
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{metrics_port}/metrics", timeout=5) as r:
            text = r.read().decode()
    except OSError:
        return 0
    return int(
        sum(
            sample.value
            for family in text_string_to_metric_families(text)
            if family.name == "trackside_source_messages"
            for sample in family.samples
            if sample.name == "trackside_source_messages_total"
        )
    )


def port_open(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.settimeout(0.2)
        return s.connect_ex(("127.0.0.1", port)) == 0


def gpsd_banner(port: int, timeout_s: float = 10.0) -> str:
    """The first line a server on 127.0.0.1:port sends: gpsd greets every client with its VERSION."""
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=timeout_s) as s:
            data = b""
            while b"\n" not in data:
                chunk = s.recv(4096)
                if not chunk:
                    break
                data += chunk
    except OSError as exc:
        return f"nothing ({exc})"
    return data.split(b"\n", 1)[0].decode(errors="replace")


def gpsd_devices(port: int) -> list[str]:
    """The paths of the devices gpsd on 127.0.0.1:port lists (``?DEVICES;``); none if it does not answer."""
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
            lines = s.makefile("rb")
            lines.readline()  # the VERSION greeting
            s.sendall(b"?DEVICES;\n")
            for _ in range(20):
                line = lines.readline()
                if not line:
                    break
                doc = json.loads(line)
                if doc.get("class") == "DEVICES":
                    return [str(d.get("path", "")) for d in doc.get("devices", [])]
    except (OSError, ValueError):
        pass
    return []


def need(binary: str) -> str:
    path = shutil.which(binary) or next(
        (p for p in (f"/usr/sbin/{binary}", f"/usr/bin/{binary}") if os.access(p, os.X_OK)), None
    )
    if path is None:
        pytest.skip(f"{binary} is not installed (Debian package: see .ci/run)")
    return path


def stop_process(proc: subprocess.Popen[Any], timeout_s: float = 5.0) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout_s)


class Mosquitto:
    """A real broker on 127.0.0.1:port; :meth:`restart` keeps the port."""

    def __init__(self, workdir: Path) -> None:
        self.binary = need("mosquitto")
        self.port = restartable_port()
        self.conf = workdir / "mosquitto.conf"
        self.conf.write_text(
            f"listener {self.port} 127.0.0.1\nallow_anonymous true\npersistence false\nlog_dest none\n"
            "max_queued_messages 100000\n"
        )
        self.proc: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        self.proc = subprocess.Popen(
            [self.binary, "-c", str(self.conf)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        if not wait_until(lambda: port_open(self.port), 10):
            self.stop()
            pytest.fail("mosquitto did not start listening")

    def stop(self) -> None:
        if self.proc is not None:
            stop_process(self.proc)
            self.proc = None

    def restart(self) -> None:
        self.stop()
        self.start()

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"


def self_signed_ca(workdir: Path, host_ip: str = "127.0.0.1") -> tuple[Path, Path, Path]:
    """A throwaway CA and a server certificate it signed for ``host_ip``: (ca.pem, server.pem, server.key).

    Made with the ``cryptography`` package (a test dependency), so no openssl binary is needed.
    """
    import datetime as dt
    import ipaddress

    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    now = dt.datetime.now(dt.UTC)
    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "trackside test CA")])
    ca = (
        x509.CertificateBuilder()
        .subject_name(ca_name)
        .issuer_name(ca_name)
        .public_key(ca_key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=1))
        .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
        .add_extension(x509.KeyUsage(False, False, False, False, False, True, True, False, False), critical=True)
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(ca_key.public_key()), critical=False)
        .sign(ca_key, hashes.SHA256())
    )
    key = ec.generate_private_key(ec.SECP256R1())
    server = (
        x509.CertificateBuilder()
        .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, host_ip)]))
        .issuer_name(ca_name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=1))
        .add_extension(x509.SubjectAlternativeName([x509.IPAddress(ipaddress.ip_address(host_ip))]), critical=False)
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()), critical=False)
        .sign(ca_key, hashes.SHA256())
    )
    ca_pem, cert_pem, key_pem = workdir / "ca.pem", workdir / "server.pem", workdir / "server.key"
    ca_pem.write_bytes(ca.public_bytes(serialization.Encoding.PEM))
    cert_pem.write_bytes(server.public_bytes(serialization.Encoding.PEM))
    key_pem.write_bytes(
        key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption())
    )
    return ca_pem, cert_pem, key_pem


class MosquittoTLS(Mosquitto):
    """The broker with one TLS listener on 127.0.0.1:port, its certificate signed by a test CA."""

    def __init__(self, workdir: Path) -> None:
        super().__init__(workdir)
        self.ca, cert, key = self_signed_ca(workdir)
        self.conf.write_text(
            f"listener {self.port} 127.0.0.1\nallow_anonymous true\npersistence false\nlog_dest none\n"
            f"cafile {self.ca}\ncertfile {cert}\nkeyfile {key}\n" + ("user root\n" if os.geteuid() == 0 else "")
            # Started as root, mosquitto would become user "mosquitto", who cannot read pytest's 0700 tmp dirs.
        )

    @property
    def url(self) -> str:
        return f"mqtts://127.0.0.1:{self.port}"


@pytest.fixture
def mosquitto(tmp_path: Path) -> Iterator[Mosquitto]:
    broker = Mosquitto(tmp_path)
    broker.start()
    try:
        yield broker
    finally:
        broker.stop()


class GpsFake:
    """gpsfake feeding a real NMEA capture to its own gpsd on 127.0.0.1:port."""

    def __init__(self, capture: Path, cycle_s: float = 0.05) -> None:
        need("gpsd")
        self.binary = need("gpsfake")
        self.capture = capture
        self.cycle_s = cycle_s
        self.port = restartable_port()
        self.proc: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        # gpsfake adds its pty to gpsd through a control socket, and gives up silently when that socket,
        # though its file exists, is not listening yet: a gpsd without a device, which clients connect to
        # and hear nothing from (a CI run's restarted gpsd).  So a start counts once gpsd lists the pty.
        for _attempt in range(3):
            self._spawn()
            if wait_until(lambda: any(p.startswith("/dev/") for p in gpsd_devices(self.port)), 10, 0.2):
                return
            self.stop()
        pytest.fail(f"gpsfake's gpsd on 127.0.0.1:{self.port} never listed its device, in 3 starts")

    def _spawn(self) -> None:
        # -P port, -c seconds between sentences, -q quiet, -n: gpsd reads the device at once, before
        # any client watches.  -G (listen on every address) is not given: gpsd listens on loopback only.
        self.proc = subprocess.Popen(
            [self.binary, "-q", "-n", "-P", str(self.port), "-c", str(self.cycle_s), str(self.capture)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
        )
        if not wait_until(lambda: self.proc is not None and self.proc.poll() is None and port_open(self.port), 15):
            self.stop()
            pytest.fail("gpsfake's gpsd did not start listening")
        banner = gpsd_banner(self.port)
        if '"class":"VERSION"' not in banner:
            self.stop()
            pytest.fail(f"what listens on 127.0.0.1:{self.port} is not gpsfake's gpsd: it said {banner!r}")

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGTERM)
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(5)
        self.proc = None


_CLI = "import sys; from console.cli.app import app; sys.argv[0] = 'trackside'; app()"


def trackside(*args: str) -> list[str]:
    """The command line of ``trackside ARGS`` with this interpreter."""
    return [sys.executable, "-c", _CLI, *args]


def read_jsonl(text: str) -> list[dict[str, Any]]:
    return [json.loads(line) for line in text.splitlines() if line.strip()]


def follow_a_live_simulation(
    follow_args: list[str], first_lines: int, ready: Callable[[list[str]], bool], simulate_args: list[str]
) -> tuple[list[str], str, subprocess.CompletedProcess[str]]:
    """``follow`` started, its first lines read (its sources' states) and checked by ``ready`` before
    ``simulate`` runs to its end, then ``follow`` waited for (it stops on its ``--idle-exit``):
    (those first lines, the rest of follow's stdout, the simulation)."""
    follow = subprocess.Popen(
        trackside("follow", *follow_args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert follow.stdout is not None
        said = [follow.stdout.readline() for _ in range(first_lines)]
        assert ready(said), said
        sim = subprocess.run(trackside("simulate", *simulate_args), capture_output=True, text=True, timeout=60)
        assert sim.returncode == 0, sim.stderr
        out, err = follow.communicate(timeout=60)
    finally:
        if follow.poll() is None:
            follow.kill()
    assert follow.returncode == 0, err
    return said, out, sim


class HeadlessChromium:
    """Headless Chromium driven over the DevTools protocol (loopback only): screenshots, and the
    text the page receives on its websockets (what the served app draws)."""

    def __init__(self, tmp: Path) -> None:
        self.binary = next((b for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)
        if self.binary is None:
            pytest.skip("chromium is not installed (Debian package: see .ci/run)")
        self.port = free_port()
        self.proc = subprocess.Popen(
            [
                self.binary,
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-background-networking",
                "--no-first-run",
                f"--remote-debugging-port={self.port}",
                "--remote-debugging-address=127.0.0.1",
                f"--user-data-dir={tmp / 'chromium-profile'}",
                "--window-size=1400,1000",
                "about:blank",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )

    def page_ws_url(self) -> str:
        end = time.monotonic() + 20
        while time.monotonic() < end:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{self.port}/json/list", timeout=1) as r:
                    pages = [t for t in json.load(r) if t.get("type") == "page"]
                if pages:
                    return str(pages[0]["webSocketDebuggerUrl"])
            except OSError:
                pass
            time.sleep(0.1)
        pytest.fail("chromium's DevTools endpoint did not come up")

    def close(self) -> None:
        stop_process(self.proc)


class DevToolsPage:
    """One page over CDP: navigate, screenshot, and the websocket text it has received."""

    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.next_id = 0
        self.frames: list[str] = []

    async def call(self, method: str, **params: Any) -> dict[str, Any]:
        self.next_id += 1
        mid = self.next_id
        await self.ws.send_json({"id": mid, "method": method, "params": params})
        async for msg in self.ws:
            doc = json.loads(msg.data)
            if doc.get("method") == "Network.webSocketFrameReceived":
                self.frames.append(doc["params"]["response"].get("payloadData", ""))
            if doc.get("id") == mid:
                return dict(doc.get("result") or {})
        raise RuntimeError("DevTools connection closed")

    async def pump(self, seconds: float) -> None:
        """Let the page run, collecting websocket frames."""
        import asyncio

        end = time.monotonic() + seconds
        while time.monotonic() < end:
            try:
                msg = await asyncio.wait_for(self.ws.receive(), timeout=max(0.01, end - time.monotonic()))
            except TimeoutError:
                return
            doc = json.loads(msg.data)
            if doc.get("method") == "Network.webSocketFrameReceived":
                self.frames.append(doc["params"]["response"].get("payloadData", ""))

    def text(self) -> str:
        """Every received frame as text (binary frames arrive base64-encoded), terminal escapes removed."""
        import base64
        import binascii
        import re

        out = []
        for f in self.frames:
            try:
                out.append(base64.b64decode(f, validate=True).decode("utf-8", "replace"))
            except (binascii.Error, ValueError):
                out.append(f)
        return re.sub(r"\x1b\[[0-9;?$]*[A-Za-z]", "", "".join(out))
