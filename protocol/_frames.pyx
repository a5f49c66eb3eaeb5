# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The serial frame decoder's fast path: a run of plain IMU frames decoded in one compiled pass (docs/performance.md).

A run is what needs no decision: frames back to back from the first byte, each whole, of the protocol's version and
the IMU message type with the IMU payload's length, its header check and CRC-32 right, and its sequence counter the
one after the last accepted. Each becomes a sample row as :func:`~sinsalign.protocol.serial_frame.decode_imu` gives
it (integers times the LSBs, the nanoseconds as the nearest double times 1e-9). The run stops at the first byte that
is anything else (garbage, another type, a bad check, a gap in the counter, an incomplete frame): the decoder's exact
path takes it from there, counts it and resynchronises.

The frame's layout, LSBs, full scale and CRC-32 table are not written here: :class:`ImuRun` takes them from
``serial_frame.py``, which defines the frame (its byte offsets from the header's struct, the table from zlib's
CRC-32). What the kernel fixes is its typed face: six signed 32-bit values and a 32-bit status word in the payload,
a 16-bit length, counter and header check, a 64-bit time in ns, read as the host's integers (the caller takes this
path on a little-endian host only).
"""
from libc.stdint cimport int32_t, int64_t, uint16_t, uint32_t, uint64_t
from libc.string cimport memcpy

import numpy as np


cdef inline uint32_t _crc32(const uint32_t* table, const unsigned char* p, Py_ssize_t n) noexcept nogil:
    """CRC-32 of n bytes with the reflected ``table`` (pre- and post-inverted, as zlib's)."""
    cdef uint32_t c = 0xFFFFFFFFu
    cdef Py_ssize_t i
    for i in range(n):
        c = table[(c ^ p[i]) & 0xFF] ^ (c >> 8)
    return c ^ 0xFFFFFFFFu


cdef class ImuRun:
    """The fast path of one frame layout (module docstring); :meth:`run` decodes a run."""

    cdef unsigned char sync0, sync1, version, msg_type
    cdef Py_ssize_t header_bytes, payload_bytes, frame_bytes, length_at, seq_at, time_at, check_at
    cdef double dtheta_lsb, dv_lsb
    cdef int64_t full_scale
    cdef uint32_t table[256]

    def __init__(self, bytes sync, int version, int msg_type, Py_ssize_t header_bytes, Py_ssize_t length_at,
                 Py_ssize_t seq_at, Py_ssize_t time_at, Py_ssize_t check_at, Py_ssize_t payload_bytes,
                 Py_ssize_t crc_bytes, double dtheta_lsb_rad, double dv_lsb_mps, int64_t full_scale,
                 const uint32_t[::1] crc_table):
        """``sync`` (2 bytes), the protocol ``version`` and the IMU ``msg_type``; the header's length and the byte
        offsets in it of the payload length, the counter, the time and the header check; the IMU payload's and the
        CRC's lengths; the LSBs of Δθ (rad) and Δv (m/s); the count at which a value is saturated; CRC-32's table
        (256 entries)."""
        cdef int i
        if len(sync) != 2 or crc_table.shape[0] != 256 or payload_bytes != 28 or crc_bytes != 4:
            raise ValueError("ImuRun: a 2-byte sync word, 256 table entries, six int32 and a uint32 status, CRC-32")
        self.sync0, self.sync1, self.version, self.msg_type = sync[0], sync[1], version, msg_type
        self.header_bytes, self.payload_bytes = header_bytes, payload_bytes
        self.frame_bytes = header_bytes + payload_bytes + crc_bytes
        self.length_at, self.seq_at, self.time_at, self.check_at = length_at, seq_at, time_at, check_at
        self.dtheta_lsb, self.dv_lsb, self.full_scale = dtheta_lsb_rad, dv_lsb_mps, full_scale
        for i in range(256):
            self.table[i] = crc_table[i]

    def crc32(self, const unsigned char[::1] data) -> int:
        """CRC-32 of ``data`` with this layout's table (for the tests: it must equal zlib.crc32)."""
        return _crc32(self.table, &data[0], data.shape[0]) if data.shape[0] else 0

    def run(self, const unsigned char[::1] buf, Py_ssize_t pos, Py_ssize_t last_seq, double[:, ::1] rows):
        """Decode the run of plain IMU frames at ``buf[pos:]`` following sequence counter ``last_seq`` into ``rows``
        (N, 9: t s, Δθ (3) rad, Δv (3) m/s, status, saturated 1.0/0.0), as many as fit; returns (frames, the
        position after them, the last one's counter)."""
        cdef Py_ssize_t n = 0, end = buf.shape[0], k
        cdef const unsigned char* p
        cdef uint16_t length, seq, check
        cdef uint64_t time_ns
        cdef int32_t values[6]
        cdef uint32_t status, crc
        cdef bint saturated
        cdef int64_t magnitude
        cdef Py_ssize_t payload_at = self.header_bytes, crc_at = self.header_bytes + self.payload_bytes
        while n < rows.shape[0] and end - pos >= self.frame_bytes:
            p = &buf[pos]
            if p[0] != self.sync0 or p[1] != self.sync1 or p[2] != self.version or p[3] != self.msg_type:
                break
            memcpy(&length, p + self.length_at, 2)
            memcpy(&seq, p + self.seq_at, 2)
            memcpy(&check, p + self.check_at, 2)
            if length != self.payload_bytes or seq != ((last_seq + 1) & 0xFFFF):
                break
            if (_crc32(self.table, p + 2, self.check_at - 2) & 0xFFFF) != check:
                break
            memcpy(&crc, p + crc_at, 4)
            if _crc32(self.table, p + 2, crc_at - 2) != crc:
                break
            memcpy(&time_ns, p + self.time_at, 8)
            memcpy(values, p + payload_at, 24)
            memcpy(&status, p + payload_at + 24, 4)
            saturated = False
            for k in range(6):
                magnitude = <int64_t>values[k] if values[k] >= 0 else -<int64_t>values[k]
                saturated = saturated or magnitude >= self.full_scale
            rows[n, 0] = <double>time_ns * 1e-9
            for k in range(3):
                rows[n, 1 + k] = values[k] * self.dtheta_lsb
                rows[n, 4 + k] = values[3 + k] * self.dv_lsb
            rows[n, 7] = status
            rows[n, 8] = 1.0 if saturated else 0.0
            last_seq = seq
            pos += self.frame_bytes
            n += 1
        return n, pos, last_seq
