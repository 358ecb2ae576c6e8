"""can: — a live CAN bus through python-can's virtual interface."""

from __future__ import annotations

import threading
import uuid

import can
import pytest

from console.sources import SourceError, open_source
from console.sources.base import CanFrame, Item
from tests.live_fixtures import wait_until

pytestmark = pytest.mark.timeout(30)


def test_frames_from_a_virtual_bus_arrive_and_sequence_gaps_count_as_lost() -> None:
    channel = f"trackside-{uuid.uuid4().hex[:8]}"
    src = open_source(f"can:virtual:{channel}")
    got: list[Item] = []
    lock = threading.Lock()

    def sink(item: Item) -> None:
        with lock:
            got.append(item)

    src.start(sink)
    sender = can.Bus(interface="virtual", channel=channel)
    try:
        assert wait_until(lambda: src.status().connected, 5)
        for seq in (1, 2, 5, 6):  # 3 and 4 lost
            sender.send(can.Message(arbitration_id=0x180 + 3, data=[0x00, 0xA5, 7, 0, seq], is_extended_id=False))
        sender.send(can.Message(arbitration_id=0x7FF, data=[1, 2], is_extended_id=False))  # a foreign frame
        assert wait_until(lambda: src.status().messages == 5, 5), src.status()
    finally:
        sender.shutdown()
        src.stop()
    frames = [i for i in got if isinstance(i, CanFrame)]
    assert [f.arbitration_id for f in frames] == [0x183] * 4 + [0x7FF]
    assert frames[2].data == bytes([0x00, 0xA5, 7, 0, 5])
    assert src.status().lost == 2


def test_an_unknown_interface_is_refused_before_starting() -> None:
    with pytest.raises(SourceError, match="unknown python-can interface"):
        open_source("can:nosuchbus:x").check()
