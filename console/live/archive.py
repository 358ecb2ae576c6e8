"""``follow --archive DIR``: what is followed is kept, and ingested into the archive.

Followed bytes are appended, exactly as read, to spool files beside the
archive (``DIR.live/``: one per followed file, one per rotation); GNSS fixes
from gpsd and MQTT go to a device CSV (``time,device,role,lat,lon,speed,
course``, the stream form ``trackside gnss`` reads).  Every
``INGEST_EVERY_S`` and at the end, the spool is ingested with the archive's
own ingest (``console.archive.ingest.run_ingest``), which reads a grown file
from where the last ingest stopped: nothing is stored twice, and the
archive holds what the batch commands would read from the spool.
"""

from __future__ import annotations

import math
import threading
import time
from pathlib import Path

from console.analysis.timefmt import iso
from console.sources.base import GnssFix, Item, LineBlock

INGEST_EVERY_S = 30.0


def spool_dir(archive: Path) -> Path:
    return archive.with_name(archive.name + ".live")


class LiveArchiver:
    """Spools followed items and ingests the spool into the archive now and then."""

    def __init__(self, archive: Path, layout: str | None = None) -> None:
        self.archive = archive
        self.layout = layout
        self.spool = spool_dir(archive)
        self.spool.mkdir(parents=True, exist_ok=True)
        self._files: dict[str, Path] = {}
        self._last_ingest = time.monotonic()
        self._thread: threading.Thread | None = None
        self.ingests = 0
        self.errors: list[str] = []

    def _path(self, key: str, suffix: str) -> Path:
        p = self._files.get(key)
        if p is None:
            safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in key)[-120:]
            p = self._files[key] = self.spool / f"{safe}{suffix}"
        return p

    def __call__(self, item: Item) -> None:
        if isinstance(item, LineBlock):
            with self._path(item.file, ".log").open("ab") as f:
                f.write(item.data)
        elif isinstance(item, GnssFix) and not (math.isnan(item.lat_deg) or math.isnan(item.lon_deg)):
            p = self._path("gnss-" + item.source, ".csv")
            new = not p.exists()
            role = item.role or ("eot" if item.device.endswith("-eot") else "head")
            speed = "" if math.isnan(item.speed_mps) else f"{item.speed_mps:.2f}"
            course = "" if math.isnan(item.course_deg) else f"{item.course_deg:.1f}"
            device = f"{item.train}-{role}" if item.train else item.device
            with p.open("a", encoding="utf-8") as f:
                if new:
                    f.write("time,device,role,lat,lon,speed,course\n")
                f.write(
                    f"{iso(item.t_fix_ns)}Z,{device},{role},{item.lat_deg:.7f},{item.lon_deg:.7f},{speed},{course}\n"
                )

    def tick(self) -> None:
        """Ingest in the background every INGEST_EVERY_S (never two at once)."""
        if time.monotonic() - self._last_ingest < INGEST_EVERY_S:
            return
        if self._thread is not None and self._thread.is_alive():
            return
        self._last_ingest = time.monotonic()
        self._thread = threading.Thread(target=self.ingest, kwargs={"wait": False}, daemon=True)
        self._thread.start()

    def ingest(self, wait: bool = True) -> None:
        from console.archive.ingest import run_ingest
        from console.archive.store import ArchiveBusy, ArchiveError

        files = sorted(p for p in self.spool.iterdir() if p.is_file())
        if not files:
            return
        try:
            run_ingest(files, self.archive, layout=self.layout, wait=wait)
            self.ingests += 1
        except ArchiveBusy:
            pass  # another ingest is writing: the next turn takes it
        except (ArchiveError, OSError) as exc:
            self.errors.append(str(exc))

    def finish(self) -> None:
        if self._thread is not None:
            self._thread.join()
        self.ingest(wait=True)
