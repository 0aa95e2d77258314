"""G and M codes: their modal groups, and which of them feedlog executes, refuses or only records.

G codes are kept x10 (G90.1 -> 901), as LinuxCNC does. A code a program may use but whose motion
cannot be known from the program alone (probing, spindle-synchronised threading, lathe cycles) is
refused with its line; codes that change nothing a motion simulation needs (coolant, spindle
direction, overrides, I/O) are recorded on their block and otherwise ignored.
"""

from __future__ import annotations

# group names follow LinuxCNC's modal groups
G_GROUP: dict[int, str] = {}
for _codes, _group in (
        ((40, 100, 280, 281, 300, 301, 520, 530, 920, 921, 922, 923, 53), "nonmodal"),
        ((0, 10, 20, 30, 330, 331, 382, 383, 384, 385, 730, 740, 760, 800, 810, 820, 830, 840, 850, 860, 870,
          880, 890, 50, 51, 52, 700, 710, 711, 712, 720, 721, 722), "motion"),
        ((170, 180, 190, 171, 181, 191), "plane"),
        ((900, 910), "distance"),
        ((901, 911), "ijk"),
        ((930, 940, 950), "feed_mode"),
        ((200, 210), "units"),
        ((400, 410, 411, 420, 421), "comp"),
        ((430, 431, 432, 490), "tool_length"),
        ((980, 990), "retract"),
        ((540, 550, 560, 570, 580, 590, 591, 592, 593), "coords"),
        ((610, 611, 640), "control"),
        ((960, 970), "spindle_mode"),
        ((70, 80), "lathe")):
    for _c in _codes:
        G_GROUP[_c] = _group

M_GROUP: dict[int, str] = {0: "stop", 1: "stop", 2: "stop", 30: "stop", 60: "stop",
                           6: "toolchange", 61: "toolchange",
                           3: "spindle", 4: "spindle", 5: "spindle", 19: "spindle",
                           7: "coolant", 8: "coolant", 9: "coolant",
                           48: "override", 49: "override", 50: "override", 51: "override", 52: "override",
                           53: "override",
                           62: "io", 63: "io", 64: "io", 65: "io", 66: "io", 67: "io", 68: "io",
                           70: "state", 71: "state", 72: "state", 73: "state"}
for _m in range(100, 200):
    M_GROUP[_m] = "user"

CYCLES = frozenset((730, 810, 820, 830, 840, 850, 860, 870, 880, 890, 740))
# recognised, but their motion is not known from the program alone (or not a mill's)
REFUSED_G = {
    330: "G33 spindle-synchronised motion (threading) depends on the spindle, not the program",
    331: "G33.1 rigid tapping is synchronised to the spindle, not simulated from the program",
    760: "G76 threading cycle is spindle-synchronised, not simulated from the program",
    382: "probing (G38.2) ends where the probe trips: the motion is not known from the program",
    383: "probing (G38.3) ends where the probe trips: the motion is not known from the program",
    384: "probing (G38.4) ends where the probe trips: the motion is not known from the program",
    385: "probing (G38.5) ends where the probe trips: the motion is not known from the program",
    700: "G70 is a lathe cycle (feedlog reads mill programs)", 710: "G71 is a lathe cycle",
    711: "G71.1 is a lathe cycle", 712: "G71.2 is a lathe cycle", 720: "G72 is a lathe cycle",
    721: "G72.1 is a lathe cycle", 722: "G72.2 is a lathe cycle",
    70: "G7 lathe diameter mode (feedlog reads mill programs)", 80: "G8 lathe radius mode",
    950: "G95 feed per revolution depends on the spindle speed; not simulated",
    171: "planes G17.1/G18.1/G19.1 (UVW) are not supported", 181: "planes G17.1/G18.1/G19.1 are not supported",
    191: "planes G17.1/G18.1/G19.1 are not supported",
}


def g_name(code: int) -> str:
    return f"G{code // 10}" if code % 10 == 0 else f"G{code // 10}.{code % 10}"
