"""Sensonor STIM300 normal-mode datagrams (incremental angle and velocity output)."""
from __future__ import annotations

STIM300_DATAGRAMS = (0x90, 0x91, 0x92, 0x93, 0xA4, 0xA5, 0xA6, 0xA7)
"""Normal-mode datagram identifiers."""
STIM300_DV_LSB = {10: 2.0**-22}
"""Incremental velocity LSB (m/s) by accelerometer variant (g)."""
