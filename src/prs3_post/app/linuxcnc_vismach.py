"""The vismach model of a 3-PRS machine, for a LinuxCNC configuration (`linuxcnc-config`).

vismach is LinuxCNC's 3D machine view: a Python script that LinuxCNC starts as a HAL component
(``loadusr``), with input pins for the joints, and that draws the machine with OpenGL. It runs under
the system Python LinuxCNC uses (Debian's ``/usr/bin/python3``, with its numpy and no scipy or
trimesh), not in prs3-post's environment. The script written here therefore holds no geometry: it
loads prs3-post's own package from where this configuration was written with (its folder is written
into the script) and the machine file copied beside it, and draws what
:func:`prs3_post.check.vismach_scene.vismach_scene` gives: the head placed by our forward
kinematics (:func:`prs3_post.check.machine_pose.machine_pose`), the stage moving the table.

The script's pins: ``stage-x``, ``stage-y`` (on a machine with a stage), one per head joint (``t1``,
``t2``, ``t3``), and ``tool-number`` (the tool in the spindle: its length and diameter from the tool
table, else the machine's own tool). ``prs3_vismach.py --pose T1 T2 T3 [X Y] [--tool N]`` prints the
scene as JSON without a display (what the tests compare with our FK).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

from prs3_post.core.errors import ConfigError
from prs3_post.core.version import __version__
from prs3_post.machine.model import DEFAULT_KINEMATICS, GENERAL_KINEMATICS, Machine

__all__ = ["VISMACH_COMPONENT", "VISMACH_HAL", "VISMACH_SCRIPT", "NoVismachModel", "check_drawable", "package_folder",
           "vismach_hal", "vismach_script"]

#: The model's HAL component (``loadusr -Wn``), its script's and its HAL file's names in the folder.
VISMACH_COMPONENT = "prs3-vismach"
VISMACH_SCRIPT = "prs3_vismach.py"
VISMACH_HAL = "vismach.hal"
#: The Python LinuxCNC's own Python programs (and vismach) run under.
SYSTEM_PYTHON = "/usr/bin/python3"


#: The kinematics the model draws (machine_pose's: the 3-PRS head, ideal or as built).
DRAWN_KINEMATICS = (DEFAULT_KINEMATICS, GENERAL_KINEMATICS)


class NoVismachModel(ConfigError, NotImplementedError):
    """The machine's kinematics has no vismach model (a configuration without one still runs)."""


def check_drawable(machine: Machine) -> None:
    """Raise :class:`NoVismachModel` unless the model can draw ``machine``'s kinematics."""
    if machine.kinematics not in DRAWN_KINEMATICS:
        raise NoVismachModel(f"kinematics: the vismach model draws a 3-PRS head ({', '.join(DRAWN_KINEMATICS)}), "
                             f"not {machine.kinematics!r}: leave it out (--no-vismach)", path=machine.source)


def package_folder() -> Path:
    """The folder of the prs3_post package this runs from (the script imports it from there)."""
    return Path(__file__).resolve().parents[1]


def one_line(text: str) -> str:
    """``text`` (a machine's name, description or file name) kept on one line of the configuration's files:
    control characters as blanks (a newline in a name would start a line, a section, a statement of its own)."""
    return re.sub(r"[\x00-\x1f\x7f]+", " ", text)


def vismach_hal(joints: Sequence[tuple[str, str]], machine: Machine) -> str:
    """The HAL file that starts the model and feeds it each joint's position and the tool in the spindle;
    ``joints``: (axis letter, the model's pin) of joint 0, 1, …"""
    out = [f"# The vismach model of {one_line(machine.name)}: a window showing the machine at the joints'",
           "# positions (it needs an X display). Rotate it with the mouse; its trail is the tool tip's path on the",
           "# table.",
           f"loadusr -Wn {VISMACH_COMPONENT} {SYSTEM_PYTHON} {VISMACH_SCRIPT}"]
    for index, (letter, pin) in enumerate(joints):
        out.append(f"net {letter.lower()}-pos-fb joint.{index}.pos-fb => {VISMACH_COMPONENT}.{pin}")
    out.append(f"net tool-in-spindle iocontrol.0.tool-number => {VISMACH_COMPONENT}.tool-number")
    return "\n".join(out) + "\n"


