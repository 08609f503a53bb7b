"""Every command starts fast: the heavy libraries load only in the commands that need them.

trimesh (with networkx and PIL) takes about 200 ms to import, matplotlib 300 ms, shapely 60 ms:
`ik`, `fk` and `machines` need none of them, and `verify` reads no STL. The package's own heavy
modules load where they are used too: the main job (with the placement search and the collision
check) and `convert` (with multiprocessing) cost about 0.1 s of start-up each, which `ik`, `fk`
and a plain `verify` never need. Each check runs in a fresh interpreter, since this test process
has long imported everything.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from prs3_post.cli.main import main

HEAVY = ("trimesh", "networkx", "PIL", "shapely", "matplotlib", "pygcode")
#: The package's modules (and the standard library's) that only the main job, convert and
#: verify --against need.
JOB_MODULES = ("prs3_post.app.convert", "prs3_post.app.job", "prs3_post.check.placement", "prs3_post.check.collision",
               "prs3_post.part.faces", "prs3_post.readers.jobfile", "multiprocessing")
#: What only writing a program needs: the emitter (the dialect's comment layout, which reading a
#: program needs as well, lives in ``prs3_post.machine.dialect``).
WRITE_MODULES = ("prs3_post.emit.gcode",)
#: What only reading a part needs (the STL reader; the CLI's --up choices live in
#: ``prs3_post.part.setup_transform``), and
#: the work plane, which only a converted program's header states.
PART_MODULES = ("prs3_post.part.stl", "prs3_post.part.workplane")
#: The five-axis source conventions: only convert and the check of a converted program need them.
SOURCE_MODULES = ("prs3_post.machine.cam_conventions",)
#: The paper's per-leg IK (``--model paper``, for validation only).
PAPER_MODULES = ("prs3_post.kinematics.prs3.paper",)
#: The ik/fk tables and the pose CSV reader, which a plain verify needs neither of.
TABLE_MODULES = ("prs3_post.app.pose_tables", "prs3_post.readers.poses")
#: The reader registry (``convert --format``'s choices, the detection of a file's format), the use cases
#: of convert, the main job and verify's inputs, and hashlib (a part's hash): about 10 ms of start-up
#: that `ik`, `fk` and `machines` never need.
REGISTRY_MODULES = ("prs3_post.readers.registry", "prs3_post.app.convert_files", "prs3_post.app.run",
                    "prs3_post.app.verify_inputs", "hashlib")
#: What a plain verify never needs of those (it asks the registry whether the program is a CL file).
VERIFY_UNUSED = ("prs3_post.app.convert_files", "prs3_post.app.run", "prs3_post.app.listings", "hashlib",
                 "prs3_post.app.cross_check")

_PROBE = """
import json, sys
from click.testing import CliRunner
import prs3_post.cli.main
args = json.loads(sys.argv[1])
if args:
    result = CliRunner().invoke(prs3_post.cli.main.main, args)
    assert result.exit_code == 0, result.output
