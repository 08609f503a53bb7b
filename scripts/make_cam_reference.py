"""Write docs/reference/cam-words.md from the CAM readers' own tables: the CL major words, feed units
and cycle kinds the CL reader takes, the G and M codes and words the 3+2 G-code reader takes (with
the modal group of each), the codes it refuses with a reason, and what the 5-axis reader adds.

Run from anywhere:  python scripts/make_cam_reference.py        (--check: exit 1 if the file is stale)

tests/docs/test_docs_reference.py fails when the file differs from what this script writes.
"""

from __future__ import annotations

import sys
from pathlib import Path

from prs3_post.readers.cl import records as cl_records
from prs3_post.readers.cl import syntax as cl_syntax
from prs3_post.readers.fivex import reader as fivex
from prs3_post.readers.gcode import words as gcode_words

ROOT = Path(__file__).resolve().parents[1]
TARGET = ROOT / "docs" / "reference" / "cam-words.md"


def _code(value: float, letter: str) -> str:
    return f"{letter}{value:g}"


def render() -> str:
    lines = [
        "# CAM input: the CL words and G/M codes the readers take",
        "",
        "Generated from the readers' own tables by `scripts/make_cam_reference.py` (a test fails when",
        "this page is stale). What each one does is in [CAM input](cam-input.md); anything not listed",
        "here is refused with its file and line.",
        "",
        "## APT / CL major words",
        "",
        " ".join(f"`{word}`" for word in cl_syntax.KNOWN_WORDS) + ", and `$$` comments.",
        "",
        "Skipped on purpose and counted (display records): "
        + ", ".join(f"`{word}`" for word in sorted(cl_syntax.DISPLAY_WORDS))
        + f", and NX's trailer `{cl_syntax.LISTING_TRAILER} has N lines.`",
        "",
        "`FEDRAT/` units: " + ", ".join(f"`{unit}`" for unit in cl_syntax.FEED_UNITS)
        + ". `CYCLE/` kinds: " + ", ".join(f"`{kind}`" for kind in cl_records._CYCLE_KINDS) + " (until `CYCLE/OFF`).",
        "",
        "## 3+2 G-code",
        "",
        "| code | modal group |",
        "|---|---|",
    ]
    read = [code.rstrip(";") for code in gcode_words.CODES_READ.split()]
    for code in read:
        value = float(code[1:])
        group = (gcode_words.G_GROUPS if code[0] == "G" else gcode_words.M_GROUPS).get(value, "")
        lines.append(f"| `{code}` | {group} |")
    lines += [
        "",
        f"Words: {gcode_words.WORDS_READ}. Comments in parentheses (kept), `%` lines, block numbers.",
        "",
        "Refused with a reason (the message says what to do instead):",
        "",
        "| code | why |",
        "|---|---|",
    ]
    lines += [f"| `{code}` | {why} |" for code, why in gcode_words.HINTS.items()]
    not_read = sorted(fivex._NOT_READ.values())
    lines += [
        "",
        "## 5-axis G-code (`convert --source`)",
        "",
        "The codes of the 3+2 reader except " + ", ".join(f"`{code}`" for code in not_read)
        + ", plus the source's TCP on/off codes, its clamp and inert codes (`prs3-post sources`;"
        " [the source file](source-file.md)), `G28` and `G53` (machine-coordinate blocks, which become"
        " nothing), and the source's rotary words (A, B, C) or tool-vector words (I, J, K).",
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    text = render()
    if "--check" in argv:
        if TARGET.read_text(encoding="utf-8") != text:
            print(f"{TARGET.relative_to(ROOT)} is stale: run python scripts/make_cam_reference.py", file=sys.stderr)
            return 1
        return 0
    TARGET.write_text(text, encoding="utf-8")
    print(f"wrote {TARGET.relative_to(ROOT)} ({len(text.splitlines())} lines)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
