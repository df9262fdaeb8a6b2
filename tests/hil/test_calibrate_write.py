"""`hil calibrate --write` replaces the file in one rename and keeps the old one as FILE.bak;
when it cannot write (a full disk, a read-only mount: here the failure is injected where it
would come), it leaves nothing behind - no FILE.tmp, no new FILE.bak - and the file as it was.
And --write onto a file it cannot write is refused before anything is read (exit 2)."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest

from hil.cli import main
from hil.cli.calibrate import write_keeping_backup

OLD, NEW = "old = 1\n", "new = 2\n"


def _full_disk(*_args: object, **_kwargs: object) -> None:
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


@pytest.mark.parametrize("failing", ["fsync", "replace"])
def test_a_write_that_fails_leaves_nothing_behind(
    failing: str, tmp_path: Path, monkeypatch
) -> None:
    path = tmp_path / "testbed.toml"
    path.write_text(OLD)
    monkeypatch.setattr(os, failing, _full_disk)
    with pytest.raises(OSError, match="No space left"):
        write_keeping_backup(path, NEW)
    assert [p.name for p in tmp_path.iterdir()] == ["testbed.toml"]
    assert path.read_text() == OLD


def test_a_write_keeps_the_old_file_as_a_backup_and_no_temporary(tmp_path: Path) -> None:
    path = tmp_path / "testbed.toml"
    path.write_text(OLD)
    (tmp_path / "testbed.toml.bak").write_text("an older backup\n")
    backup = write_keeping_backup(path, NEW)
    assert path.read_text() == NEW and backup.read_text() == OLD
    assert backup.name == "testbed.toml.bak-2"  # the older backup is kept too
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "testbed.toml", "testbed.toml.bak", "testbed.toml.bak-2",
    ]  # fmt: skip


def test_write_to_a_file_that_is_not_there_is_refused_before_reading(
    tmp_path: Path, capsys
) -> None:
    missing = tmp_path / "nothing.toml"
    assert main(["calibrate", "--config", str(missing), "--write"]) == 2
    assert "nothing.toml" in capsys.readouterr().err
