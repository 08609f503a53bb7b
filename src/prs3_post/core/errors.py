"""The one error hierarchy of prs3-post.

Everything raised on purpose across module boundaries is a :class:`Prs3Error`; the CLI prints it
as ``where: message`` and exits non-zero, never with a traceback.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable

ECHO_LIMIT = 40
"""Characters of a user's value that a message shows (a longer one is cut, with ``…``)."""

STDIN_PATH = "-"
"""The file name that means standard input (and, for an output, standard output)."""
STDIN_NAME = "<stdin>"
"""How messages name standard input read as a file (``<stdin>:12: ...``)."""


def shown_path(path: str) -> str:
    """A file name as messages show it: ``-`` (standard input) is ``<stdin>``.

    >>> shown_path("-"), shown_path("part.cls")
    ('<stdin>', 'part.cls')
    """
    return STDIN_NAME if path == STDIN_PATH else path


def quoted(value: object, limit: int = ECHO_LIMIT) -> str:
    """A value from the user's input for a message: ``repr``, cut to ``limit`` characters plus ``…``, so that a
    10,000-character TOML string or header line is not printed back in full.

    A bool is spelled as the TOML and JSON files it comes from spell it (``true``, not ``True``).

    >>> quoted("G0 X1"), quoted("x" * 50), quoted([1.5, "a" * 60], limit=12), quoted(True)
    ("'G0 X1'", "'xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx…'", "[1.5, 'aaaa…", 'true')
    """
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(shortened(value, limit)) if isinstance(value, str) else shortened(repr(value), limit)


def shortened(text: str, limit: int = ECHO_LIMIT) -> str:
    """``text`` cut to ``limit`` characters, the last one ``…`` (a key or name shown without quotes).

    >>> shortened("step_down"), shortened("x" * 50, limit=8)
    ('step_down', 'xxxxxxx…')
    """
    return text if len(text) <= limit else text[:limit - 1] + "…"


class KeyedMessage(Exception):
    """A message (of an error or a warning) that may name the request keys it concerns as ``{key}``
    (``{depth} must be > 0 mm``, ``check {setup.part_origin}``): such a message says which (``names_keys``,
    per class or per instance: True for any, or the keys) and each front end words them (:meth:`worded`: the
    command line's ``--depth``, a job file's ``depth``); ``str()`` names them bare. Nothing else in a
    message, which may echo a user's text braces and all, is rewritten."""

    names_keys: bool | tuple[str, ...] = False

    def __init__(self, *args: object, names_keys: bool | tuple[str, ...] = False):
        super().__init__(*args)
        if names_keys:
            self.names_keys = names_keys

    def worded(self, spell: Callable[[str], str] = str) -> str:
        """The message, each key it names as ``{key}`` spelled ``spell(key)`` (default: the key itself)."""
        message = super().__str__()
        names = self.names_keys
        if names:
            message = spelled(message, spell, None if isinstance(names, bool) else names)
        return self._framed(message)

    def carried(self) -> str:
        """The message with its keys still as ``{key}``: for an error that wraps this one (and passes
        ``names_keys=error.names_keys`` on), so that its front end still words them."""
        return self.worded(lambda key: "{" + key + "}")

    def _framed(self, message: str) -> str:
        """The message as :meth:`worded` gives it (an :class:`InputError` puts its file and line first)."""
        return message

    def __str__(self) -> str:
        return self.worded()


class Prs3Error(KeyedMessage):
    """Reported by the CLI as `where: message`; never a traceback (its keys worded: :class:`KeyedMessage`)."""

    exit_code = 1

    def __reduce__(self) -> tuple[object, ...]:
        """Pickled with its attributes (``path``, ``line``, ``key``...), whatever its constructor takes:
        an error that crosses a process boundary (a ``convert --jobs`` worker's) arrives whole."""
        return _restored, (type(self), self.args, self.__dict__)


def _restored(kind: type[Prs3Error], args: tuple[object, ...], attributes: dict[str, object]) -> Prs3Error:
    error = kind.__new__(kind)
    error.args = args
    error.__dict__.update(attributes)
    return error


class InputError(Prs3Error):
    """A file or option the user gave is wrong; names the file (and line) and what would be valid."""

    exit_code = 2

    def __init__(self, message: str, *, path: str, line: int | None = None,
                 names_keys: bool | tuple[str, ...] = False):
        super().__init__(message, names_keys=names_keys)
        self.path, self.line = path, line

    def _framed(self, message: str) -> str:
        path = shown_path(self.path)
        where = path if self.line is None else f"{path}:{self.line}"
        return f"{where}: {message}"


