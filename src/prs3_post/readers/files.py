"""Reading an input file's bytes, with the same clear errors for every reader."""

from __future__ import annotations

from prs3_post.errors import InputError


def read_input(path: str, what: str) -> bytes:
    """The whole file at ``path``.

    Parameters
    ----------
    path : str — as the user gave it (messages show it unchanged)
    what : str — what the file should be, for the directory message (``an STL file``)

    Raises
    ------
    InputError
        ``file not found``, ``is a directory, not <what>``, ``permission denied`` or
        ``cannot read the file: <reason>``.
    """
    try:
        with open(path, "rb") as stream:
            return stream.read()
    except FileNotFoundError as exc:
        raise InputError("file not found", path=path) from exc
    except IsADirectoryError as exc:
        raise InputError(f"is a directory, not {what}", path=path) from exc
    except PermissionError as exc:
        raise InputError("permission denied", path=path) from exc
    except OSError as exc:
        raise InputError(f"cannot read the file: {exc.strerror or exc}", path=path) from exc
