"""The output-directory rule every command shares: a new or empty directory, or an earlier
output of the same command (replaced whole), and nothing else."""

from __future__ import annotations

import json

import pytest

from ftrac_design.errors import InputError
from ftrac_design.fileio import check_output_dir, json_format_is


def _ours(d):
    return json_format_is(d / "summary.json", "ftrac-test")


def test_new_empty_and_earlier_directories_are_accepted(tmp_path):
    check_output_dir(tmp_path / "new", "an earlier output", _ours)
    (tmp_path / "empty").mkdir()
    check_output_dir(tmp_path / "empty", "an earlier output", _ours)
    earlier = tmp_path / "earlier"
    earlier.mkdir()
    (earlier / "summary.json").write_text(json.dumps({"format": "ftrac-test"}))
    (earlier / "plot.png").write_bytes(b"x")
    check_output_dir(earlier, "an earlier output", _ours)


@pytest.mark.parametrize("content", ['{"format": "other"}', "not json", "[1, 2]"])
def test_a_directory_holding_something_else_is_refused_naming_the_key(tmp_path, content):
    (tmp_path / "summary.json").write_text(content)
    with pytest.raises(InputError) as exc:
        check_output_dir(tmp_path, "an earlier output", _ours)
    assert exc.value.key == "output" and "an earlier output" in str(exc.value)
    assert ": --output: a new or empty directory" in exc.value.for_command_line()


def test_a_file_is_refused_and_the_argument_may_be_unnamed(tmp_path):
    f = tmp_path / "out"
    f.write_text("")
    with pytest.raises(InputError) as exc:
        check_output_dir(f, "an earlier output", _ours, parameter=None)
    assert exc.value.key is None and "a file of that name exists" in str(exc.value)
    assert exc.value.for_command_line() == str(exc.value)


def test_json_format_is(tmp_path):
    p = tmp_path / "a.json"
    assert not json_format_is(p, "x")  # missing
    p.write_text('{"format": "x"}')
    assert json_format_is(p, "x") and not json_format_is(p, "y")
    p.write_text("[]")
    assert not json_format_is(p, "x")  # not an object
