"""Start-up of the small commands: whole-process wall and CPU time (a script, not a test).

    python bench/bench_startup.py [--repeat 10] [--no-bytecode]

Runs, each ``--repeat`` times in a fresh process (``_measure.run_cli``), alternately:

* ``ik`` on one pose;
* ``verify`` of a small program (the 33-line hole demo, made first);
* ``convert`` of a 17-line G-code file (``fixtures/gcode/wedge-face-3axis.ngc``, ``--jobs 1``).

and prints each command's median and range (min..max) of wall and CPU time, with the load average
before and after. Target (issue 7 §2b): ``ik`` on one pose and ``verify`` of a small program under
0.25 s wall. The children run with the package's byte code compiled, as an installed prs3-post has
it (a cache in the temporary folder, filled by one run of each first); where
``PYTHONDONTWRITEBYTECODE`` is set, each run would also compile what it imports (``--no-bytecode``
measures that).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from _measure import REPO, load, run_cli, spread

TIP = ["--tip", "-81.0264,21.2132,-679.4865", "--axis", "0.447214,0,0.894427"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=10)
    parser.add_argument("--no-bytecode", action="store_true",
                        help="run the children as the environment says (compiling each time where it forbids bytecode)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        env = None if args.no_bytecode else {"PYTHONDONTWRITEBYTECODE": "", "PYTHONPYCACHEPREFIX": str(folder / "pyc")}
        program = folder / "hole.ngc"
        made = run_cli(["demo", "--profile", "hole", "-d", str(program)], env)
        assert made.code == 0, made.last
        commands = {
            "ik (one pose)": ["ik", *TIP],
            "verify (33 lines)": ["verify", str(program)],
            "convert (17 lines)": ["convert", str(REPO / "fixtures/gcode/wedge-face-3axis.ngc"), "-d",
                                   str(folder / "out"), "--part-origin=-60.9,-10.9,-745.0", "--jobs", "1"],
        }
        for command in commands.values():                   # the byte code cache, and a check that each works
            run = run_cli(command, env)
            assert run.code == 0, run.last
        print(f"before: {load()}; children run with "
              + ("the environment's bytecode setting" if args.no_bytecode else "compiled bytecode"))
        walls: dict[str, list[float]] = {name: [] for name in commands}
        cpus: dict[str, list[float]] = {name: [] for name in commands}
        for _ in range(args.repeat):
            for name, command in commands.items():
                run = run_cli(command, env)
                walls[name].append(run.wall)
                cpus[name].append(run.cpu)
        for name in commands:
            print(f"{name}: wall {spread(walls[name], '.3f')} s; CPU {spread(cpus[name], '.3f')} s")
        print(f"after: {load()}")


if __name__ == "__main__":
    main()
