"""Every corpus part and CAM file, run the way the tutorial and the how-tos run a file of one's own, with
every suggestion the output prints followed once (issue 20 §3).

A part: ``faces PART``, then the main job (``PART --profile hole``, and the square and round profiles with
their defaults); a CAM file: ``convert FILE`` and ``convert FILE --part-origin auto``. Whatever the output
suggests as options to give (``--part-origin=X,Y,Z``, ``--up X``, ``--part-units inch``, ``--source NAME``,
``--at U,V``, ``--size S``, ...) is given in the next run, each suggestion once; the walk ends in a program
written (exit 0) or in an honest "cannot": a refusal that says no setup or option fixes it, and suggests
nothing more. A suggestion that leads to a refusal suggesting nothing and saying no such thing fails the test.
Runs in-process (CliRunner); the corpus is ../shared/corpus.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from prs3_post.cli.main import main

REPO = Path(__file__).resolve().parents[2]
CORPUS = REPO.parent / "shared" / "corpus"
pytestmark = pytest.mark.skipif(not CORPUS.is_dir() and not os.environ.get("CI"),
                                reason=f"the shared corpus is not at {CORPUS}")

#: Files of the corpus that are no CAM program or part, and why they are left out.
NOT_INPUTS = {"humman_aptwords.tbl": "a table of APT word codes (reference data), no CAM program"}
PARTS = sorted(p.name for p in (CORPUS / "stl").glob("*")) if CORPUS.is_dir() else []
CAM = sorted(f"{d}/{p.name}" for d in ("cl", "gcode") for p in (CORPUS / d).glob("*")
             if p.name not in NOT_INPUTS) if CORPUS.is_dir() else []

#: Words of a refusal that says no setup or option fixes it.
CANNOT = ("no setup changes that", "no setup turns", "no setup brings", "no translation of the part", "no part origin",
          "no placement changes this", "cannot be converted", "no other up axis", "cannot reach it from above",
          "no part origin and rotation")
#: How many suggestions a walk may follow, one after the other (each once).
MAX_STEPS = 5


def _suggestions(text: str) -> list[list[str]]:
    """The options a message asks for, each as the arguments that give it, in the order they appear."""
    found: list[list[str]] = []
    for match in re.finditer(r"--part-origin=(-?[0-9.]+,-?[0-9.]+,-?[0-9.]+)", text):
        found.append([f"--part-origin={match[1]}"])
    for match in re.finditer(r"\((--up) (-?[xyz])\)", text):
        found.append([match[1], match[2]])
    for match in re.finditer(r"use (--part-units|--units) (inch|mm)", text):
        found.append(["--part-units", match[2]])
    for match in re.finditer(r"\((--at) (-?[0-9.]+,-?[0-9.]+)((?: --[a-z-]+ [0-9.]+)*)\)", text):
        found.append([match[1], match[2], *match[3].split()])
    for match in re.finditer(r"\((--(?:size|diameter|tool-diameter)) ([0-9.]+)\)", text):
        found.append([match[1], match[2]])
    return found


def _source_for(path: Path) -> list[str]:
    """``--source NAME`` for a 5-axis program, NAME the shipped source whose rotary words are the program's
    (``prs3-post sources`` lists them), as a user picks it; [] when none is."""
    listed = CliRunner().invoke(main, ["sources"]).stdout.splitlines()
    letters = set(re.findall(r"(?<![A-Z#<_])([ABC])\s*-?[0-9.]", path.read_text(errors="replace").upper()))
    for line in listed:
        name, axes = line.split()[0], set(line.split()[1:3])
        if axes == letters:
            return ["--source", name]
    return []


def _walk(base: list[str], first_suggestions: list[list[str]] | None = None,
          source: Path | None = None) -> list[tuple[list[str], int, str]]:
    """Run ``base``, then again with each new suggestion added (each once): every run's options, exit code
    and output (standard output and error)."""
    given: list[list[str]] = []
    runs = []
    for _ in range(MAX_STEPS + 1):
        args = base + [word for option in given for word in option]
        result = CliRunner().invoke(main, args)
        text = result.stdout + result.stderr
        runs.append((args, result.exit_code, text))
        assert result.exception is None or isinstance(result.exception, SystemExit), text
        if result.exit_code == 0 and "failed\t" not in text:
            break
        new = [s for s in _suggestions(text) if s not in given
               and not any(s[0].split("=")[0] == g[0].split("=")[0] for g in given)]
        if source is not None and "--source" in text and not any(g[0] == "--source" for g in given):
            new.append(_source_for(source))
        new = [s for s in new if s]
        if not new:
            break
        given.append(new[0])
    return runs


def _verdict(runs: list[tuple[list[str], int, str]]) -> None:
    """The walk ended in a program, or in a refusal that says no option fixes it (and asks for nothing)."""
    _, code, text = runs[-1]
    trail = "\n".join(f"$ prs3-post {' '.join(a)}\n  exit {c}: {t.strip()[:900]}" for a, c, t in runs)
    if code == 0 and "failed\t" not in text:
        return
    assert any(words in text for words in CANNOT), f"neither a program nor an honest 'cannot':\n{trail}"
    assert len(runs) <= MAX_STEPS, f"suggestions lead on and on:\n{trail}"


@pytest.mark.parametrize("part", PARTS)
def test_a_corpus_part_works_or_says_why_not_the_tutorials_way(part, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = str(CORPUS / "stl" / part)
    faces = CliRunner().invoke(main, ["faces", path])
    assert faces.exit_code == 0, faces.output
    hinted = _suggestions(faces.stdout + faces.stderr)
    for profile in ("hole", "square", "round"):
        runs = _walk([path, "--profile", profile, "-o", f"{profile}.ngc", *[w for s in hinted[:1] for w in s]])
        _verdict(runs)


@pytest.mark.parametrize("name", CAM)
def test_a_corpus_cam_file_converts_or_says_why_not_the_how_tos_way(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = CORPUS / name
    for extra in ([], ["--part-origin", "auto"]):
        out = tmp_path / ("auto" if extra else "given")
        out.mkdir()
        _verdict(_walk(["convert", str(path), "-o", str(out), *extra], source=path))
