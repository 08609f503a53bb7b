"""Size and browser load time of `prs3-post preview PROGRAM -o view.html` on a long program (a script, not a test).

    python bench/bench_view.py [--lines 1000000] [--repeat 3] [--keep DIR] [--program PROGRAM.ngc]

Generates the program bench_verify.py does (``--lines`` G1 lines: laps of a circle on the stage, every
tenth lap a sweep of the tool axis; or takes ``--program``), writes its view with ``prs3-post preview``
in a fresh process (wall time, peak memory), then opens the page ``--repeat`` times in Debian's
chromium through Playwright (headless, WebGL through SwiftShader, a new page each time) and times
from the navigation to the page's ``data-ready`` mark (both plots drawn, the machine at the first
stop): median and range, with the file's size and the machine's load average.

Targets (issue 21): a 1,000,000-line program gives a view under 30 MB that loads in under 15 s.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from _measure import load, run_cli, spread
from bench_verify import make_program

CHROMIUM = "/usr/bin/chromium"


def load_times(view: Path, repeat: int) -> list[float]:
    """Seconds from ``goto`` to the page's ready mark, one new page per repeat (one browser)."""
    from playwright.sync_api import sync_playwright

    times = []
    with sync_playwright() as driver:
        browser = driver.chromium.launch(executable_path=CHROMIUM, args=[
            "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"])
        for _ in range(repeat):
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            start = time.perf_counter()
            page.goto(view.as_uri(), timeout=120_000)
            page.wait_for_selector("body[data-ready='1']", timeout=120_000)
            times.append(time.perf_counter() - start)
            page.close()
        browser.close()
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lines", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--program", type=Path, help="view this program instead of a generated one")
    parser.add_argument("--keep", type=Path, help="write the program and its view here and keep them")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        folder = args.keep or Path(scratch)
        folder.mkdir(parents=True, exist_ok=True)
        program = args.program or folder / "long.ngc"
        if args.program is None:
            make_program(program, args.lines)
        view = folder / "view.html"
        made = run_cli(["preview", str(program), "-o", str(view), "-q"])
        if made.code != 0:
            raise SystemExit(f"preview failed: {made.last}")
        lines = sum(1 for _ in open(program, "rb"))
        print(f"{program.name}: {lines} lines; {load()}")
        print(f"preview -o view.html: {made.wall:.1f} s wall, {made.cpu:.1f} s CPU, peak {made.peak_mb:.0f} MB")
        print(f"view.html: {view.stat().st_size / 1e6:.2f} MB")
        times = load_times(view, args.repeat)
        print(f"load in chromium (goto to ready), {args.repeat} pages: {spread(times, '.2f')} s "
              f"(median {statistics.median(times):.2f} s)")


if __name__ == "__main__":
    main()
