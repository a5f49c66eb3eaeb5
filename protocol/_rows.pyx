# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The log readers' fast path: the plain rows of a CSV chunk parsed in one compiled pass (docs/performance.md).

It accepts only what needs no diagnosis: lines of ``ncols`` plain decimal numbers ([+-]digits[.digits][e[+-]digits],
spaces or tabs around them) separated by commas, blank lines, and comment lines ('#' first after any spaces). Each
number is converted by the C library's correctly rounded ``strtod``, as numpy's text reader converts it, so the
values are the same bits. Anything else (a letter, a missing or extra cell, a number beyond float64, a carriage
return, a byte beyond ASCII) returns None, and the reader takes its exact path that names the file, line and column.
"""
from libc.math cimport isfinite
from libc.stdlib cimport strtod

import numpy as np


cdef inline bint _blank(char c) noexcept nogil:
    return c == b' ' or c == b'\t'


cdef inline bint _digit(char c) noexcept nogil:
    return b'0' <= c <= b'9'


cdef Py_ssize_t _number_end(const char* s, Py_ssize_t p) noexcept nogil:
    """The end of the plain decimal number at ``s[p]``, or -1 if there is none."""
    cdef Py_ssize_t digits = 0
    if s[p] == b'+' or s[p] == b'-':
        p += 1
    while _digit(s[p]):
        p += 1
        digits += 1
    if s[p] == b'.':
        p += 1
        while _digit(s[p]):
            p += 1
            digits += 1
    if digits == 0:
        return -1
    if s[p] == b'e' or s[p] == b'E':
        p += 1
        if s[p] == b'+' or s[p] == b'-':
            p += 1
        if not _digit(s[p]):
            return -1
        while _digit(s[p]):
            p += 1
    return p


def parse_rows(bytes data, int ncols):
    """The data rows of ``data`` (ASCII lines, each ended by a newline) as an (N, ncols) float64 array, every value
    finite; None where the chunk holds anything beyond plain rows, blank lines and comments."""
    cdef const char* s = data
    cdef Py_ssize_t n = len(data), p = 0, end, rows = data.count(b"\n") + 1, row = 0
    cdef int col
    cdef char* stop
    cdef double value
    out = np.empty((rows, ncols))
    cdef double[:, ::1] o = out
    while p < n:
        while _blank(s[p]):
            p += 1
        if s[p] == b'\n':
            p += 1
            continue
        if s[p] == b'#':
            while p < n and s[p] != b'\n':
                p += 1
            p += 1
            continue
        if p >= n:
            break
        col = 0
        while True:
            while _blank(s[p]):
                p += 1
            end = _number_end(s, p)
            if end < 0 or col >= ncols:
                return None
            value = strtod(s + p, &stop)
            if stop != s + end or not isfinite(value):
                return None
            o[row, col] = value
            col += 1
            p = end
            while _blank(s[p]):
                p += 1
            if s[p] == b',':
                p += 1
            elif s[p] == b'\n' or p >= n:
                break
            else:
                return None
        if col != ncols:
            return None
        row += 1
        p += 1
    return out[:row]
