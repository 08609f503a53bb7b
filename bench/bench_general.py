"""The general 3-PRS kinematics (a head as built, each leg its own) against the ideal closed form, in one run.

    python bench/bench_general.py [--n 1000000] [--repeat 7] [--only KERNEL]

The head as built is ``fixtures/machines/patel2020-as-built.toml`` (rail points, links, platform
joints, encoder zeros off by tenths of a millimetre, rails and revolute axes by a tenth of a degree,
rails not parallel); the ideal head is the shipped ``patel2020``. The poses are
``bench_kinematics.workspace``'s (tilt ≤ 45°, any azimuth). Pairs run alternately, ``--repeat``
times each, so that a change of the machine's load hits both: general IK against the ideal exact IK
of the same poses, general FK (of the general IK's strokes) against today's FK (of the ideal IK's).
Printed: each kernel's rate, median (min..max), and the ratio of each pair's times, run by run,
median (min..max). Targets (issue 22): general IK within 10× the ideal closed form's time, general
FK within 2× today's FK. ``--only KERNEL`` runs one kernel ``--repeat`` times after the set-up and
prints nothing (for timing whole processes side by side; the FK kernels then both take the ideal
IK's strokes, and ``--only setup`` is the set-up alone, the part of each process that is not the kernel).
"""

from __future__ import annotations

import argparse
import statistics
from collections.abc import Callable
from pathlib import Path

from _measure import load, spread, timed
from bench_kinematics import workspace

from prs3_post.kinematics.prs3.exact import inverse_exact
from prs3_post.kinematics.prs3.forward import forward
from prs3_post.kinematics.prs3_general.forward import forward_general
from prs3_post.kinematics.prs3_general.inverse import inverse_general
from prs3_post.machine.loading import load_machine

AS_BUILT = Path(__file__).resolve().parents[1] / "fixtures" / "machines" / "patel2020-as-built.toml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--only", choices=("setup", "ideal-ik", "general-ik", "ideal-fk", "general-fk"))
    args = parser.parse_args()
    ideal = load_machine("patel2020").geometry
    built = load_machine(str(AS_BUILT)).geometry.general_geometry()
    n = args.n
    tip, axis = workspace(n)
    if args.only is not None:
        strokes = inverse_exact(ideal, tip, axis)      # the FK kernels' strokes (part of every set-up)
        alone: dict[str, Callable[[], object]] = {
            "setup": lambda: None,
            "ideal-ik": lambda: inverse_exact(ideal, tip, axis),
            "general-ik": lambda: inverse_general(built, tip, axis),
            "ideal-fk": lambda: forward(ideal, strokes.strokes, strokes.stage),
            "general-fk": lambda: forward_general(built, strokes.strokes, strokes.stage),
        }
        for _ in range(args.repeat):
            alone[args.only]()
        return
    ik_ideal, ik_general = inverse_exact(ideal, tip, axis), inverse_general(built, tip, axis)
    kernels: dict[str, Callable[[], object]] = {
        "ideal-ik": lambda: inverse_exact(ideal, tip, axis),
        "general-ik": lambda: inverse_general(built, tip, axis),
        "ideal-fk": lambda: forward(ideal, ik_ideal.strokes, ik_ideal.stage),
        "general-fk": lambda: forward_general(built, ik_general.strokes, ik_general.stage),
    }
    reached = ik_general.reachable.mean()
    print(f"N = {n:,} poses ({reached:.1%} reachable on the head as built), {args.repeat} runs each; before: {load()}")
    print(f"{'kernel':<11} {'M poses/s: median (min..max)':>30} {'against':<9} {'time ratio: median (min..max)':>32}")
    for general, reference in (("general-ik", "ideal-ik"), ("general-fk", "ideal-fk")):
        kernels[general](), kernels[reference]()       # warm up: page in, thread pool
        times: dict[str, list[float]] = {general: [], reference: []}
        for _ in range(args.repeat):                   # alternately, so that a load change hits both
            for name in (general, reference):
                times[name].append(timed(kernels[name])[0])
        ratios = [a / b for a, b in zip(times[general], times[reference], strict=True)]
        for name in (general, reference):
            rates = [n / t / 1e6 for t in times[name]]
            shown = spread(ratios, "6.2f") if name == general else ""
            print(f"{name:<11} {spread(rates, '6.2f'):>30} {reference if name == general else '':<9} {shown:>32}")
    print(f"after: {load()}")
    fk = forward_general(built, ik_general.strokes, ik_general.stage)
    ok = ik_general.reachable & fk.converged
    print(f"round trip: {ok.mean():.1%} of the poses, worst tip error {abs(fk.tip[ok] - tip[ok]).max():.2e} mm, "
          f"general IK Newton steps median {statistics.median(ik_general.iterations.tolist()):.0f} "
          f"max {ik_general.iterations.max()}, general FK steps median {statistics.median(fk.iterations.tolist()):.0f}")


if __name__ == "__main__":
    main()
