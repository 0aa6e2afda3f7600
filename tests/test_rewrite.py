import os

import numpy as np
import pytest

from postproc.core.atomic import write_atomic
from postproc.programs.rewrite import apply_edits, format_like, format_many, insert_stamp


@pytest.mark.parametrize(
    "token, value, expected",
    [
        ("1950.1", 1950.3456, "1950.346"),  # at least 3 decimals
        ("12.34567", 12.3, "12.30000"),  # more decimals kept
        ("1900.", 1900.3456, "1900.346"),
        ("880", 880.25, "880.250"),
        (".5", 0.5123, ".512"),
        ("-.5", -0.5123, "-.512"),
        ("+5.0", 5.25, "+5.250"),
        ("-0.000", -0.0002, "0.000"),  # never '-0.000'
        ("1.5E+03", 1500.3456, "1.500346E+03"),  # exponent kept, µm resolution
        ("2e3", 2000.1234, "2.000123e3"),
    ],
)
def test_number_keeps_token_style(token, value, expected):
    assert format_like(token, value) == expected
    assert abs(float(expected) - value) <= 0.0005 + 1e-12


def test_format_many_matches_format_like():
    tokens = ["1.0", "-2.50", "3", ".5", "1E2", "-0.000"]
    values = np.array([1.23456, -2.5, 3.0001, 0.25, 100.5, 0.0])
    assert format_many(tokens, values) == [format_like(t, v) for t, v in zip(tokens, values)]


def test_apply_edits_touches_only_spans():
    text = "LIN {X 1.0,Y 2.0} ; X 9.0"
    out = apply_edits(text, np.array([13, 7]), np.array([16, 10]), ["2.500", "1.500"])
    assert out == "LIN {X 1.500,Y 2.500} ; X 9.0"


def test_stamp_after_krl_headers_with_file_line_ending():
    text = "&ACCESS RVP\r\n&REL 3\r\nDEF a()\r\nEND"
    out = insert_stamp(text, "; stamp", "\r\n", after_headers="&")
    assert out == "&ACCESS RVP\r\n&REL 3\r\n; stamp\r\nDEF a()\r\nEND"


def test_write_atomic_all_or_nothing(tmp_path, monkeypatch):
    a, b = tmp_path / "p.src", tmp_path / "p.dat"
    a.write_text("old src")
    b.write_text("old dat")
    real_replace = os.replace
    calls = []

    def failing_replace(src, dst):
        calls.append(dst)
        if len(calls) == 2:  # the .dat rename fails after the .src went through
            raise OSError("disk full")
        return real_replace(src, dst)

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(OSError):
        write_atomic([(a, "new src"), (b, "new dat")])
    monkeypatch.setattr(os, "replace", real_replace)
    assert a.read_text() == "old src" and b.read_text() == "old dat"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.dat", "p.src"]  # no temp files left
    write_atomic([(a, "new src"), (b, "new dat")])
    assert a.read_text() == "new src" and b.read_text() == "new dat"


def test_bulk_plain_path_keeps_each_tokens_decimals_and_no_negative_zero():
    tokens = ["1.0", "-2.50", "12.34567", "0.000", "-7.1234"]
    values = np.array([1.23456, -2.5, 12.3, -0.0004, -7.12341])
    assert format_many(tokens, values) == ["1.235", "-2.500", "12.30000", "0.000", "-7.1234"]