class ConfigError(InputError):
    """A machine or dialect TOML file is wrong; the message starts with the dotted key."""


class OutputClosed(InputError):
    """Standard output's reader went away before everything was written (``prs3-post machines | head -1``):
    not the command's error. The command line ends quietly with exit status 141 (128 + SIGPIPE: what a
    shell reports for a process the signal ended, as it would have without Python's handling)."""

    exit_code = 141


class MissingDependency(Prs3Error):
    """An optional dependency the command needs is not installed (matplotlib for a picture): the message
    gives the command that installs it. Exit status 2, as for bad input."""

    exit_code = 2


class LimitError(Prs3Error):
    """A point would drive the machine past a limit: names the source line/step, limit, value, margin."""


class ReachError(Prs3Error):
    """A pose is outside the workspace (cannot assemble, or needs a stage the machine lacks)."""


class PoseError(Prs3Error):
    """Tool poses that are not numbers, or whose axis is zero or points away from the spindle."""

    exit_code = 2


def spelled(message: str, spell: Callable[[str], str] = str, keys: Iterable[str] | None = None) -> str:
    """A message that names keys as ``{key}`` (``{depth} must be > 0 mm``), each as ``spell(key)``: the
    command line spells them as its flags (``--depth``), a job file as its keys. With ``keys``, only those
    (the rest of the message, a user's text among it, stays as it is)."""
    only = None if keys is None else frozenset(keys)
    return re.sub(r"\{([a-z_.]+)\}", lambda match: spell(match[1]) if only is None or match[1] in only
                  else match[0], message)


class FieldError(Prs3Error):
    """A value of a request (the main job's, from the command line or a job file) is wrong.

    The message does not say where the value came from: each front end words that, the command
    line as its flag (``--depth``), a job file as its key (``operation[1].depth``). Other fields a
    message names are written ``{key}`` (``{line_step}``) and spelled by :meth:`worded`.

    Attributes
    ----------
    field : str — the key at fault, as a job file spells it (``depth``, ``tool``, ``line_start``,
        ``setup.part_origin``)
    operation : int | None — which operation (1-based) the key belongs to; None for a job's setting
    also : tuple of str — other keys at fault with it (two values that do not go together)
    """

    exit_code = 2
    names_keys: bool | tuple[str, ...] = True

    def __init__(self, message: str, *, field: str, operation: int | None = None, also: tuple[str, ...] = ()):
        super().__init__(message)
        self.field, self.operation, self.also = field, operation, also


class UnusedFields(FieldError):
    """An operation's keys that its profile does not use (``diameter`` on a square): given, they would be ignored.

    Attributes
    ----------
    profile : str — the operation's profile
    keys : tuple of (str, tuple of str) — each unused key and the profiles that use it
    """

    def __init__(self, profile: str, keys: tuple[tuple[str, tuple[str, ...]], ...], *, operation: int | None = None):
        shown = ", ".join(f"{key} ({' and '.join(profiles)} only)" for key, profiles in keys)
        super().__init__(f"profile {profile} does not use {shown}", field=keys[0][0], operation=operation)
        self.profile, self.keys = profile, keys


class FeatureError(Prs3Error):
    """An operation cannot be placed as asked (does not fit the face, tool too big, bad size).

    The message names the keys it is about as ``{key}`` (``{depth} must be > 0 mm``); ``str()`` gives
    them bare, and each front end words them (:meth:`worded`: ``--depth``, or a job file's ``depth``).

    Attributes
    ----------
    key : str | None — the operation's parameter at fault, as a job file's key (``at``, ``side``), if one is
    operation : int | None — which operation of a job (1-based), once the job knows it
    """

    exit_code = 2
    names_keys = True

    def __init__(self, message: str, *, key: str | None = None, operation: int | None = None):
        super().__init__(message)
        self.key, self.operation = key, operation


class Prs3Warning(KeyedMessage, UserWarning):
    """Something looks wrong but may be meant (a part of an unusual size): the CLI prints it as
    ``prs3-post: warning: message`` on standard error (its keys worded: :class:`KeyedMessage`) and goes on."""


class LexError(Prs3Error):
    """Text that is not G-code words (:mod:`prs3_post.core.lexer`). It knows neither the file nor the
    line: a reader wraps it in an :class:`InputError` with both (``raise InputError(...) from exc``).

    Attributes
    ----------
    column : int | None — 1-based column in the line (None: not about one line, e.g. undecodable bytes)
    found : str — the text that could not be read, from where reading stopped (``''`` if none)
    """

    exit_code = 2

    def __init__(self, message: str, *, column: int | None = None, found: str = ""):
        super().__init__(message)
        self.column, self.found = column, found
