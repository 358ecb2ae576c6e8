"""The GNSS units' LoRa link: airtime, duty cycle and so the report period.

Semtech's time-on-air formula (SX1276 datasheet §4.1.1.7): a symbol lasts
2^SF / BW; the preamble is n + 4.25 symbols; the payload takes
8 + max(ceil((8·PL − 4·SF + 28 + 16·CRC − 20·IH) / (4·(SF − 2·DE)))·(CR + 4), 0)
symbols.  A 20-byte packet at 125 kHz, CR 4/5, CRC on, explicit header
takes about 57 ms at SF7 and 1.3 s at SF12 (low-data-rate optimisation on
at SF11/12).  Under a 1 % duty cycle a unit may send one packet every
airtime / 0.01: 5.7 s at SF7, 132 s at SF12.  The report period of the
simulated head and EOT units is that consequence, not a free number.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class LoRaLink:
    spreading_factor: int = 7
    bandwidth_hz: float = 125_000.0
    coding_rate: int = 1  # 4/(4+CR): 1 → 4/5
    payload_bytes: int = 20
    preamble_symbols: int = 8
    crc: bool = True
    explicit_header: bool = True
    duty_cycle: float = 0.01
    processing_s: float = 0.05  # unit and crossing-unit handling on top of the airtime

    @property
    def low_data_rate_optimize(self) -> bool:
        # Mandated when a symbol lasts longer than 16 ms (SF11 and SF12 at 125 kHz).
        return (2**self.spreading_factor) / self.bandwidth_hz > 0.016

    def airtime_s(self) -> float:
        """Time on air of one packet."""
        sf, bw = self.spreading_factor, self.bandwidth_hz
        t_sym = (2**sf) / bw
        de = 1 if self.low_data_rate_optimize else 0
        ih = 0 if self.explicit_header else 1
        numerator = 8 * self.payload_bytes - 4 * sf + 28 + 16 * int(self.crc) - 20 * ih
        payload_symbols = 8 + max(math.ceil(numerator / (4 * (sf - 2 * de))) * (self.coding_rate + 4), 0)
        return (self.preamble_symbols + 4.25) * t_sym + payload_symbols * t_sym

    def report_period_s(self) -> float:
        """The shortest interval between packets the duty cycle allows."""
        return self.airtime_s() / self.duty_cycle

    def latency_s(self) -> float:
        """From the fix to the crossing unit: the packet's airtime plus handling."""
        return self.airtime_s() + self.processing_s
