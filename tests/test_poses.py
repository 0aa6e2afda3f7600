"""Generic pose programs: CSV with a header, whitespace lists, comments, bad input."""
import numpy as np
import pytest

from postproc.diagnostics import PostprocError
from postproc.programs import read_program

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
