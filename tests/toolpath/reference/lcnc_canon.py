"""Runs LinuxCNC's own RS274/NGC interpreter (its `gcode` Python module, the one AXIS previews with:
the same interpreter library as `rs274`, but with every canonical call in full double precision and the
line it came from) on one program and prints its canonical calls as JSON lines.

Run with Debian's /usr/bin/python3 (where linuxcnc-uspace installs `gcode`):
    python3 lcnc_canon.py PROGRAM TOOL_TABLE [VAR_FILE] [SUBROUTINE_PATH]
Lengths are printed in mm (the module reports inches), angles in degrees. The tool table and the
parameter file are given in mm and converted to the module's inch machine units. Last line:
{"result": code, "line": n, "message": "..."}.
"""

import json
import os
import sys
import tempfile

import gcode

MM = 25.4


def tool_table(path):
    tools = {}
    for raw in open(path):
        code = raw.split(";", 1)[0].split()
        if not code:
            continue
        w = {t[0].upper(): float(t[1:]) for t in code}
        tools[int(w.get("P", w["T"]))] = w
    return tools


def var_file(path, out_dir):
    """The parameter file with its lengths in inches (the module's machine units)."""
    lengths = set()
    for base in [5160, 5180] + [5200 + 20 * s for s in range(1, 10)]:
        lengths |= {base + 1, base + 2, base + 3, base + 7, base + 8, base + 9}
    lengths |= {5211, 5212, 5213, 5217, 5218, 5219}
    lines = []
    for raw in open(path):
        parts = raw.split()
        if len(parts) == 2:
            i, v = int(parts[0]), float(parts[1])
            lines.append(f"{i}\t{v / MM if i in lengths else v!r}")
    out = os.path.join(out_dir, "ref.var")
    with open(out, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    return out


class Canon:
    def __init__(self, tools, var):
        self.tools = tools
        self.parameter_file = var
        self.line = 0
        self.plane = 1
        self.feed = 0.0
        self.g5x = [0.0] * 6
        self.g92 = [0.0] * 6
        self.rot = 0.0
        self.tool = [0.0] * 6
        self.out = []

    def next_line(self, state):
        self.line = state.sequence_number

    def set_plane(self, plane):
        self.plane = plane

    def set_feed_rate(self, rate):
        self.feed = rate * MM

    def set_g5x_offset(self, index, x, y, z, a, b, c, *uvw):
        self.g5x = [x * MM, y * MM, z * MM, a, b, c]

    def set_g92_offset(self, x, y, z, a, b, c, *uvw):
        self.g92 = [x * MM, y * MM, z * MM, a, b, c]

    def set_xy_rotation(self, theta):
        self.rot = theta

    def tool_offset(self, x, y, z, a, b, c, *uvw):
        self.tool = [x * MM, y * MM, z * MM, a, b, c]

    def _move(self, kind, end, **extra):
        self.out.append(dict(kind=kind, line=self.line, end=end, feed=self.feed, g5x=self.g5x, g92=self.g92,
                             rot=self.rot, tool=self.tool, **extra))

    def straight_traverse(self, x, y, z, a, b, c, *uvw):
        self._move("rapid", [x * MM, y * MM, z * MM, a, b, c])

    def straight_feed(self, x, y, z, a, b, c, *uvw):
        self._move("linear", [x * MM, y * MM, z * MM, a, b, c])

    def arc_feed(self, first_end, second_end, first_axis, second_axis, rotation, axis_end, a, b, c, *uvw):
        uvw_index = {1: (0, 1, 2), 2: (1, 2, 0), 3: (2, 0, 1)}[self.plane]
        end = [0.0] * 6
        centre = [None] * 3
        u, v, w = uvw_index
        end[u], end[v], end[w] = first_end * MM, second_end * MM, axis_end * MM
        end[3:] = [a, b, c]
        centre[u], centre[v] = first_axis * MM, second_axis * MM
        self._move("arc", end, centre=centre, rotation=rotation, plane=self.plane)

    def straight_probe(self, x, y, z, a, b, c, *uvw):
        self._move("probe", [x * MM, y * MM, z * MM, a, b, c])

    def rigid_tap(self, x, y, z, *rest):
        self._move("rigid_tap", [x * MM, y * MM, z * MM, 0, 0, 0])

    def dwell(self, seconds):
        self.out.append(dict(kind="dwell", line=self.line, seconds=seconds))

    def get_tool(self, pocket):
        w = self.tools.get(pocket)
        if w is None or pocket == 0:
            return (-1,) + (0.0,) * 12 + (0,)
        return (int(w["T"]), w.get("X", 0) / MM, w.get("Y", 0) / MM, w.get("Z", 0) / MM, w.get("A", 0),
                w.get("B", 0), w.get("C", 0), 0.0, 0.0, 0.0, w.get("D", 0) / MM, 0.0, 0.0, 0)

    def get_external_angular_units(self):
        return 1.0

    def get_external_length_units(self):
        return 1.0 / MM

    def get_axis_mask(self):
        return 0x3F

    def get_block_delete(self):
        return 0

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return lambda *args: None


def main():
    program, tbl = sys.argv[1], sys.argv[2]
    var = sys.argv[3] if len(sys.argv) > 3 and sys.argv[3] else ""
    subs = sys.argv[4] if len(sys.argv) > 4 else ""
    with tempfile.TemporaryDirectory() as tmp:
        ref_var = var_file(var, tmp) if var else os.path.join(tmp, "empty.var")
        if not var:
            open(ref_var, "w").close()
        ini = os.path.join(tmp, "ref.ini")
        with open(ini, "w") as fh:
            fh.write(f"[RS274NGC]\nPARAMETER_FILE = {ref_var}\n")
            if subs:
                fh.write(f"SUBROUTINE_PATH = {subs}\n")
        os.environ["INI_FILE_NAME"] = ini
        canon = Canon(tool_table(tbl), ref_var)
        result, line = gcode.parse(program, canon, "G21", "")
        message = gcode.strerror(result) if result > gcode.MIN_ERROR else ""
    for move in canon.out:
        print(json.dumps(move))
    print(json.dumps({"result": result, "line": line, "message": message, "error": result > gcode.MIN_ERROR}))


main()
