"""The output-directory rule every command shares: a new or empty directory, or an earlier
output of the same command (replaced whole), and nothing else; and every file and directory
written through a temporary name gets the mode the user's umask gives a plain one."""

from __future__ import annotations

import json
import os
import stat

import numpy as np
import pytest

from ftrac_design.cli.main import main
from ftrac_design.errors import InputError
from ftrac_design.fileio import (
    atomic_directory,
    atomic_file,
    check_output_dir,
    current_umask,
    json_format_is,
    write_json_atomic,
    write_text_atomic,
)
from ftrac_design.workflows.track_run import TrackOutputs


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


# --------------------------------------------------------------------------- modes under the umask
@pytest.fixture(params=[0o022, 0o077], ids=["umask022", "umask077"])
def umask(request):
    """The process's umask set for the test (each xdist worker is its own process)."""
    old = os.umask(request.param)
    yield request.param
    os.umask(old)


def _mode(p) -> int:
    return stat.S_IMODE(os.stat(p).st_mode)


def test_the_umask_is_read_as_it_is(umask):
    assert current_umask() == umask


def test_files_written_through_a_temporary_name_get_a_plain_files_mode(tmp_path, umask):
    expect = 0o666 & ~umask
    assert _mode(write_text_atomic(tmp_path / "a.txt", "x")) == expect
    assert _mode(write_json_atomic(tmp_path / "b.json", {"a": 1})) == expect
    with atomic_file(tmp_path / "c.png") as tmp:
        tmp.write_bytes(b"x")
    assert _mode(tmp_path / "c.png") == expect
    outputs = TrackOutputs(tmp_path / "poses.jsonl", tmp_path / "obs.jsonl")
    with outputs:
        fh = open(outputs.temporary(outputs.poses), "w")  # noqa: SIM115
        fh.close()
        outputs.commit()
    assert _mode(tmp_path / "poses.jsonl") == expect


def test_directories_written_through_a_temporary_name_get_a_plain_directorys_mode(tmp_path, umask):
    with atomic_directory(tmp_path / "out") as tmp:
        (tmp / "f.txt").write_text("x")
        write_text_atomic(tmp / "g.txt", "y")
    assert _mode(tmp_path / "out") == 0o777 & ~umask
    assert _mode(tmp_path / "out" / "f.txt") == _mode(tmp_path / "out" / "g.txt") == 0o666 & ~umask


def test_a_commands_outputs_honour_the_umask(tmp_path, umask):
    # export writes through the temporary-then-rename path, as track's JSON Lines and analyze's directory do
    pose = {
        "format": "ftrac-pose",
        "version": 1,
        "rotation": np.eye(3).tolist(),
        "translation_mm": [0.0, 0.0, 600.0],
        "converged": True,
    }
    src = tmp_path / "pose.json"
    src.write_text(json.dumps(pose))
    for out in ("p.tfm", "run.seq.mha"):
        assert main(["export", str(src), "-o", str(tmp_path / "exports" / out)]) == 0
        assert _mode(tmp_path / "exports" / out) == 0o666 & ~umask
    assert not [p for p in (tmp_path / "exports").iterdir() if p.name.startswith(".")]