print(json.dumps(sorted(set(sys.modules) & set(json.loads(sys.argv[2])))))
"""


def _loaded_after(args: list[str], modules: tuple[str, ...] = HEAVY) -> list[str]:
    """The ``modules`` a fresh interpreter holds after importing the CLI and running ``args``."""
    done = subprocess.run([sys.executable, "-c", _PROBE, json.dumps(args), json.dumps(modules)],
                          capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_importing_the_cli_loads_no_heavy_library():
    assert _loaded_after([]) == []


@pytest.mark.parametrize("args", [
    ["ik", "--tip", "-81.0264,21.2132,-679.4865", "--axis", "0.447214,0,0.894427"],
    ["fk", "--strokes", "36.2244,170.3886,88.9519", "--xy", "-2.7640,12.0703"],
    ["machines"],
], ids=["ik", "fk", "machines"])
def test_kinematics_commands_load_no_heavy_library(args):
    unused = HEAVY + JOB_MODULES + WRITE_MODULES + PART_MODULES + SOURCE_MODULES + PAPER_MODULES + REGISTRY_MODULES
    assert _loaded_after(args, unused) == []


def test_verify_loads_no_heavy_library(tmp_path):
    program = tmp_path / "hole.ngc"
    made = CliRunner().invoke(main, ["demo", "--profile", "hole", "-o", str(program)])
    assert made.exit_code == 0, made.output
    unused = (HEAVY + JOB_MODULES + WRITE_MODULES + PART_MODULES + SOURCE_MODULES + TABLE_MODULES + PAPER_MODULES
              + VERIFY_UNUSED)
    assert _loaded_after(["verify", str(program)], unused) == []


#: What a conversion needs only with a part (--part: the collision check), an automatic placement,
#: a 5-axis source, or several files at once (--jobs: worker processes).
CONVERT_EXTRAS = ("prs3_post.check.placement", "prs3_post.check.collision", "prs3_post.readers.fivex.reader",
                  "prs3_post.machine.cam_conventions", "prs3_post.app.job", "multiprocessing",
                  "concurrent.futures.process")


def test_convert_loads_no_plotting_or_mesh_library(tmp_path):
    """A G-code file converted without a part, at a given origin, in this process: no matplotlib, trimesh
    or shapely, and none of the modules of the conversions it is not (about 40 ms of start-up)."""
    source = Path(__file__).resolve().parents[2] / "fixtures" / "gcode" / "wedge-face-3axis.ngc"
    args = ["convert", str(source), "-d", str(tmp_path), "--part-origin=-60.9,-10.9,-745.0", "--jobs", "1"]
    assert _loaded_after(args, HEAVY + CONVERT_EXTRAS) == []


def test_the_console_script_runs_openblas_on_one_thread_unless_told_otherwise() -> None:
    """numpy's OpenBLAS starts a thread per core when imported (0.09 CPU s of every start, for nothing):
    the console script asks for one, and a user's own setting is kept."""
    count = ("import os, sys; from prs3_post.cli import entry; {set}; entry.configure_blas(); import numpy; "
             "print(len(os.listdir('/proc/self/task')), os.environ['OPENBLAS_NUM_THREADS'])")
    env = {k: v for k, v in __import__("os").environ.items() if k != "OPENBLAS_NUM_THREADS"}
    alone = subprocess.run([sys.executable, "-c", count.format(set="pass")], env=env, capture_output=True,
                           text=True, check=True)
    assert alone.stdout.split() == ["1", "1"]
    kept = subprocess.run([sys.executable, "-c", count.format(set="os.environ['OPENBLAS_NUM_THREADS'] = '2'")],
                          env=env, capture_output=True, text=True, check=True)
    assert kept.stdout.split()[1] == "2"


_FAULTS = """import resource, sys
from prs3_post.cli import entry
if sys.argv[1] == "set":
    assert entry.configure_malloc()
import numpy as np
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for k in range(500):                                   # a chunk's temporaries: made, combined, freed
    a = np.ones(40_000 + 1000 * (k % 7))
    b = a * 2.0
    c = np.concatenate([a, b, a])
    d = c[::2] + 1.0
    del a, b, c, d
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc")
def test_the_console_script_keeps_a_chunks_temporaries_on_the_heap() -> None:
    """Without the malloc settings the arrays (320 KB to 1 MB) are mapped anew or the heap is trimmed
    and grown again, and their pages fault in again (255,532 faults here); with them the heap's
    pages are reused (575)."""
    env = {k: v for k, v in __import__("os").environ.items()
           if k not in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "GLIBC_TUNABLES")}
    faults = {}
    for mode in ("set", "unset"):
        done = subprocess.run([sys.executable, "-c", _FAULTS, mode], env=env, capture_output=True, text=True,
                              check=True)
        faults[mode] = int(done.stdout)
    assert faults["set"] * 20 < faults["unset"], faults


def test_the_console_script_freezes_what_it_loaded_for_the_garbage_collector() -> None:
    """The collections the CLI's loading triggered were some 7 % of a short command's CPU time: the
    collector is off while it loads, what it loaded is frozen, and the collector is on again."""
    code = ("import gc, sys\nfrom prs3_post.cli import entry\nsys.argv = ['prs3-post', '--version']\n"
            "try:\n    entry.main()\nexcept SystemExit:\n    pass\n"
            "print(gc.get_freeze_count() > 10_000, gc.isenabled())")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split()[-2:] == ["True", "True"]