def vismach_script(machine: Machine, toml: str, tools: str, pins: tuple[str, ...]) -> str:
    """The model's script: ``toml`` and ``tools`` are the machine file's and the tool table's names in the
    configuration's folder, ``pins`` the head joints' pin names (``t1``, ``t2``, ``t3``)."""
    doc_name = one_line(machine.name).replace("\\", "/").replace('"', "'")   # in the docstring: not its end
    return _SCRIPT.format(name=machine.name, doc_name=doc_name, version=__version__, package=str(package_folder()),
                          toml=toml, tools=tools, pins=pins, stage=machine.stage.present, component=VISMACH_COMPONENT,
                          python=SYSTEM_PYTHON)


_SCRIPT = '''#!{python}
"""The vismach model of the 3-PRS machine {doc_name}, written by prs3-post {version} linuxcnc-config.

LinuxCNC starts it (vismach.hal) under its system Python. It draws the machine at the joints'
positions: the base, the rails with their sliders, the links, the platform, the spindle and the tool,
and the XY stage moving the table. The head is placed by prs3-post's own forward kinematics, from
the package the configuration was written with (PACKAGE below; write the configuration again when
prs3-post moves). Without a display:

    {python} prs3_vismach.py --pose T1 T2 T3 [X Y] [--tool N]

prints what it draws at that pose as JSON.
"""

import importlib.util
import json
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
PACKAGE = {package!r}
MACHINE = os.path.join(HERE, {toml!r})
TOOL_TABLE = os.path.join(HERE, {tools!r})
JOINT_PINS = {pins!r}
STAGE = {stage!r}
COMPONENT = {component!r}
NAME = {name!r}
#: Colours (red, green, blue, alpha) of the drawn parts.
COLOURS = {{
    "base": (0.55, 0.55, 0.6, 1), "rail": (0.75, 0.75, 0.8, 1), "slider": (0.2, 0.45, 0.85, 1),
    "link": (0.95, 0.6, 0.1, 1), "platform": (0.3, 0.7, 0.35, 1), "joint": (0.9, 0.9, 0.2, 1),
    "spindle": (0.4, 0.4, 0.45, 1), "spindle nose": (0.5, 0.5, 0.55, 1), "holder": (0.7, 0.7, 0.7, 1),
    "tool": (0.9, 0.15, 0.15, 1), "bed": (0.35, 0.35, 0.38, 1), "saddle": (0.55, 0.55, 0.5, 1),
    "table": (0.7, 0.65, 0.5, 1),
}}


def load_package():
    """prs3_post from PACKAGE (not through sys.path, so the system Python's own packages stay first)."""
    if "prs3_post" in sys.modules:
        return
    init = os.path.join(PACKAGE, "__init__.py")
    if not os.path.isfile(init):
        sys.exit("prs3_vismach.py: prs3-post's package is not at " + PACKAGE + " any more: write the "
                 "configuration again (prs3-post linuxcnc-config)")
    spec = importlib.util.spec_from_file_location("prs3_post", init, submodule_search_locations=[PACKAGE])
    module = importlib.util.module_from_spec(spec)
    sys.modules["prs3_post"] = module
    spec.loader.exec_module(module)


class Model:
    """The machine (the file beside this script) and the tool table's tools: the scene at a pose."""

    def __init__(self):
        load_package()
        from prs3_post.check.vismach_scene import vismach_scene
        from prs3_post.core.errors import Prs3Error
        from prs3_post.machine.loading import load_machine
        from prs3_post.readers.tooltable import read_tool_table

        self.machine = load_machine(MACHINE)
        try:
            self.tools = {{tool.number: tool for tool in read_tool_table(TOOL_TABLE).tools}}
        except Prs3Error as error:                       # an edited table: draw the machine's own tool
            print("prs3_vismach.py: " + str(error), file=sys.stderr)
            self.tools = {{}}
        self.vismach_scene = vismach_scene
        self.key = None
        self.last = None

    def scene(self, joints, stage, tool):
        """The scene at joints (T1, T2, T3) and stage (X, Y), mm, with tool number ``tool`` in the spindle."""
        import numpy as np

        key = (tuple(joints), tuple(stage), tool)
        if key != self.key:
            machine, diameter = self.machine, 6.0
            found = self.tools.get(tool)
            if found is not None:
                machine = machine.with_tool_length(machine.geometry.gauge_offset + found.length)
                diameter = max(found.diameter, 0.5)
            self.last = self.vismach_scene(machine, np.array(joints, dtype=float), np.array(stage, dtype=float),
                                           tool_diameter=diameter)
            self.key = key
        return self.last


def print_pose(args):
    """--pose T1 T2 T3 [X Y] [--tool N]: the scene as JSON on standard output."""
    tool = 0
    if "--tool" in args:
        at = args.index("--tool")
        tool = int(args[at + 1])
        args = args[:at] + args[at + 2:]
    values = [float(v) for v in args]
    joints, stage = values[:len(JOINT_PINS)], (values[len(JOINT_PINS):] + [0.0, 0.0])[:2]
    print(json.dumps(Model().scene(joints, stage, tool).as_dict()))


def show():
    """The vismach window, driven by the HAL pins."""
    import tkinter

    import hal
    import vismach
    from OpenGL import GL, GLU

    comp = hal.component(COMPONENT)
    for pin in (("stage-x", "stage-y") if STAGE else ()) + tuple(JOINT_PINS):
        comp.newpin(pin, hal.HAL_FLOAT, hal.HAL_IN)
    comp.newpin("tool-number", hal.HAL_S32, hal.HAL_IN)
    comp.ready()
    model = Model()

    class Hud(vismach.Hud):
        """vismach's text box; off where the X server lacks its bitmap font (a bare Xvfb has no 9x15)."""

        def draw(self):
            if not self.fontbase:
                try:
                    self.fontbase = int(self.app.loadbitmapfont("9x15"))
                except tkinter.TclError:
                    self.hide()
                    return
            vismach.Hud.draw(self)

    hud = Hud()
    quadric = GLU.gluNewQuadric()

    def current():
        stage = (comp["stage-x"], comp["stage-y"]) if STAGE else (0.0, 0.0)
        return model.scene([comp[pin] for pin in JOINT_PINS], stage, comp["tool-number"])

    def colour(kind):
        GL.glMaterialfv(GL.GL_FRONT_AND_BACK, GL.GL_AMBIENT_AND_DIFFUSE, COLOURS[kind])

    def cylinder(start, end, radius):
        d = [e - s for s, e in zip(start, end)]
        length = math.sqrt(sum(c * c for c in d))
        if length < 1e-9:
            return
        GL.glPushMatrix()
        GL.glTranslatef(*start)
        across = math.hypot(d[0], d[1])
        if across > 1e-12:                               # turn z onto the axis
            GL.glRotatef(math.degrees(math.atan2(across, d[2])), -d[1], d[0], 0)
        elif d[2] < 0:
            GL.glRotatef(180, 1, 0, 0)
        GLU.gluCylinder(quadric, radius, radius, length, 24, 1)
        GL.glRotatef(180, 1, 0, 0)
        GLU.gluDisk(quadric, 0, radius, 24, 1)
        GL.glRotatef(180, 1, 0, 0)
        GL.glTranslatef(0, 0, length)
        GLU.gluDisk(quadric, 0, radius, 24, 1)
        GL.glPopMatrix()

    def box(low, high):
        (x0, y0, z0), (x1, y1, z1) = low, high
        faces = (((0, 0, -1), ((x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0))),
                 ((0, 0, 1), ((x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1))),
                 ((0, -1, 0), ((x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1))),
                 ((0, 1, 0), ((x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0))),
                 ((-1, 0, 0), ((x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0))),
                 ((1, 0, 0), ((x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1))))
        GL.glBegin(GL.GL_QUADS)
        for normal, corners in faces:
            GL.glNormal3f(*normal)
            for corner in corners:
                GL.glVertex3f(*corner)
        GL.glEnd()

    def triangle(corners):
        a, b, c = corners
        u = [b[i] - a[i] for i in range(3)]
        v = [c[i] - a[i] for i in range(3)]
        n = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
        GL.glBegin(GL.GL_TRIANGLES)
        GL.glNormal3f(*n)
        for corner in (a, b, c):
            GL.glVertex3f(*corner)
        GL.glNormal3f(-n[0], -n[1], -n[2])
        for corner in (a, c, b):
            GL.glVertex3f(*corner)
        GL.glEnd()

    class Bodies:
        """Every part of the machine at the pins' pose."""

        def draw(self):
            scene = current()
            GL.glPushAttrib(GL.GL_LIGHTING_BIT)
            for ends, radius, kind in zip(scene.cylinders.tolist(), scene.radii.tolist(), scene.kinds):
                colour(kind)
                cylinder(ends[0], ends[1], radius)
            colour("joint")
            for x, y, z, radius in scene.spheres.tolist():
                GL.glPushMatrix()
                GL.glTranslatef(x, y, z)
                GLU.gluSphere(quadric, radius, 24, 12)
                GL.glPopMatrix()
            if scene.converged:
                colour("platform")
                triangle(scene.platform.tolist())
            for (low, high), kind in zip(scene.boxes.tolist(), scene.box_kinds):
                colour(kind)
                box(low, high)
            GL.glPopAttrib()
            names = ("X", "Y") + tuple(pin.upper() for pin in JOINT_PINS) if STAGE else tuple(
                pin.upper() for pin in JOINT_PINS)
            values = ((comp["stage-x"], comp["stage-y"]) if STAGE else ()) + tuple(comp[pin] for pin in JOINT_PINS)
            hud.strs = ["  ".join(name + " " + format(value, ".3f") for name, value in zip(names, values)),
                        "tool T" + str(comp["tool-number"]) + ("" if scene.converged else "   NO POSE: the joints "
                                                                "give no platform position")]

    class At(vismach.Collection):
        """Its parts moved to a point of the scene (the tool tip, the table top) at each draw."""

        def __init__(self, parts, where):
            vismach.Collection.__init__(self, parts)
            self.where = where

        def apply(self):
            GL.glPushMatrix()
            GL.glTranslatef(*self.where(current()).tolist())

        def unapply(self):
            GL.glPopMatrix()

    tooltip = vismach.Capture()
    work = vismach.Capture()
    first = current()
    top = max(first.cylinders[:, :, 2].max(), first.boxes[:, :, 2].max())
    bottom = min(first.cylinders[:, :, 2].min(), first.boxes[:, :, 2].min())
    model_parts = vismach.Collection([Bodies(), At([tooltip], lambda s: s.tip), At([work], lambda s: s.work)])
    # raised so that the view (which turns about the origin) centres on the machine
    centred = vismach.Translate([model_parts], 0, 0, -0.5 * (top + bottom))
    hud.show()

    base = tkinter.Tk

    class Window(base):
        """vismach's window, titled, and placed where PRS3_VISMACH_GEOMETRY says (Tk's WxH+X+Y), if set."""

        def __init__(self, *args, **kwargs):
            base.__init__(self, *args, **kwargs)
            self.title("prs3-post: " + NAME + " (vismach)")
            if os.environ.get("PRS3_VISMACH_GEOMETRY"):
                self.geometry(os.environ["PRS3_VISMACH_GEOMETRY"])

    tkinter.Tk = Window                                    # vismach.main makes its window with tkinter.Tk()
    vismach.main(centred, tooltip, work, size=0.85 * (top - bottom), hud=hud, lat=-62, lon=35)


if __name__ == "__main__":
    if sys.argv[1:2] == ["--pose"]:
        print_pose(sys.argv[2:])
    else:
        show()
'''
