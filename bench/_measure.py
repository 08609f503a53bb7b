"""What the benches share: a call timed in this process (wall, CPU, traced peak), the CLI in a child
process (wall, CPU, peak memory), pygcode's parse-only loop as the reference, the load average, and
"median (range min..max)" (helpers, not a bench).

The child runs the console script's entry point (:func:`prs3_post.cli.entry.main`, which also sets
OpenBLAS's threads), as ``prs3-post`` on the command line does. Its peak memory is its ``VmHWM`` from
``/proc/self/status`` (the peak resident set of that process image; ``ru_maxrss`` would count the
parent's pages at fork), plus, where it forked processes of its own (``convert`` reads a large input
in one), the largest of theirs (``ru_maxrss`` of its waited children, which counts the pages they
share with it at fork again: an upper bound); its CPU time is user + system of itself (all its
threads) and of those processes. On a loaded machine the rates per CPU second say more than the
wall-clock ones.
"""

from __future__ import annotations

import itertools
import os
import statistics
import subprocess
import sys
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

#: Runs the CLI in a child process and reports its own CPU time and peak resident memory on standard error.
_CHILD = """import resource, sys
from prs3_post.cli.entry import main
sys.argv = ["prs3-post", *sys.argv[1:]]
try:
    main()
finally:
    usage, forked = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    peak = int(next(ln.split()[1] for ln in open("/proc/self/status") if ln.startswith("VmHWM:")))
    cpu = usage.ru_utime + usage.ru_stime + forked.ru_utime + forked.ru_stime
    sys.stderr.write(f"\\nPEAK_KB {peak + forked.ru_maxrss} CPU_S {cpu} FORKED_KB {forked.ru_maxrss}\\n")
"""


@dataclass(frozen=True, slots=True)
class ChildRun:
    """One CLI run in a child process.

    Attributes
    ----------
    wall, cpu : float — s (cpu: the child's user + system time, start-up included)
    peak_mb : float — the child's peak resident memory (VmHWM), MB (2**20 bytes), plus ``forked_mb``
    forked_mb : float — the largest peak of the processes the child forked and waited for (0: none), MB
    code : int — exit status
    last : str — its last line of output (standard output, else standard error), for the log
    stdout : str — its standard output
    """

    wall: float
    cpu: float
    peak_mb: float
    code: int
    last: str
    stdout: str = ""
    forked_mb: float = 0.0


def run_cli(args: list[str], env: dict[str, str] | None = None) -> ChildRun:
    """Run ``prs3-post ARGS`` (this worktree's ``src``) in a fresh process and measure it."""
    env = {**os.environ, "PYTHONPATH": str(REPO / "src"), **(env or {})}      # env may name another src
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", _CHILD, *args], capture_output=True, env=env, text=True,
                          check=False)
    wall = time.perf_counter() - start
    words = next(ln.split() for ln in done.stderr.splitlines() if ln.startswith("PEAK_KB "))
    said = [ln for ln in done.stderr.splitlines() if ln.strip() and not ln.startswith("PEAK_KB ")]
    last = (done.stdout.strip().splitlines() or said or [""])[-1]
    return ChildRun(wall=wall, cpu=float(words[3]), peak_mb=float(words[1]) / 1024, code=done.returncode,
                    last=last[:160], stdout=done.stdout, forked_mb=float(words[5]) / 1024)


def pygcode_rate(path: Path | str, lines: int) -> tuple[float, float]:
    """Lines per second of wall time and of CPU time of a loop that only parses the file's first
    ``lines`` lines with ``pygcode.Line`` (read into memory first: the loop times the parsing alone)."""
    import pygcode  # the reference only: not a dependency of prs3-post

    with open(path, encoding="utf-8") as stream:
        text = list(itertools.islice(stream, lines))
    wall, cpu = time.perf_counter(), time.process_time()
    for line in text:
        pygcode.Line(line)
    return len(text) / (time.perf_counter() - wall), len(text) / (time.process_time() - cpu)


def timed(call: Callable[[], object]) -> tuple[float, float]:
    """Wall time and CPU time of one call in this process (s; CPU time is the fairer on a loaded machine)."""
    start, start_cpu = time.perf_counter(), time.process_time()
    call()
    return time.perf_counter() - start, time.process_time() - start_cpu


def traced_peak(call: Callable[[], object]) -> int:
    """Peak memory traced by tracemalloc during one call (bytes; NumPy reports its buffers to it).
    Traced apart from the timed calls: tracing slows the call."""
    tracemalloc.start()
    call()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak


def measure(call: Callable[[], object], repeat: int) -> tuple[float, float, int]:
    """Best wall and best CPU time of ``repeat`` calls (s) and the traced peak of one more (bytes)."""
    times = [timed(call) for _ in range(repeat)]
    return min(t[0] for t in times), min(t[1] for t in times), traced_peak(call)


def spread(values: list[float], fmt: str) -> str:
    """``median (range min..max)``, each formatted with ``fmt``."""
    return f"{format(statistics.median(values), fmt)} (range {format(min(values), fmt)}..{format(max(values), fmt)})"


def load() -> str:
    """The load average (1 and 5 minutes) and the cores, for the log."""
    one, five, _ = os.getloadavg()
    return f"load average {one:.2f} (5 min {five:.2f}), {os.cpu_count()} cores"


def count_lines(path: Path | str) -> int:
    """Newlines in a file, read in blocks."""
    with open(path, "rb") as stream:
        return sum(block.count(b"\n") for block in iter(lambda: stream.read(1 << 20), b""))
