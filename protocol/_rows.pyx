# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The log readers' fast path: the plain rows of a CSV chunk parsed in one compiled pass (docs/performance.md).

It accepts only what needs no diagnosis: lines of ``ncols`` plain decimal numbers ([+-]digits[.digits][e[+-]digits],
spaces or tabs around them) separated by commas, blank lines, and comment lines ('#' first after any spaces). Each
number is converted to the nearest float64 (ties to even), the bits of the C library's correctly rounded ``strtod``
that numpy's text reader calls: exactly by one rounded product or quotient when the digits and the power of ten are
both exact doubles (Clinger's fast path), else by the Eisel-Lemire algorithm (the digits times a 128-bit truncation
of the power of five, accepted only where that truncation cannot change the rounding), else by ``strtod`` itself
(more than 19 significant digits, subnormal results, the undecidable few). Anything else (a letter, a missing or
extra cell, a number beyond float64, a carriage return, a byte beyond ASCII) returns None, and the reader takes its
exact path that names the file, line and column.
"""
from libc.math cimport isfinite
from libc.stdint cimport int64_t, uint64_t
from libc.stdlib cimport strtod
from libc.string cimport memchr, memcmp, memcpy
from cpython.unicode cimport PyUnicode_AsUTF8AndSize

import numpy as np


cdef extern from *:
    """
    #include <stdint.h>
    static inline void sinsalign_mul_64x64(uint64_t a, uint64_t b, uint64_t *lo, uint64_t *hi) {
        unsigned __int128 r = (unsigned __int128)a * b;
        *lo = (uint64_t)r;
        *hi = (uint64_t)(r >> 64);
    }
    """
    void _mul_64x64 "sinsalign_mul_64x64"(uint64_t a, uint64_t b, uint64_t* lo, uint64_t* hi) noexcept nogil
    int _leading_zeros "__builtin_clzll"(uint64_t x) noexcept nogil


DEF SMALLEST_POWER = -342   # below, any 19-digit significand rounds to zero; above LARGEST_POWER, to infinity
DEF LARGEST_POWER = 308
DEF MAX_DIGITS = 19         # significant digits a uint64 always holds
DEF ZERO = 48               # '0'

cdef uint64_t _POW5_HI[LARGEST_POWER - SMALLEST_POWER + 1]
cdef uint64_t _POW5_LO[LARGEST_POWER - SMALLEST_POWER + 1]
cdef double _POW10[23]


def _fill_tables() -> None:
    """5^q for q in [SMALLEST_POWER, LARGEST_POWER] as 128-bit significands, the top bit set: truncated for q >= 0,
    a truncated reciprocal plus one for q < 0 (the Eisel-Lemire tables); 10^k for k <= 22, each an exact double."""
    for q in range(SMALLEST_POWER, LARGEST_POWER + 1):
        if q >= 0:
            c = 5 ** q
            bits = c.bit_length()
            c = c << (128 - bits) if bits <= 128 else c >> (bits - 128)
        else:
            power5 = 5 ** -q
            z = power5.bit_length()          # the least z with 2^z >= 5^-q (no power of five is a power of two)
            c = 2 ** (z + 127 if q >= -27 else 2 * z + 128) // power5 + 1
            if c.bit_length() > 128:
                c >>= c.bit_length() - 128
        _POW5_HI[q - SMALLEST_POWER] = c >> 64
        _POW5_LO[q - SMALLEST_POWER] = c & 0xFFFFFFFFFFFFFFFF
    for q in range(23):
        _POW10[q] = float(10 ** q)


_fill_tables()


cdef inline bint _eisel_lemire(int64_t q, uint64_t w, bint negative, double* out) noexcept nogil:
    """w * 10^q (w > 0) rounded to the nearest float64 into ``out``; False where this algorithm cannot decide
    (or the result is subnormal or beyond float64): the caller asks strtod."""
    cdef uint64_t lo, hi, second_lo, second_hi, mantissa, bits
    cdef int lz, upper_bit
    cdef int64_t power2
    if q < SMALLEST_POWER or q > LARGEST_POWER:
        return False
    lz = _leading_zeros(w)
    w <<= lz
    _mul_64x64(w, _POW5_HI[q - SMALLEST_POWER], &lo, &hi)
    if (hi & 0x1FF) == 0x1FF:    # the bits below the 55 kept may carry into them: take the table's next word
        _mul_64x64(w, _POW5_LO[q - SMALLEST_POWER], &second_lo, &second_hi)
        lo += second_hi
        if second_hi > lo:
            hi += 1
    if lo == ~(<uint64_t>0) and (q < -27 or q > 55):
        return False
    upper_bit = <int>(hi >> 63)
    mantissa = hi >> (upper_bit + 9)
    power2 = ((q * (152170 + 65536)) >> 16) + 63 + upper_bit - lz + 1023
    if power2 <= 0:
        return False
    if (lo <= 1 and -4 <= q <= 23 and (mantissa & 3) == 1
            and (mantissa << (upper_bit + 9)) == hi):   # exactly halfway: round to even, down
        mantissa &= ~(<uint64_t>1)
    mantissa += mantissa & 1
    mantissa >>= 1
    if mantissa >= (<uint64_t>2 << 52):
        mantissa = <uint64_t>1 << 52
        power2 += 1
    mantissa &= ~(<uint64_t>1 << 52)
    if power2 >= 0x7FF:
        return False
    bits = mantissa | (<uint64_t>power2 << 52) | (<uint64_t>negative << 63)
    memcpy(out, &bits, 8)
    return True


cdef inline bint _blank(char c) noexcept nogil:
    return c == b' ' or c == b'\t'


cdef inline bint _digit(char c) noexcept nogil:
    return b'0' <= c <= b'9'


cdef Py_ssize_t _number(const char* s, Py_ssize_t p, double* value) noexcept nogil:
    """The end of the plain decimal number at ``s[p]``, its value in ``value``; -1 if there is none."""
    cdef Py_ssize_t start = p
    cdef Py_ssize_t digits = 0, significant = 0
    cdef uint64_t w = 0
    cdef int64_t q = 0, exponent = 0
    cdef bint negative = s[p] == b'-', exponent_negative = False
    cdef char* stop
    if s[p] == b'+' or s[p] == b'-':
        p += 1
    while _digit(s[p]):
        if w or s[p] != b'0':
            significant += 1
            w = w * 10 + <uint64_t>(s[p] - ZERO)
        p += 1
        digits += 1
    if s[p] == b'.':
        p += 1
        while _digit(s[p]):
            if w or s[p] != b'0':
                significant += 1
                w = w * 10 + <uint64_t>(s[p] - ZERO)
            q -= 1
            p += 1
            digits += 1
    if digits == 0:
        return -1
    if s[p] == b'e' or s[p] == b'E':
        p += 1
        if s[p] == b'+' or s[p] == b'-':
            exponent_negative = s[p] == b'-'
            p += 1
        if not _digit(s[p]):
            return -1
        while _digit(s[p]):
            if exponent < 100000:   # any more is zero or infinity for every significand
                exponent = exponent * 10 + (s[p] - ZERO)
            p += 1
        q += -exponent if exponent_negative else exponent
    if significant > MAX_DIGITS:   # w wrapped: the C library's conversion
        value[0] = strtod(s + start, &stop)
        return p if stop == s + p else -1
    if w == 0:
        value[0] = -0.0 if negative else 0.0
    elif -22 <= q <= 22 and w <= (<uint64_t>1 << 53):   # both exact doubles: one correctly rounded operation
        value[0] = <double>w / _POW10[-q] if q < 0 else <double>w * _POW10[q]
        if negative:
            value[0] = -value[0]
    elif not _eisel_lemire(q, w, negative, value):
        value[0] = strtod(s + start, &stop)
        if stop != s + p:
            return -1
    return p


cdef Py_ssize_t _parse(const char* s, Py_ssize_t n, int ncols, Py_ssize_t max_line_chars,
                       const char* marker, Py_ssize_t marker_len, double* o) noexcept nogil:
    """The rows of ``s[:n]`` into ``o`` (row-major, ``ncols`` a row, room for every line): how many, or -1 where the
    text holds anything beyond plain rows (:func:`parse_rows`)."""
    cdef Py_ssize_t p = 0, end, line_start = 0, row = 0
    cdef int col
    cdef double value
    while p < n:
        while _blank(s[p]):
            p += 1
        if s[p] == b'\n':
            p += 1
            if p - line_start > max_line_chars:
                return -1
            line_start = p
            continue
        if s[p] == b'#':
            if marker_len and p == line_start and n - p >= marker_len and memcmp(s + p, marker, marker_len) == 0:
                return -1
            while p < n and s[p] != b'\n':
                if s[p] & 0x80 or s[p] == b'\r':   # a buffer's bytes: a comment in ASCII, its line one line
                    return -1
                p += 1
            p += 1
            if p - line_start > max_line_chars:
                return -1
            line_start = p
            continue
        if p >= n:
            break
        col = 0
        while True:
            while _blank(s[p]):
                p += 1
            end = _number(s, p, &value)
            if end < 0 or col >= ncols or not isfinite(value):
                return -1
            o[row * ncols + col] = value
            col += 1
            p = end
            while _blank(s[p]):
                p += 1
            if s[p] == b',':
                p += 1
            elif s[p] == b'\n' or p >= n:
                break
            else:
                return -1
        if col != ncols:
            return -1
        row += 1
        p += 1
        if p - line_start > max_line_chars:
            return -1
        line_start = p
    return row


def parse_rows(text, int ncols, Py_ssize_t max_line_chars, bytes marker=b""):
    """The data rows of ``text`` (lines, each ended by a newline) as an (N, ncols) float64 array, every value
    finite; None where the chunk holds anything beyond plain rows, blank lines and comments in ASCII, a line of
    more than ``max_line_chars`` characters (the newline included), a line that begins with ``marker`` (a comment
    the caller acts on: the log's restart marker), or a last line without its newline (a file cut inside it).
    ``text`` is a str, or the bytes of a piece of text in any buffer (a view of a read: :func:`plain_text` says
    where its bytes are their text). The pass runs without the interpreter's lock, so a reader thread parses while
    another runs the alignment."""
    cdef const unsigned char[::1] data
    cdef const char* s
    cdef Py_ssize_t n, rows, lines
    if isinstance(text, str):
        if not text.isascii():
            return None
        s = PyUnicode_AsUTF8AndSize(text, &n)   # an ASCII str's own bytes, not a copy
    else:
        data = text
        n = data.shape[0]
        s = _start(data)
    if n and s[n - 1] != b'\n':   # also keeps the parse, which reads the character after a number, in the buffer
        return None
    cdef const char* m = marker
    cdef Py_ssize_t marker_len = len(marker)
    with nogil:
        lines = _newlines(s, n)
    out = np.empty((lines + 1, ncols))
    cdef double[:, ::1] o = out
    with nogil:
        rows = _parse(s, n, ncols, max_line_chars, m, marker_len, &o[0, 0])
    return None if rows < 0 else out[:rows]


cdef const char* _EMPTY = b""


cdef inline const char* _start(const unsigned char[::1] data) noexcept:
    """The first byte of a buffer, a valid address when it has none."""
    return <const char*>&data[0] if data.shape[0] else _EMPTY


cdef Py_ssize_t _newlines(const char* s, Py_ssize_t n) noexcept nogil:
    """The newlines among the n characters at s (the C library's memchr finds each)."""
    cdef Py_ssize_t count = 0
    cdef const char* end = s + n
    cdef const char* p = <const char*>memchr(s, b'\n', n)
    while p != NULL:
        count += 1
        p = <const char*>memchr(p + 1, b'\n', end - p - 1)
    return count


def newlines(text):
    """``text.count("\n")`` of a str, or the newline bytes of a buffer, counted without the interpreter's lock where
    the text is ASCII."""
    cdef const unsigned char[::1] data
    cdef const char* s
    cdef Py_ssize_t n, count
    if isinstance(text, str):
        if not text.isascii():
            return text.count("\n")
        s = PyUnicode_AsUTF8AndSize(text, &n)
    else:
        data = text
        n = data.shape[0]
        s = _start(data)
    with nogil:
        count = _newlines(s, n)
    return count


def plain_text(const unsigned char[::1] data):
    """Whether the bytes of ``data`` are ASCII without a carriage return: then they are their own text, line for
    line, as a text-mode read (UTF-8, universal newlines) gives it. Without the interpreter's lock."""
    cdef const char* s = _start(data)
    cdef Py_ssize_t i, n = data.shape[0], words = data.shape[0] // 8
    cdef uint64_t word, seen = 0
    cdef bint plain
    with nogil:
        for i in range(words):   # the high bits of eight bytes at a time
            memcpy(&word, s + 8 * i, 8)
            seen |= word
        for i in range(8 * words, n):
            seen |= <unsigned char>s[i]
        plain = (seen & 0x8080808080808080ULL) == 0 and memchr(s, b'\r', n) == NULL
    return plain


def rows_within(const double[:, ::1] block, const double[::1] low, const double[::1] high,
                const unsigned char[::1] open_low, const unsigned char[::1] open_high, bint increasing,
                double t_last):
    """Whether every value of ``block`` (N, ncols) lies within its column's range (``low`` to ``high``, an end
    excluded where ``open_low`` or ``open_high`` says; imu_log.Range.holds) and, with ``increasing``, each time (the
    first column) exceeds the one before it (``t_last`` before the first: imu_log.first_not_increasing's steps).
    One pass without the interpreter's lock: a reading thread checks its piece while another runs the alignment."""
    cdef Py_ssize_t rows = block.shape[0], ncols = block.shape[1], i, j
    cdef double v, previous = t_last
    cdef bint good = True
    if low.shape[0] != ncols or high.shape[0] != ncols or open_low.shape[0] != ncols or open_high.shape[0] != ncols:
        raise ValueError("rows_within: one range per column")
    with nogil:
        for i in range(rows):
            for j in range(ncols):
                v = block[i, j]
                if not ((v > low[j]) if open_low[j] else (v >= low[j])) or \
                        not ((v < high[j]) if open_high[j] else (v <= high[j])):
                    good = False
                    break
            if not good:
                break
            if increasing:
                if not (block[i, 0] - previous > 0.0):
                    good = False
                    break
                previous = block[i, 0]
    return good
