"""One Settings object: file options → CLI / API overrides → frozen sections, each value checked
the same way wherever it comes from, and located where it was given."""
import dataclasses
import re

import pytest

from helpers import DOCS
from postproc.cli import build_parser
from postproc.cli.settings import ARGUMENTS, settings_of
from postproc.core.diagnostics import PostprocError
from postproc.programs import ActiveFrames
from postproc.robot.description import robot_description, robot_name
from postproc.settings import OPTIONS, Settings, load_settings
from postproc.settings.sections import FILE_KEYS, parse_flags


def write(path, text):
    path.write_text(text)
    return path


def test_the_file_then_the_flags_then_nothing_else(tmp_path):
    write(tmp_path / "postproc.toml", 'strict = true\nmax_correction = 3\niterations = 2\nbase = 0\ntool = "1"\n'
          'ignore = ["P301"]\nmax_mean = 0.2\n')
    args = build_parser("check").parse_args(["check", "p.src", "--settings", str(tmp_path / "postproc.toml"),
                                             "--iterations", "4", "--tool", "model", "--ignore", "p213"])
    s = settings_of(args)
    assert s.path == tmp_path / "postproc.toml"
    assert (s.rules.strict, s.rules.max_correction_mm, s.rules.iterations) == (True, 3.0, 4)
    assert s.reading.active == ActiveFrames(base=0, tool="model")  # each frame on its own: the flag's tool, the file's base
    assert s.check.ignore == {"P301", "P213"}  # codes add up
    assert s.acceptance.stated == {"max_mean": 0.2}
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.rules.strict = False


def test_a_flag_not_given_leaves_the_file_value(tmp_path):
    write(tmp_path / "postproc.toml", "strict = true\n")
    args = build_parser("compensate").parse_args(["compensate", "p.src", "-o", "o.src", "--settings",
                                                  str(tmp_path / "postproc.toml")])
    assert args.strict is None and settings_of(args).rules.strict is True
    args = build_parser("compensate").parse_args(["compensate", "p.src", "-o", "o.src", "--no-fill-partial"])
    assert settings_of(args).rules.fill_partial is False


@pytest.mark.parametrize("text, line, message", [
    ("model = 'm.onnx'\n\nmax_correction = nan\n", 3, "max_correction must be a positive number of mm, not nan"),
    ("iterations = 1000\n", 1, "iterations must be between 1 and 100"),
    ("model = 'm.onnx'\nbase = '1,2'\n", 2, "base: expected six numbers"),
    ("max_std = -1\n", 1, "max_std must be a positive number of mm"),
    ("ignore = ['301']\n", 1, "expected a list of codes"),
    ("max_p95 = 0\n", 1, "max_p95 must be a positive number"),
])
def test_a_bad_value_in_a_file_is_refused_at_its_line(tmp_path, text, line, message):
    write(tmp_path / "postproc.toml", text)
    with pytest.raises(PostprocError) as info:
        load_settings(tmp_path / "postproc.toml")
    assert (info.value.code, info.value.line) == ("P610", line) and message in info.value.message


def test_pyproject_keys_are_located_in_their_table(tmp_path):
    write(tmp_path / "pyproject.toml", '[project]\nname = "x"\nstrict = 1\n[tool.postproc]\nmodel = "m.onnx"\nstrict = 1\n')
    with pytest.raises(PostprocError) as info:
        load_settings(tmp_path / "pyproject.toml")
    assert info.value.line == 6


@pytest.mark.parametrize("flags, code, message", [
    (["--max-correction", "nan"], "P308", "--max-correction must be a positive number of mm, not nan"),
    (["--iterations", "0"], "P308", "--iterations must be between 1 and 100"),
    (["--base", "1,2"], "P222", "base: expected six numbers"),
    (["--max-std", "0"], "P308", "--max-std must be a positive number of mm"),
])
def test_a_bad_flag_is_refused_by_the_same_check(flags, code, message):
    args = build_parser("compensate").parse_args(["compensate", "p.src", "-o", "o.src", *flags])
    with pytest.raises(PostprocError) as info:
        settings_of(args)
    assert info.value.code == code and message in info.value.message


def test_the_api_takes_options_by_name_and_names_an_unknown_one():
    s = Settings().override(max_correction_mm=2, strict=True, active=ActiveFrames(base=0))
    assert (s.rules.max_correction_mm, s.rules.strict, s.reading.active.base) == (2.0, True, 0)
    assert Settings().override(strict=None).rules.strict is False  # None: not given
    with pytest.raises(TypeError, match="did you mean 'max_correction_mm'"):
        Settings().override(max_correction=2)
    with pytest.raises(PostprocError, match="--max-correction"):
        Settings().override(max_correction_mm=float("inf"))


def test_train_flags_parse_as_the_cli_does():
    names = [n for n, o in OPTIONS.items() if o.section == "training"]
    assert parse_flags(["--val-fraction", "0.2", "--search", "--hidden=8,4", "--epochs", "5"], names) == {
        "val_fraction": 0.2, "search": True, "hidden": (8, 4), "epochs": 5}
    for bad, why in ((["--val-fraction"], "needs a value"), (["--search=1"], "takes no value"),
                     (["--strict"], "unknown option"), (["--epochs", "x"], "expects int")):
        with pytest.raises(ValueError, match=why):
            parse_flags(bad, names)
    args = build_parser("train").parse_args(["train", "d.csv", "-o", "m.onnx", "--val-fraction", "0.2", "--search",
                                             "--hidden", "8,4", "--epochs", "5"])
    assert {k: getattr(settings_of(args).training, k) for k in ("val_fraction", "search", "hidden", "epochs")} == \
        parse_flags(["--val-fraction", "0.2", "--search", "--hidden=8,4", "--epochs", "5"], names)


def test_robot_means_one_thing_everywhere(tmp_path):
    assert robot_name("KR500-sim") == robot_name("kr500") == "KR500-sim"  # a shipped robot by its name or stem
    assert robot_name("models/ur10.toml") == "UR10"  # a description file: its [robot] name
    assert robot_name("My-Robot") == "My-Robot"  # any other name: itself
    assert robot_description("irb6700").name == robot_description("IRB6700-sim").name == "IRB6700-sim"
    with pytest.raises(PostprocError, match="no robot description named 'My-Robot'"):
        robot_description("My-Robot")
    flags = {p: build_parser(p)._subparsers._group_actions[0].choices[p] for p in
             ("compensate", "check", "train", "plan", "measure", "verify", "export")}
    for command, parser in flags.items():
        robot = [a for a in parser._actions if "--robot" in a.option_strings]
        assert robot and robot[0].metavar == "NAME|FILE.toml", command


def test_every_setting_is_declared_once_and_documented():
    page = (DOCS / "settings.md").read_text()
    for key, name in FILE_KEYS.items():
        option = OPTIONS[name]
        assert re.search(rf"^\| `{key}` \| `{re.escape(option.flag)}`", page, re.M) or option.flag in ("fresh",), key
    for name, option in OPTIONS.items():
        assert name in ARGUMENTS or option.flag in ("active", "fresh"), name  # a flag's help once (cli/settings.py)
        assert option.flag in page or option.flag in ("active", "fresh") or name == "active", name
