"""The vismach model of a 3-PRS machine for a LinuxCNC configuration (the next step: not written yet)."""

from __future__ import annotations

from typing import Any

__all__ = ["VISMACH_COMPONENT", "VISMACH_SCRIPT", "vismach_hal", "vismach_script"]

#: The model's HAL component (``loadusr -Wn``) and its script's name in the configuration's folder.
VISMACH_COMPONENT = "prs3-vismach"
VISMACH_SCRIPT = "prs3_vismach.py"


def vismach_hal(axes: Any, machine: Any) -> str:
    """The HAL file that starts the model (not written yet)."""
    raise NotImplementedError("the vismach model is not written yet")


def vismach_script(machine: Any, toml: str, tools: str) -> str:
    """The model's script (not written yet)."""
    raise NotImplementedError("the vismach model is not written yet")
