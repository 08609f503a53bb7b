"""Build hook: compiles csrc/*.c into prs3_post/_native.so (the compiled line writer, lexer and CL GOTO reader).

Plain C with no Python API, built with the machine's C compiler (``$CC``, else ``cc``) and loaded with
ctypes (src/prs3_post/core/native.py). Where no compiler works, the package is built all the same and
numpy writes the lines and lexes the programs (the same results, slower): a message says so, and nothing
fails.
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from hatchling.builders.hooks.plugin.interface import BuildHookInterface

SOURCES = Path("csrc")
TARGET = Path("src") / "prs3_post" / "_native.so"


def compile_library(root: Path, target: Path) -> bool:
    """Compile SOURCES' C files into ``target``; False (with a message on stderr) where that fails."""
    compiler = shlex.split(os.environ.get("CC", "cc"))
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as scratch:
        built = Path(scratch) / target.name
        # -Wall -Werror: a warning is a bug here (the library is called with raw addresses and sizes); a
        # compiler that warns builds no library, and numpy does the work (a message says so)
        command = [*compiler, "-O2", "-shared", "-fPIC", "-o", str(built), "-Wall", "-Werror",
                   *sorted(str(path) for path in (root / SOURCES).glob("*.c"))]
        try:
            result = subprocess.run(command, capture_output=True, text=True, timeout=120, check=False)
        except (OSError, subprocess.TimeoutExpired) as error:
            print(f"prs3-post: no compiled library ({error}); numpy writes and lexes instead", file=sys.stderr)
            return False
        if result.returncode != 0:
            print(f"prs3-post: no compiled library ({shlex.join(command)} failed: {result.stderr.strip()[:500]});"
                  " numpy writes and lexes instead", file=sys.stderr)
            return False
        os.replace(built, target)                       # a loaded old copy keeps its own inode
    return True


class NativeBuildHook(BuildHookInterface):  # type: ignore[misc]
    PLUGIN_NAME = "custom"

    def initialize(self, version: str, build_data: dict[str, Any]) -> None:
        if self.target_name != "wheel":
            return
        root = Path(self.root)
        if not compile_library(root, root / TARGET):
            return
        build_data["pure_python"] = False
        build_data["infer_tag"] = True
        if version != "editable":                       # an editable install finds it in src/ itself
            build_data["force_include"][str(root / TARGET)] = "prs3_post/_native.so"
