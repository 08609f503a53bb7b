"""A folder of files is written whole or not at all (core/output_folders.py)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from prs3_post.core import output_folders
from prs3_post.core.errors import InputError
from prs3_post.core.output_folders import FolderFile, write_folder

FILES = {"a.ini": FolderFile("[A]\n"), "run.py": FolderFile("#!/bin/sh\n", executable=True)}


def test_the_files_and_their_modes(tmp_path: Path) -> None:
    umask = os.umask(0o022)
    try:
        folder = write_folder(str(tmp_path / "out"), FILES)
    finally:
        os.umask(umask)
    assert folder == tmp_path / "out"
    assert (folder / "a.ini").read_text() == "[A]\n"
    assert (os.stat(folder / "a.ini").st_mode & 0o777, os.stat(folder / "run.py").st_mode & 0o777,
            os.stat(folder).st_mode & 0o777) == (0o644, 0o755, 0o755)


def test_a_failed_write_leaves_no_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def fail(staging: Path, files: object) -> None:
        (staging / "half").write_text("x")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(output_folders, "_fill", fail)
    with pytest.raises(InputError) as caught:
        write_folder(str(tmp_path / "out"), FILES)
    assert str(caught.value) == f"{tmp_path / 'out'}: cannot write the folder: No space left on device"
    assert list(tmp_path.iterdir()) == []


def test_an_interrupted_write_leaves_the_old_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    old = tmp_path / "out"
    old.mkdir()
    (old / "mine").write_text("kept")

    def interrupted(staging: Path, files: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(output_folders, "_fill", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_folder(str(old), FILES, replace=True)
    assert [p.name for p in tmp_path.iterdir()] == ["out"]
    assert (old / "mine").read_text() == "kept"


def test_a_failed_swap_puts_the_old_folder_back(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    old = tmp_path / "out"
    old.mkdir()
    (old / "mine").write_text("kept")
    real_rename = os.rename

    def rename(src: object, dst: object) -> None:
        if Path(str(dst)) == old and str(src).endswith(".tmp"):
            raise OSError(5, "Input/output error")
        real_rename(src, dst)  # type: ignore[arg-type]

    monkeypatch.setattr(output_folders.os, "rename", rename)
    with pytest.raises(InputError):
        write_folder(str(old), FILES, replace=True)
    assert [p.name for p in tmp_path.iterdir()] == ["out"]
    assert (old / "mine").read_text() == "kept"
