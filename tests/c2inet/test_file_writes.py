"""Atomic writes: a failed write leaves nothing behind, and a full or read-only device is one
named error, not the writer's own (torch reports a full disk as an iostream RuntimeError)."""

import errno

import pytest

from c2inet import files
from c2inet.errors import CannotWrite
from c2inet.files import write_atomic, write_text_atomic


def failing(error):
    def write(tmp):
        tmp.write_text("half")
        raise error

    return write


@pytest.mark.parametrize(
    "code,words", [(errno.ENOSPC, "no space left"), (errno.EROFS, "read-only")]
)
def test_a_device_that_refuses_a_write_is_one_named_error(tmp_path, code, words):
    target = tmp_path / "result.json"
    with pytest.raises(CannotWrite, match=f"cannot write {target}: .*{words}"):
        write_atomic(target, failing(OSError(code, "refused")))
    assert list(tmp_path.iterdir()) == []  # no temporary file left


def test_a_write_error_on_a_full_disk_is_put_down_to_the_disk(tmp_path, monkeypatch):
    error = RuntimeError("basic_ios::clear: iostream error")
    with pytest.raises(RuntimeError, match="iostream"):  # plenty of space: the error as it was
        write_atomic(tmp_path / "a.pt", failing(error))
    monkeypatch.setattr(files, "FULL", float("inf"))  # as if the disk were full
    with pytest.raises(CannotWrite, match="no space left on its device"):
        write_atomic(tmp_path / "a.pt", failing(error))
    assert list(tmp_path.iterdir()) == []


def test_an_atomic_write_replaces_the_file_whole(tmp_path):
    target = tmp_path / "notes.txt"
    write_text_atomic(target, "one")
    write_text_atomic(target, "two")
    assert target.read_text() == "two" and list(tmp_path.iterdir()) == [target]


@pytest.mark.parametrize("step", ["mkdir", "mkstemp"])
def test_a_file_system_out_of_inodes_fails_the_folder_or_the_temporary_in_one_error(
    tmp_path, monkeypatch, step
):
    """With bytes free but no inode left, making the folder or the temporary file fails with
    ENOSPC before anything is written: one named error, no traceback."""

    def no_inode(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    if step == "mkdir":
        monkeypatch.setattr(files.Path, "mkdir", no_inode)
    else:
        monkeypatch.setattr(files.tempfile, "mkstemp", no_inode)
    with pytest.raises(CannotWrite, match="no space left on its device"):
        write_text_atomic(tmp_path / "sub" / "result.json", "{}")
