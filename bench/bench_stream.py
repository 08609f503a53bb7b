"""Throughput and peak memory of the streaming pipeline, CL file to G-code file (a script, not a test).

    python bench/bench_stream.py [--lines 1000000] [--repeat 3]

The synthetic CL file of ``bench_cl_reader.py`` (5-axis GOTOs, one tool axis tilted 36.9°) goes
(a) through ``ClStream`` alone (chunks dropped: the reader's share), (b) through ``ClStream`` →
``PostStream`` (setup, subdivision, IK, resolution guard, limits, feeds; programs dropped), (c) the
whole conversion, streamed: ``program_text`` over the chunks into ``write_atomic`` (a temp file,
renamed), and (d) the same conversion whole: ``read_cl`` + ``post_process`` + ``emit_program`` +
``write_atomic``. Moves/s are input GOTOs per second of wall and of CPU time (best of ``repeat``); peak memory
is traced with tracemalloc on one call. The streamed peak should stay flat in the file's length
(it holds one chunk), the whole one grows with it; (c) and (d) must write the same bytes.
"""

from __future__ import annotations

import argparse
import os
import tempfile

from _measure import measure
from bench_cl_reader import write_cl

from prs3_post.app.streaming import program_text
from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE, DEFAULT_TOLERANCE
from prs3_post.core.defaults import DEFAULT_CIRCLE_TOLERANCE as CIRCLE_TOL
from prs3_post.core.output_files import write_atomic
from prs3_post.emit.gcode import emit_program
from prs3_post.machine.loading import load_dialect, load_machine
from prs3_post.part.setup_transform import Setup
from prs3_post.post.pipeline import PostStream, post_process
from prs3_post.readers.cl.reader import ClStream, read_cl

MACHINE = load_machine("patel2020")
DIALECT = load_dialect("linuxcnc")
SETUP = Setup((0.0, 0.0, -690.0))


def read_only(path: str) -> None:
    for _ in ClStream(path, tolerance=0.002, circle_tolerance=CIRCLE_TOL):
        pass


def post_only(path: str) -> None:
    stream = PostStream(MACHINE, SETUP, length_decimals=DIALECT.decimals.length)
    for chunk in ClStream(path, tolerance=0.002, circle_tolerance=CIRCLE_TOL):
        stream.feed(chunk)


def streamed(path: str, out: str) -> None:
    write_atomic(out, program_text(MACHINE, ClStream(path, tolerance=0.002,
                                                     circle_tolerance=CIRCLE_TOL), SETUP, DIALECT,
                                   tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE))


def whole(path: str, out: str) -> None:
    result = post_process(MACHINE, read_cl(path, tolerance=0.002, circle_tolerance=CIRCLE_TOL).toolpath, SETUP,
                          length_decimals=DIALECT.decimals.length,
                          tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    write_atomic(out, emit_program(result.program, DIALECT))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lines", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "bench.cls")
        out_streamed, out_whole = os.path.join(tmp, "streamed.ngc"), os.path.join(tmp, "whole.ngc")
        moves = write_cl(path, args.lines)
        print(f"{args.lines:,} lines, {moves:,} GOTOs, {os.path.getsize(path) / 1e6:.1f} MB")
        results = {
            "ClStream (reader only)": measure(lambda: read_only(path), args.repeat),
            "ClStream -> PostStream": measure(lambda: post_only(path), args.repeat),
            "streamed CL -> .ngc": measure(lambda: streamed(path, out_streamed), args.repeat),
            "whole CL -> .ngc": measure(lambda: whole(path, out_whole), args.repeat),
        }
        with open(out_streamed, "rb") as a, open(out_whole, "rb") as b:
            same = a.read() == b.read()
        for name, (seconds, cpu, peak) in results.items():
            print(f"{name:24s} {moves / seconds:12,.0f} moves/s wall {moves / cpu:12,.0f} per CPU s  "
                  f"peak {peak / 1e6:8.1f} MB")
        print(f"streamed and whole programs byte-identical: {same}")
        if not same:
            raise SystemExit(1)


if __name__ == "__main__":
    main()
