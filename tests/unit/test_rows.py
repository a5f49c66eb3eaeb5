"""The log readers' compiled fast path against numpy's reader (protocol/_rows.pyx).

GIVEN chunks of rows of any finite float64 in the writers' and other plain spellings, with spaces, blank lines and
comments, WHEN the fast path parses them, THEN it gives numpy's bits. GIVEN any text at all, THEN it either refuses
(None: the exact reader takes over) or agrees with numpy's reader on a chunk numpy reads as finite rows.
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sinsalign.protocol._rows import parse_rows

NCOLS = 3
finite = st.floats(allow_nan=False, allow_infinity=False)
spelling = st.sampled_from(["{:.17g}", "{!r}", "{:.3f}", "{:+.6e}", "{:.0f}", "{:.12E}"])
blank = st.sampled_from(["", " ", "\t", "  \t"])


def numpy_rows(text: str) -> np.ndarray:
    kept = [line for line in text.split("\n") if line.strip() and not line.strip().startswith("#")]
    return np.loadtxt(kept, delimiter=",", ndmin=2, comments=None) if kept else np.empty((0, NCOLS))


@st.composite
def plain_chunk(draw) -> str:
    lines = []
    for _ in range(draw(st.integers(0, 30))):
        kind = draw(st.sampled_from(["row", "row", "row", "comment", "blank"]))
        if kind == "row":
            cells = [draw(blank) + draw(spelling).format(draw(finite)) + draw(blank) for _ in range(NCOLS)]
            lines.append(",".join(cells))
        elif kind == "comment":
            lines.append(draw(blank) + "#" + draw(st.text(st.characters(codec="ascii", exclude_characters="\n\r"))))
        else:
            lines.append(draw(blank))
    return "".join(line + "\n" for line in lines)


@settings(max_examples=300, deadline=None)
@given(plain_chunk())
def test_plain_rows_are_parsed_to_numpys_bits(text):
    got = parse_rows(text.encode(), NCOLS)
    assert got is not None
    assert got.tobytes() == numpy_rows(text).tobytes() and got.shape[1] == NCOLS


@settings(max_examples=500, deadline=None)
@given(st.text(st.characters(codec="ascii"), max_size=200) | plain_chunk().map(lambda t: t[:len(t) // 2] + "x,"))
def test_anything_else_is_refused_or_read_as_numpy_reads_it(text):
    got = parse_rows(text.encode(), NCOLS)
    if got is None:
        return
    expected = numpy_rows(text)
    assert got.tobytes() == expected.tobytes()


@pytest.mark.parametrize("text", ["1,2\n", "1,2,3,4\n", "1,2,\n", "1,2,nan\n", "1,2,inf\n", "1,2,1e309\n",
                                  "1,2,3\r\n", "1,2,0x10\n", "1,2,1_0\n", "1,2,1d5\n", "1,,3\n", "1,2,.\n",
                                  "1,2,e5\n", "1,2,3 4\n", "1,2,--3\n", "1,2,3\x00\n"])
def test_what_needs_a_diagnosis_is_refused(text):
    assert parse_rows(text.encode(), NCOLS) is None
