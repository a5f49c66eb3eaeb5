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
from sinsalign.protocol._rows import newlines, parse_rows, plain_text, rows_within
from sinsalign.protocol.imu_log import Range, RowLimits, first_not_increasing

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
    got = parse_rows(text, NCOLS, 4096)
    assert got is not None
    assert got.tobytes() == numpy_rows(text).tobytes() and got.shape[1] == NCOLS


@settings(max_examples=500, deadline=None)
@given(st.text(st.characters(codec="ascii"), max_size=200) | plain_chunk().map(lambda t: t[:len(t) // 2] + "x,"))
def test_anything_else_is_refused_or_read_as_numpy_reads_it(text):
    got = parse_rows(text, NCOLS, 4096)
    if got is None:
        return
    expected = numpy_rows(text)
    assert got.tobytes() == expected.tobytes()


@pytest.mark.parametrize("text", ["1,2\n", "1,2,3,4\n", "1,2,\n", "1,2,nan\n", "1,2,inf\n", "1,2,1e309\n",
                                  "1,2,3\r\n", "1,2,0x10\n", "1,2,1_0\n", "1,2,1d5\n", "1,,3\n", "1,2,.\n",
                                  "1,2,e5\n", "1,2,3 4\n", "1,2,--3\n", "1,2,3\x00\n"])
def test_what_needs_a_diagnosis_is_refused(text):
    assert parse_rows(text, NCOLS, 4096) is None


@pytest.mark.parametrize("spelling", ["{:.17g}", "{:.15g}", "{:.6e}", "{:.20g}", "{:.25e}"])
def test_any_float64_bits_are_read_as_correctly_rounded(spelling):
    """Random bit patterns (subnormals, the extremes), written with up to 26 digits: Python's correctly rounded
    float() is the truth; the fast paths (exact products, Eisel-Lemire) and strtod must all give its bits."""
    rng = np.random.default_rng(7)
    values = rng.integers(0, 2**64, 20000, dtype=np.uint64, endpoint=False).view(np.float64)
    values = values[np.isfinite(values)]
    cells = [spelling.format(float(v)) for v in values]
    got = parse_rows("".join(cell + "\n" for cell in cells), 1, 4096)
    assert got is not None
    assert got[:, 0].tobytes() == np.array([float(cell) for cell in cells]).tobytes()


@pytest.mark.parametrize("text", ["9007199254740993\n", "2.2250738585072011e-308\n", "4.9406564584124654e-324\n",
                                  "1.7976931348623157e308\n", "-0\n", "00000001.5\n",
                                  "0.1000000000000000055511151231257827\n",
                                  "123456789012345678901234567890\n", "1e-400\n", "7.2057594037927933e16\n"])
def test_ties_and_edges_are_rounded_as_float_rounds_them(text):
    got = parse_rows(text, 1, 4096)
    assert got is not None and got[0, 0].tobytes() == np.float64(float(text)).tobytes()


def test_a_line_longer_than_the_bound_is_refused():
    row = "1," * 10 + "1\n"
    assert parse_rows(row * 3, 11, len(row)) is not None
    assert parse_rows(row + " " * len(row) + "\n" + row, 11, len(row)) is None
    assert parse_rows("#" + "x" * len(row) + "\n", 11, len(row)) is None


@settings(max_examples=300, deadline=None)
@given(st.text(alphabet=st.sampled_from("0123456789.,-e\n# xé"), max_size=300))
def test_newlines_are_counted_as_str_counts_them(text):
    assert newlines(text) == text.count("\n")


RANGES = [Range(-1e4, 1e4), Range(-1.0, 1.0, open_low=True), Range(0.0, 2.0, open_high=True)]


@settings(max_examples=500, deadline=None)
@given(st.lists(st.lists(st.sampled_from([-1e5, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 3.0, 1e5]), min_size=3, max_size=3),
                min_size=0, max_size=6),
       st.booleans(), st.sampled_from([-np.inf, -1.0, 0.5]))
def test_the_compiled_range_check_is_the_numpy_one(rows, increasing, t_last):
    block = np.array(rows, dtype=float).reshape(-1, 3)
    columns = ("t", "a", "b")
    limits = RowLimits(dict(zip(columns, RANGES, strict=True)))
    want = limits.problem(block, columns) is None and (
        not increasing or first_not_increasing(block[:, 0], t_last) is None)
    low, high = np.array([r.low for r in RANGES]), np.array([r.high for r in RANGES])
    open_low = np.array([r.open_low for r in RANGES], dtype=np.uint8)
    open_high = np.array([r.open_high for r in RANGES], dtype=np.uint8)
    assert rows_within(block, low, high, open_low, open_high, increasing, t_last) == want


@pytest.mark.parametrize(("text", "refused"), [("1,2,3\n# restart: sensor\n4,5,6\n", True),
                                               ("# restart:\n", True),
                                               ("1,2,3\n # restart: indented, a comment\n", False),
                                               ("1,2,3\n# a comment # restart: inside\n", False),
                                               ("1,2,3\n# restart\n", False)])
def test_a_line_that_begins_with_the_marker_refuses_the_piece(text, refused):
    """The log's restart marker is a comment the reader acts on: the piece goes to the line reader, which cuts there;
    the same words anywhere but at a line's start are a plain comment."""
    assert (parse_rows(text, NCOLS, 4096, b"# restart:") is None) == refused
    assert parse_rows(text, NCOLS, 4096) is not None


@settings(max_examples=300, deadline=None)
@given(plain_chunk() | st.text(st.characters(codec="ascii"), max_size=200))
def test_a_buffer_of_the_text_parses_as_the_text(text):
    """The reader hands its pieces as views of its read: the same rows (or refusal) as the str of the same bytes."""
    data = bytearray(text.encode() + b"9")   # a byte after the view: the parse must not read it
    got, want = parse_rows(memoryview(data)[:-1], NCOLS, 4096), parse_rows(text, NCOLS, 4096)
    assert (got is None) == (want is None)
    if got is not None:
        assert got.tobytes() == want.tobytes()
    assert newlines(memoryview(data)[:-1]) == text.count("\n")


@pytest.mark.parametrize("data", [b"1,2,3\n# caf\xc3\xa9\n", b"1,2,3\n# a\rb\n", b"1,2,3\n# \xff\n", b"1,2,3"])
def test_a_buffer_beyond_plain_ascii_or_without_its_last_line_end_is_refused(data):
    """Bytes whose text a text-mode read would give otherwise (a carriage return ends a line there) are refused."""
    assert parse_rows(data, NCOLS, 4096) is None


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=100), st.integers(0, 7))
def test_plain_text_is_ascii_without_a_carriage_return(data, offset):
    view = memoryview(bytearray(b"x" * offset + data))[offset:]   # any alignment
    assert plain_text(view) == (data.isascii() and b"\r" not in data)
