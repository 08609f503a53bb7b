"""Regenerate docs/preview-demo.png: the demo job (the paper's wedge, square profile) and its preview.

Run from anywhere:  python scripts/make_preview.py

It runs the one-step form of the main job, exactly as a user would type it,

  prs3-post demo --profile square --size 40 --corner-radius 6 -o <temp>/demo-square.ngc --preview docs/preview-demo.png

so the picture is the FK replay of the program that command writes. The PNG carries no time stamp
or software version, so it only changes when the program or the drawing does (the bytes may still
differ between matplotlib or FreeType versions). Needs matplotlib: pip install 'prs3-post[plot]'.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from click.testing import CliRunner

from prs3_post.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
IMAGE = ROOT / "docs" / "preview-demo.png"
ARGS = ["demo", "--profile", "square", "--size", "40", "--corner-radius", "6"]


def make() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        program = Path(tmp) / "demo-square.ngc"
        result = CliRunner().invoke(main, [*ARGS, "-o", str(program), "--preview", str(IMAGE)])
    sys.stderr.write(result.output)
    if result.exit_code == 0:
        print(f"{IMAGE.relative_to(ROOT)}: {IMAGE.stat().st_size} bytes")
    return result.exit_code


if __name__ == "__main__":
    sys.exit(make())
