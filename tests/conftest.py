"""Shared test options and fixtures.

``pytest --update-golden`` rewrites the golden programs in fixtures/golden/ instead of comparing
them; review every golden change in its diff before committing it.
"""

from __future__ import annotations

import difflib
import os
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
FIXTURES = REPO / "fixtures"
SHARED = REPO.parent / "shared"
RS274_CHECK = REPO / "scripts" / "rs274-check"       # LinuxCNC's interpreter, with the axes named
CHROMIUM = Path("/usr/bin/chromium")                  # Debian's chromium (apt), driven by Playwright


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--update-golden", action="store_true", help="rewrite fixtures/golden/* from the current output")


@pytest.fixture
def update_golden(request: pytest.FixtureRequest) -> bool:
    return bool(request.config.getoption("--update-golden"))


def compare_golden(text: str, golden: Path, update: bool) -> None:
    """Compare ``text`` byte for byte with ``golden`` (or rewrite it with --update-golden)."""
    if update:
        golden.parent.mkdir(parents=True, exist_ok=True)
        golden.write_bytes(text.encode("utf-8"))
        return
    if not golden.exists():
        pytest.fail(f"{golden.relative_to(REPO)} does not exist: run pytest --update-golden and review it")
    expected = golden.read_bytes().decode("utf-8")
    if text != expected:
        diff = "".join(difflib.unified_diff(
            expected.splitlines(keepends=True), text.splitlines(keepends=True),
            fromfile=f"{golden.name} (golden)", tofile=f"{golden.name} (now)", n=2,
        ))
        pytest.fail(f"{golden.relative_to(REPO)} differs:\n{diff[:6000]}")


def rs274_available() -> tuple[bool, str]:
    """Whether LinuxCNC's interpreter check can run here, and why not."""
    if not RS274_CHECK.exists():
        return False, f"{RS274_CHECK} not found"
    if shutil.which("python3") is None:
        return False, "python3 not on PATH"
    probe = subprocess.run([str(RS274_CHECK), "--help"], capture_output=True, text=True, check=False)
    if probe.returncode != 0:
        return False, "rs274-check cannot run"
    if not Path("/usr/bin/python3").exists():
        return False, "/usr/bin/python3 missing"
    gcode = subprocess.run(["/usr/bin/python3", "-c", "import gcode"], capture_output=True, check=False)
    if gcode.returncode != 0:
        return False, "LinuxCNC's gcode module is not installed (apt-get install linuxcnc-uspace)"
    return True, ""


@pytest.fixture(scope="session")
def rs274_check():
    """A function that runs rs274-check on files and returns (exit code, output).

    Skips where LinuxCNC is not installed, except in CI (CI set), where that is a failure.
    """
    ok, why = rs274_available()
    if not ok:
        if os.environ.get("CI"):
            pytest.fail(f"rs274-check must run in CI: {why}")
        pytest.skip(f"LinuxCNC interpreter unavailable: {why}")

    def check(*paths: Path, axes: str = "XYUVW") -> tuple[int, str]:
        done = subprocess.run(
            [str(RS274_CHECK), "-a", axes, *map(str, paths)], capture_output=True, text=True, check=False
        )
        return done.returncode, done.stdout + done.stderr

    return check


def chromium_available() -> tuple[bool, str]:
    """Whether a real browser can run here (Debian's chromium, and Playwright to drive it), and why not."""
    if not CHROMIUM.exists():
        return False, f"{CHROMIUM} not found (apt-get install --no-install-recommends chromium)"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return False, "playwright is not installed (pip install -e '.[test]')"
    return True, ""


def linuxcnc_available() -> tuple[bool, str]:
    """Whether `prs3-post sim` can run LinuxCNC here (its launcher, and Debian's python3 with the
    linuxcnc module), and why not."""
    if shutil.which("linuxcnc") is None:
        return False, "the linuxcnc launcher is not on PATH (apt-get install linuxcnc-uspace)"
    if not Path("/usr/bin/python3").exists():
        return False, "/usr/bin/python3 missing"
    probe = subprocess.run(["/usr/bin/python3", "-c", "import linuxcnc"], capture_output=True, check=False)
    if probe.returncode != 0:
        return False, "LinuxCNC's python module is not installed (apt-get install linuxcnc-uspace)"
    return True, ""


@pytest.fixture(scope="session")
def chromium():
    """A headless chromium (Playwright's Browser), WebGL through SwiftShader; never ``playwright install``.

    Skips where chromium or Playwright is missing, except in CI (CI set), where that is a failure.
    """
    ok, why = chromium_available()
    if not ok:
        if os.environ.get("CI"):
            pytest.fail(f"the browser tests must run in CI: {why}")
        pytest.skip(f"no browser: {why}")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as driver:
        # --no-sandbox: chromium refuses to start as root without it (CI containers run as root)
        browser = driver.chromium.launch(executable_path=str(CHROMIUM), args=[
            "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"])
        yield browser
        browser.close()


@pytest.fixture(scope="session")
def linuxcnc() -> None:
    """Needs LinuxCNC (`prs3-post sim`): skips where it is not installed, except in CI (CI set), where
    that is a failure."""
    ok, why = linuxcnc_available()
    if not ok:
        if os.environ.get("CI"):
            pytest.fail(f"LinuxCNC must run in CI: {why}")
        pytest.skip(f"LinuxCNC unavailable: {why}")
