"""The vendor IMU formats the daemon tests play: each with the [imu] table of a sensor as its makers label it."""
from __future__ import annotations

DECLARED = {"sync": "A5 5A", "length": 33, "endian": "little", "checksum": "crc32", "checksum_from": 2,
            "fields": ["counter u16", "dtheta_x i32 4.656612873077393e-10", "dtheta_y i32 4.656612873077393e-10",
                       "dtheta_z i32 4.656612873077393e-10", "dv_x i32 5.960464477539063e-08",
                       "dv_y i32 5.960464477539063e-08", "dv_z i32 5.960464477539063e-08", "status u8",
                       "checksum u32"]}
"""A frame declared in [imu.frame]: Δθ in 2⁻³¹ rad, Δv in 2⁻²⁴ m/s, a u16 counter, zlib's CRC-32."""
VENDOR_IMUS = {"stim300": {"format": "stim300", "axes": ["y", "x", "-z"]},
               "kvh1750": {"format": "kvh1750", "axes": ["y", "x", "-z"]},
               "kvh1775": {"format": "kvh1775"},
               "xsens": {"format": "xsens", "axes": ["-y", "x", "z"]},
               "frame": {"format": "frame", "frame": DECLARED}}
"""The [imu] table of each vendor format: STIM300 and KVH labelled x forward, y right, z down; Xsens x forward,
y left, z up."""
