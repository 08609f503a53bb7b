"""What a dialect's literal blocks (safe start, preamble, postamble) may say to the controller.

The emitter writes these blocks as they are, so the dialect loader checks each one here: a block
the controller rejects, or one that would change what the program's moves mean, must never reach a
program. The rules are LinuxCNC's (RS-274/NGC, 2.9), against which both shipped dialects are
checked (``/work/shared/tools/rs274-check``), narrowed to what a block around the moves may do:

* no motion: no motion code (G0 G1 G2 G3, G38.x probes, G73 G81-G89 cycles, G28/G30 homing, ...)
  and no axis word (the program's moves carry their own reach and limit checks);
* no program end (M2 M30) and no subprogram call or return (M98 M99): the emitter ends the
  program with ``program.end_code`` after the postamble;
* nothing that changes what the program's numbers mean: inches (G20), incremental distances
  (G91), a diameter X (G7), cutter compensation (G41 G42), offsets and stored positions (G10 G52
  G92 ...), and no path blending (G64: the control would round corners in joint space);
* only codes LinuxCNC knows, at most one per modal group and four M codes, each other word once,
  only with a code that uses it (``H`` with G43, ``P`` with G4, ...), with the values it accepts;
* comments closed and not nested; no ``;`` (LinuxCNC reads the rest of the line as a comment, ISO
  controls as the end of the block); no ``N`` (the emitter numbers blocks) and no ``O`` word.

Every rule that says LinuxCNC rejects something was confirmed with its interpreter.
"""

from __future__ import annotations

from prs3_post.core.errors import LexError
from prs3_post.core.lexer import Word, code_name, lex_words, split_comments

__all__ = ["block_problem"]

# ----------------------------------------------------------------------------- the codes

#: G codes a block may use: modal group (codes of one group exclude each other on a block) and the
#: words the code uses. LinuxCNC puts G4 in group 0 but accepts it next to G92.1: its own group here.
_G_ALLOWED: dict[str, tuple[str, str]] = {
    "G4": ("dwell", "P"),
    **{g: ("plane", "") for g in ("G17", "G18", "G19", "G17.1", "G18.1", "G19.1")},
    "G8": ("lathe diameter", ""), "G21": ("units", ""), "G40": ("cutter compensation", ""),
    "G43": ("tool length offset", "H"), "G43.2": ("tool length offset", "H"), "G49": ("tool length offset", ""),
    **{g: ("coordinate system", "") for g in ("G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3")},
    "G61": ("path control", ""), "G61.1": ("path control", ""), "G80": ("motion", ""),
    "G90": ("distance", ""), "G90.1": ("arc distance", ""), "G91.1": ("arc distance", ""),
    "G92.1": ("non-modal", ""), "G92.2": ("non-modal", ""),
    "G93": ("feed mode", ""), "G94": ("feed mode", ""), "G95": ("feed mode", ""),
    "G96": ("spindle speed mode", "SD"), "G97": ("spindle speed mode", ""),
    "G98": ("canned cycle return", ""), "G99": ("canned cycle return", ""),
}
_MOVES = "moves the machine (a dialect block must not: the program's moves carry their own checks)"
_OFFSETS = "sets offsets, tool data or stored positions (not for a dialect block)"
#: G codes LinuxCNC knows that a block must not use, and why.
_G_REFUSED: dict[str, str] = {
    **{g: _MOVES for g in ("G0", "G1", "G2", "G3", "G5", "G5.1", "G5.2", "G5.3", "G28", "G30", "G33", "G33.1",
                           "G38.2", "G38.3", "G38.4", "G38.5", "G53", "G70", "G71", "G71.1", "G71.2", "G72",
                           "G72.1", "G72.2", "G73", "G74", "G76", "G81", "G82", "G83", "G84", "G85", "G86",
                           "G87", "G88", "G89")},
    "G7": "makes X a diameter (lathe mode): the stage would move half as far",
    "G20": "switches to inches: the program's numbers are mm",
    "G91": "switches to incremental distances: the program's moves are absolute",
    **{g: "offsets the X Y path (cutter compensation): the stage would leave it" for g in
       ("G41", "G41.1", "G42", "G42.1")},
    "G64": "lets the control blend corners, in joint space: the tip would leave its path (the program needs G61)",
    **{g: _OFFSETS for g in ("G10", "G28.1", "G30.1", "G43.1", "G52", "G92", "G92.3")},
}
#: M codes a block may use: modal group and the words the code uses (M100-M199 are added below).
_M_ALLOWED: dict[str, tuple[str, str]] = {
    "M0": ("stopping", ""), "M1": ("stopping", ""), "M60": ("stopping", ""),
    "M3": ("spindle", ""), "M4": ("spindle", ""), "M5": ("spindle", ""), "M19": ("spindle", "RQ"),
    "M6": ("tool change", ""), "M61": ("tool change", "Q"),
    "M7": ("coolant", ""), "M8": ("coolant", ""), "M9": ("coolant", ""),
    "M48": ("overrides", ""), "M49": ("overrides", ""),
    **{m: ("overrides", "P") for m in ("M50", "M51", "M52", "M53")},
    **{m: ("input/output", "P") for m in ("M62", "M63", "M64", "M65")},
    "M66": ("input/output", "PELQ"), "M67": ("input/output", "EQ"), "M68": ("input/output", "EQ"),
    **{m: ("modal state", "") for m in ("M70", "M71", "M72", "M73")},
    **{f"M{n}": ("user", "PQ") for n in range(100, 200)},
}
#: M codes LinuxCNC knows that a block must not use, and why.
_M_REFUSED: dict[str, str] = {
    "M2": "ends the program (program.end_code does, after the postamble)",
    "M30": "ends the program (program.end_code does, after the postamble)",
    "M98": "calls a subprogram (not for a dialect block)",
    "M99": "returns from a subprogram, or restarts the main program (not for a dialect block)",
}
#: Words a code needs on its block (LinuxCNC rejects the code without them): alternatives in one string.
_NEEDS = {"G4": "P", "G43.2": "H", "G96": "S", "M61": "Q", "M62": "P", "M63": "P", "M64": "P", "M65": "P",
          "M66": "PE", "M67": "E", "M68": "E"}
