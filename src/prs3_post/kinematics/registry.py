"""The kinematics a machine file may name, by name: ``kinematics = "3-prs"`` → a :class:`Kinematics`.

:func:`register` adds one (a factory from the machine's geometry) and tells the machine loader the
name (:data:`prs3_post.machine.model.KINEMATICS_NAMES`: the loader, a layer below, cannot import
this module); :func:`kinematics_of` gives a loaded machine's.
"""

from __future__ import annotations

from collections.abc import Callable

from prs3_post.kinematics.protocol import Kinematics
from prs3_post.kinematics.prs3.kinematics import Prs3Kinematics
from prs3_post.kinematics.prs3_general.kinematics import GENERAL_KINEMATICS, Prs3GeneralKinematics
from prs3_post.machine.model import KINEMATICS_NAMES, Geometry, Machine

__all__ = ["Kinematics", "as_kinematics", "kinematics_of", "register", "unregister"]

_FACTORIES: dict[str, Callable[[Geometry], Kinematics]] = {}


def register(name: str, factory: Callable[[Geometry], Kinematics]) -> None:
    """Let machine files name ``name``: its kinematics are ``factory(machine.geometry)``."""
    _FACTORIES[name] = factory
    KINEMATICS_NAMES.add(name)


def unregister(name: str) -> None:
    """Forget ``name`` (a test's toy kinematics)."""
    _FACTORIES.pop(name, None)
    KINEMATICS_NAMES.discard(name)


def kinematics_of(machine: Machine) -> Kinematics:
    """The kinematics ``machine`` names, built from its geometry (with the tool it was given)."""
    return _FACTORIES[machine.kinematics](machine.geometry)



def as_kinematics(given: Geometry | Kinematics) -> Kinematics:
    """``given``, or the 3-PRS head of a bare :class:`Geometry` (the callers that predate the protocol)."""
    return Prs3Kinematics(given) if isinstance(given, Geometry) else given


register("3-prs", Prs3Kinematics)
register(GENERAL_KINEMATICS, Prs3GeneralKinematics)   # each leg as built: [[legs]] in the machine file
