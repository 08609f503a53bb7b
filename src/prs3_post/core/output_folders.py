"""Writing a folder of files (a LinuxCNC configuration) whole or not at all.

The files are written into a hidden temp folder ``.NAME.*.tmp`` beside the target and renamed into
place once all are written: a reader sees no folder, or the old one, or the whole new one, and a
failed or interrupted write removes the temp folder and leaves the old one as it was.

- A new folder, or an existing empty one, is replaced by one rename (Linux renames a folder over an
  empty one).
- An existing folder with files in it is refused unless ``replace`` is asked for; then it is renamed
  aside (``.NAME.*.old``), the new one renamed into place, and the old one removed.
- A folder that holds one of the inputs is never replaced (its removal would destroy the input).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import stat
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from prs3_post.core.errors import InputError

__all__ = ["FolderFile", "write_folder"]

_TEMP_NAME_MAX = 60  # characters of the target's name kept in its temp folder's name


@dataclass(frozen=True, slots=True)
class FolderFile:
    """One file of a folder: its text (written as UTF-8) and whether it is a program to run."""

    text: str
    executable: bool = False


def write_folder(path: str, files: Mapping[str, FolderFile], *, replace: bool = False,
                 inputs: Sequence[str] = ()) -> Path:
    """Write ``files`` ({name in the folder: file}) as the folder ``path``, whole or not at all.

    Parameters
    ----------
    path : str — the folder, as given (messages name it so)
    files : {str: FolderFile} — plain file names (no folders)
    replace : bool — an existing folder with files in it is replaced (else refused)
    inputs : paths of the inputs, which must not lie inside a folder that is replaced

    Returns
    -------
    Path — the folder (symbolic links resolved)

    Raises
    ------
    InputError
        ``the output folder's name is empty``, ``standard output cannot take a folder``, ``is not a folder``,
        ``exists and is not empty``,
        ``holds the input ...``, ``cannot write the folder here: <reason>``.
    """
    if not path:
        raise InputError("the output folder's name is empty: give the folder to write (e.g. -o config)", path="''")
    if path == "-":                                     # the command line's standard output: not a folder
        raise InputError("standard output cannot take a folder of files: give the folder to write (e.g. -o config)",
                         path="'-'")
    target = Path(os.path.realpath(path))
    try:
        mode: int | None = os.stat(target).st_mode
    except FileNotFoundError:
        mode = None
    except OSError as exc:                              # name too long, loop of links, no permission
        raise InputError(f"cannot write the folder here: {exc.strerror}", path=path) from exc
    full = False
    if mode is not None:
        if not stat.S_ISDIR(mode):
            raise InputError("is not a folder: give a new or empty folder for the files", path=path)
        try:
            full = any(target.iterdir())
        except OSError as exc:
            raise InputError(f"cannot read the folder: {exc.strerror}", path=path) from exc
        if full and not replace:
            raise InputError("exists and is not empty: give a new or empty folder, or --force to replace it",
                             path=path)
        for given in inputs:
            inside = Path(os.path.realpath(given))
            if target == inside or target in inside.parents:
                raise InputError(f"holds the input {given}: replacing the folder would destroy it (give another "
                                 "folder)", path=path)
    for name in files:
        if not name or os.sep in name or name in (".", ".."):
            raise ValueError(f"not a plain file name: {name!r}")
    try:
        staging = Path(tempfile.mkdtemp(prefix=_prefix(target), suffix=".tmp", dir=target.parent))
    except OSError as exc:
        raise InputError(f"cannot write the folder here: {exc.strerror}", path=path) from exc
    try:
        _fill(staging, files)
        _swap(staging, target, full)
    except OSError as exc:
        raise InputError(f"cannot write the folder: {exc.strerror}", path=path) from exc
    finally:
        with contextlib.suppress(OSError):
            if staging.exists():
                shutil.rmtree(staging)
    return target


def _prefix(target: Path) -> str:
    return f".{target.name[:_TEMP_NAME_MAX]}."


def _fill(staging: Path, files: Mapping[str, FolderFile]) -> None:
    """Write each file into the temp folder, with the usual permissions (not mkdtemp's 0700)."""
    umask = os.umask(0)
    os.umask(umask)
    for name, file in files.items():
        where = staging / name
        where.write_text(file.text, encoding="utf-8")
        os.chmod(where, (0o777 if file.executable else 0o666) & ~umask)
    os.chmod(staging, 0o777 & ~umask)


def _swap(staging: Path, target: Path, full: bool) -> None:
    """Rename the temp folder to ``target``; a full ``target`` is moved aside first and removed after."""
    if not full:
        os.rename(staging, target)                      # a new name, or over an empty folder
        return
    aside = Path(tempfile.mkdtemp(prefix=_prefix(target), suffix=".old", dir=target.parent))
    os.rename(target, aside / "old")
    try:
        os.rename(staging, target)
    except OSError:
        os.rename(aside / "old", target)                # put the old folder back
        raise
    finally:
        with contextlib.suppress(OSError):
            shutil.rmtree(aside)