#: Words no code on a block uses: why not.
_LETTER_REFUSED = {
    **{a: "is an axis word (a dialect block must not move the machine)" for a in "ABCUVWXYZ"},
    **{a: "is an arc or canned-cycle word (a dialect block has no motion to use it)" for a in "IJK"},
    "N": "is a block number (the emitter numbers blocks: line_numbers)",
    "O": "is a program number or subprogram word (the program number is program.number)",
}
#: Words that must be whole numbers, and words that must not be negative.
_WHOLE, _NON_NEGATIVE = "THL", "DFHLPQST"


# ----------------------------------------------------------------------------- the check


def block_problem(line: str, comment: tuple[str, str], *, tool_number_max: int) -> str | None:
    """What is wrong with one literal block, or None.

    Parameters
    ----------
    line : str — the block (one line of printable ASCII, already checked for that)
    comment : (open, close) — the dialect's comment delimiters
    tool_number_max : int — the dialect's largest tool number (``T`` and ``M61 Q``)

    Returns
    -------
    str | None — e.g. ``G0 moves the machine (...)``; the caller adds the key and the block

    Examples
    --------
    >>> block_problem("G43 H1 (tool length)", ("(", ")"), tool_number_max=99999) is None
    True
    >>> block_problem("M2", ("(", ")"), tool_number_max=99999)
    'M2 ends the program (program.end_code does, after the postamble)'
    """
    if ";" in line:
        return "has ';' (LinuxCNC reads the rest of the line as a comment, ISO controls as the end of the block)"
    try:
        code, _ = split_comments(line, (comment,))
        words = lex_words(code)
    except LexError as error:
        return str(error)
    codes = [(code_name(letter, value), letter) for letter, value, _ in words if letter in "GM"]
    others = [w for w in words if w[0] not in "GM"]
    return _code_problem(codes) or _word_problem(codes, others, tool_number_max)


def _code_problem(codes: list[tuple[str, str]]) -> str | None:
    """Unknown, refused or conflicting G and M codes."""
    groups: dict[str, str] = {}
    for name, letter in codes:
        allowed, refused = (_G_ALLOWED, _G_REFUSED) if letter == "G" else (_M_ALLOWED, _M_REFUSED)
        if name in refused:
            return f"{name} {refused[name]}"
        if name not in allowed:
            return f"{name} is not an RS-274/NGC {letter} code LinuxCNC knows"
        group = f"{letter} {allowed[name][0]}"
        if group in groups:
            return f"{groups[group]} and {name} are in the same modal group ({allowed[name][0]}): one per block"
        groups[group] = name
    if sum(letter == "M" for _, letter in codes) > 4:
        return "has more than 4 M codes (LinuxCNC: too many M codes on a line)"
    return None


def _word_problem(codes: list[tuple[str, str]], others: list[Word], tool_number_max: int) -> str | None:
    """Words other than G and M: refused, repeated, unused, missing or out of range."""
    names = [name for name, _ in codes]
    uses = "".join((_G_ALLOWED | _M_ALLOWED)[name][1] for name in names)
    seen: set[str] = set()
    for letter, value, text in others:
        if letter in _LETTER_REFUSED:
            return f"{text}: {letter} {_LETTER_REFUSED[letter]}"
        if letter in seen:
            return f"has two {letter} words (LinuxCNC takes one per block)"
        seen.add(letter)
        if letter not in "FST" and letter not in uses:
            return f"{text}: {letter} needs a code that uses it on the same block ({_users(letter)})"
        if letter in _NON_NEGATIVE and value < 0:
            return f"{text}: {letter} must not be negative"
        if letter in _WHOLE and value != int(value):
            return f"{text}: {letter} must be a whole number"
        if letter == "T" and value > tool_number_max:
            return f"{text}: the tool number is above words.tool_number_max = {tool_number_max}"
    for name in names:
        need = _NEEDS.get(name, "")
        if need and not seen & set(need):
            return f"{name} needs {' or '.join(need)} on the same block"
    tool = next((v for w, v, _ in others if w == "Q"), 0.0) if "M61" in names else 0.0
    if tool != int(tool) or tool > tool_number_max:
        return f"M61 Q is the tool number: a whole number 0..{tool_number_max} (words.tool_number_max)"
    if "M19" in names and any(w == "Q" and v <= 0 for w, v, _ in others):
        return "M19 Q (the orientation mode) must be > 0"
    return None


def _users(letter: str) -> str:
    """``G4, M50, ..., M100-M199``: the codes a block may use ``letter`` with."""
    users = [n for n, (_, used) in (_G_ALLOWED | _M_ALLOWED).items() if letter in used and not _user_m(n)]
    user = any(_user_m(n) and letter in used for n, (_, used) in _M_ALLOWED.items())
    return ", ".join([*users, *(["M100-M199"] if user else [])])


def _user_m(name: str) -> bool:
    return name.startswith("M") and 100 <= int(name[1:]) <= 199
