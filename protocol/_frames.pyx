# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The serial frame decoder's fast path: a run of plain IMU frames decoded in one compiled pass (docs/performance.md).

A run is what needs no decision: frames back to back from the first byte, each whole, of protocol version 1 and
type 1 with the IMU payload's length, its header check and CRC-32 right, and its sequence counter the one after the
last accepted. Each becomes a sample row as :func:`~sinsalign.protocol.serial_frame.decode_imu` gives it (the same
bits: integers times powers of two, the nanoseconds as the nearest double times 1e-9). The fields are read as the
host's integers: the caller takes this path on a little-endian host only. The run stops at the first
byte that is anything else (garbage, another type, a bad check, a gap in the counter, an incomplete frame): the
decoder's exact path takes it from there, counts it and resynchronises.
"""
from libc.stdint cimport int32_t, int64_t, uint16_t, uint32_t, uint64_t
from libc.string cimport memcpy

cdef uint32_t _CRC_TABLE[256]
cdef uint32_t ALL_ONES = 0xFFFFFFFFu
cdef uint32_t POLY = 0xEDB88320u   # reflected


cdef void _fill_table() noexcept:
    cdef uint32_t c
    cdef int n, k
    for n in range(256):
        c = n
        for k in range(8):
            c = (POLY ^ (c >> 1)) if c & 1 else (c >> 1)
        _CRC_TABLE[n] = c


_fill_table()


cdef inline uint32_t _crc32(const unsigned char* p, Py_ssize_t n) noexcept nogil:
    """CRC-32 (IEEE 802.3, zlib's) of n bytes."""
    cdef uint32_t c = ALL_ONES
    cdef Py_ssize_t i
    for i in range(n):
        c = _CRC_TABLE[(c ^ p[i]) & 0xFF] ^ (c >> 8)
    return c ^ ALL_ONES


def crc32(const unsigned char[::1] data) -> int:
    """CRC-32 of ``data`` (for the tests: it must equal zlib.crc32)."""
    return _crc32(&data[0], data.shape[0]) if data.shape[0] else 0


cdef enum:
    HEADER_BYTES = 18
    PAYLOAD_BYTES = 28
    FRAME_BYTES = 50   # header, IMU payload, CRC
cdef int64_t INT32_MAX = 2147483647
cdef double DTHETA_LSB_RAD = 1.0 / 2147483648.0   # 2**-31, exact
cdef double DV_LSB_MPS = 1.0 / 16777216.0        # 2**-24, exact


def imu_run(const unsigned char[::1] buf, Py_ssize_t pos, Py_ssize_t last_seq, double[:, ::1] rows):
    """Decode the run of plain IMU frames at ``buf[pos:]`` following sequence counter ``last_seq`` into ``rows``
    (N, 9: t s, Δθ (3) rad, Δv (3) m/s, status, saturated 1.0/0.0), as many as fit; returns (frames, the position
    after them, the last one's counter)."""
    cdef Py_ssize_t n = 0, end = buf.shape[0], k
    cdef const unsigned char* p
    cdef uint16_t length, seq, check
    cdef uint64_t time_ns
    cdef int32_t values[6]
    cdef uint32_t status, crc
    cdef bint saturated
    while n < rows.shape[0] and end - pos >= FRAME_BYTES:
        p = &buf[pos]
        if p[0] != 0xAA or p[1] != 0x55 or p[2] != 1 or p[3] != 1:
            break
        memcpy(&length, p + 4, 2)
        memcpy(&seq, p + 6, 2)
        memcpy(&check, p + 16, 2)
        if length != PAYLOAD_BYTES or seq != ((last_seq + 1) & 0xFFFF):
            break
        if (_crc32(p + 2, 14) & 0xFFFF) != check:
            break
        memcpy(&crc, p + HEADER_BYTES + PAYLOAD_BYTES, 4)
        if _crc32(p + 2, FRAME_BYTES - 6) != crc:
            break
        memcpy(&time_ns, p + 8, 8)
        memcpy(values, p + HEADER_BYTES, 24)
        memcpy(&status, p + HEADER_BYTES + 24, 4)
        saturated = False
        for k in range(6):
            saturated = saturated or (<int64_t>values[k] if values[k] >= 0 else -<int64_t>values[k]) >= INT32_MAX
        rows[n, 0] = <double>time_ns * 1e-9
        for k in range(3):
            rows[n, 1 + k] = values[k] * DTHETA_LSB_RAD
            rows[n, 4 + k] = values[3 + k] * DV_LSB_MPS
        rows[n, 7] = status
        rows[n, 8] = 1.0 if saturated else 0.0
        last_seq = seq
        pos += FRAME_BYTES
        n += 1
    return n, pos, last_seq
