"""Generic pose programs: CSV with a header, whitespace lists, comments, bad input."""
import numpy as np
import pytest

from postproc.core.diagnostics import PostprocError
from postproc.programs.io import read_program

from helpers import REPO


def read(text, name="p.csv"):
    return read_program([name], [text], "poses")


def test_csv_with_extra_columns_and_comments():
    text = "# part 7\nname,x,y,z,a,b,c,feed\nP1,1950.1,12.5,880,0,90,0,100\n\n# next\nP2,1960.0,-12.5,880.,1,89,2,120\n"
    p = read(text)
    assert p.targets.poses.tolist() == [[1950.1, 12.5, 880, 0, 90, 0], [1960.0, -12.5, 880.0, 1, 89, 2]]
    tokens = [[text[s:e] for s, e in row] for row in p.targets.spans]
    assert tokens == [["1950.1", "12.5", "880"], ["1960.0", "-12.5", "880."]]
    assert p.targets.line.tolist() == [3, 6]


def test_columns_in_any_order_and_case_and_separator():
    text = "C;B;A;Z;Y;X\n1;2;3;4;5;6\n"
    p = read(text)
    assert p.targets.poses.tolist() == [[6, 5, 4, 3, 2, 1]]
    assert text[slice(*p.targets.spans[0, 0])] == "6"


def test_whitespace_list_without_header_and_without_orientation():
    p = read("1 2 3\n\t4   5 6\n", "p.txt")
    assert p.targets.poses[:, :3].tolist() == [[1, 2, 3], [4, 5, 6]]
    assert np.isnan(p.targets.poses[:, 3:]).all()  # filled from the model's nominal attitude later


def test_name_column_with_digits_does_not_shift_numbers():
    p = read("name,x,y,z\nP1,10,20,30\nP22,11,21,31\n")
    assert p.targets.poses[:, :3].tolist() == [[10, 20, 30], [11, 21, 31]]


def test_quoted_field_with_separator_and_numbers():
    p = read('x,y,z,note\n1,2,3,"5, 6 and 7"\n')
    assert p.targets.poses[0, :3].tolist() == [1, 2, 3]


@pytest.mark.parametrize(
    "text, line, col, code",
    [
        ("x,y\n1,2\n", 1, 1, "P104"),  # no z column
        ("x,y,z\n1,2\n", 2, 1, "P104"),  # too few fields
        ("x,y,z\n1,2,3\n1,abc,3\n", 3, 3, "P103"),  # not a number
        ("x,y,z\n1,(2,3\n", 2, 3, "P101"),  # syntax
        ("# only a comment\n", 1, 1, "P105"),
        ("x,y,z\n1,,3\n", 2, 1, "P103"),  # empty
    ],
)
def test_bad_input_points_at_the_place(text, line, col, code):
    with pytest.raises(PostprocError) as info:
        read(text)
    err = info.value
    assert (err.line, err.col, err.code) == (line, col, code)
    assert str(err).startswith(f"p.csv:{line}:{col}: {code} ")


def test_shipped_samples_parse():
    csv = (REPO / "samples/poses/drill_plate.csv").read_bytes().decode("latin-1")
    assert len(read(csv, "drill_plate.csv").targets) == 48
    txt = (REPO / "samples/poses/sweep.txt").read_bytes().decode("latin-1")
    assert len(read(txt, "sweep.txt").targets) == 20


def _read_both(text):
    """The vectorised reader and the line-by-line one on ``text``: the same targets or the same error."""
    from postproc.programs import poses

    out = []
    for fast in (True, False):
        try:
            p = poses.read(["big.csv"], [text], fast=fast)
        except PostprocError as exc:
            out.append(str(exc))
            continue
        t = p.targets
        out.append([t.poses.tobytes(), t.spans.tolist(), t.abc_spans.tolist(), t.line.tolist(), t.col.tolist(),
                    t.config.tolist(), None if t.joints is None else t.joints.tobytes(), p.stamps])
    return out


@pytest.mark.parametrize("header,odd", [
    ("x,y,z,a,b,c,s,t", None),  # config columns, rows of one shape, interleaved other shapes
    ("x,y,z,a,b,c", "1,2-3,3,4,5,6"),  # a run of number characters that is not one number: P103 where line by line
    ("x,y,z,a,b,c", "1,2,3,4,5,1e999"),  # not finite
    ("x,y,z,a,b,c,s,t", "1,2,3,4,5,6,1.5,2"),  # S not an integer
])
def test_vectorised_reader_equals_line_by_line(header, odd):
    rng = np.random.default_rng(3)
    rows = rng.uniform(-999, 999, (6000, 6))
    lines = [header] + [",".join(f"{v:.{k % 4}f}" for k, v in enumerate(r)) + (",1,63" if ",s" in header else "")
                        for r in rows]
    lines[4000:4000] = ["# a comment", "  1,2,3,4,5,6" + (",0,0" if ",s" in header else ""), "",
                        "1;2;3;4;5;6" + (";1;2" if ",s" in header else ""), "1.e5,+.5,-3.,4e-2,5,6" + (",0,0" if ",s" in header else "")]
    if odd:
        lines[5000] = odd
    text = "\r\n".join(lines) + "\r\n"
    fast, exact = _read_both(text)
    assert fast == exact
    assert isinstance(exact, str) == (odd is not None)
    if odd is None:
        assert len(np.frombuffer(fast[0]).reshape(-1, 6)) == 6003  # the 6000 rows and 3 of the 5 lines inserted
