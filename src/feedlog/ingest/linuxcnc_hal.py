"""The recorder's HAL side: which LinuxCNC pins feed which sampler columns, and the haltcl file.

One `sampler` component takes at most ~20 pins, so the columns are spread over several samplers.
Every sampler's first column is a shared clock (an `integ` with `in = 1` on servo-thread, in
seconds), which joins the samplers row by row and shows any missing servo period. All samplers are
gated by one signal (`feedlog-enable`) that the driver sets just before it starts the program.

The same haltcl file serves a LinuxCNC we start (it is a `[HAL] HALFILE`) and one that is already
running (`haltcl record.tcl` loads it into the live HAL); see docs/linuxcnc.md.
"""

from __future__ import annotations

from dataclasses import dataclass

ENABLE_SIGNAL = "feedlog-enable"
CLOCK_COMPONENT = "feedlog-clock"
MOTION_TIME_COMPONENT = "feedlog-motion-time"
MAX_PINS_PER_SAMPLER = 16
# HAL pin type -> sampler cfg letter
_CFG_LETTER = {"float": "f", "bit": "b", "s32": "s", "u32": "u"}
ROTARY_LETTERS = "abc"


@dataclass(frozen=True)
class Column:
    """One recorded HAL pin: its column name in the capture and its HAL type."""

    name: str
    pin: str
    hal_type: str

    def __post_init__(self) -> None:
        if self.hal_type not in _CFG_LETTER:
            raise ValueError(f"column {self.name!r}: unknown HAL type {self.hal_type!r}; "
                             f"known: {', '.join(_CFG_LETTER)}")


@dataclass(frozen=True)
class SamplerLayout:
    """Columns grouped per sampler; column 0 of every sampler is the shared clock `clock_s`.

    `clock=False` (attaching to a HAL that already uses `integ`) leaves the clock out: time then
    comes from halsampler's sample tag, which every gated sampler advances in step.
    """

    groups: tuple[tuple[Column, ...], ...]
    depth: int = 16384
    first_channel: int = 0
    clock: bool = True

    def __post_init__(self) -> None:
        if not self.groups:
            raise ValueError("sampler layout needs at least one group of columns")
        for k, group in enumerate(self.groups):
            if len(group) + int(self.clock) > MAX_PINS_PER_SAMPLER:
                raise ValueError(f"sampler {k} has {len(group) + 1} pins; at most {MAX_PINS_PER_SAMPLER}")
        if self.depth < 1024:
            raise ValueError(f"sampler depth {self.depth} too small (>= 1024 samples)")

    @property
    def channels(self) -> list[int]:
        return [self.first_channel + k for k in range(len(self.groups))]

    def column_names(self, k: int) -> list[str]:
        """Names of the fields halsampler -t prints for sampler group k (tag, clock, columns)."""
        return ["sample"] + (["clock_s"] if self.clock else []) + [c.name for c in self.groups[k]]

    @property
    def cfgs(self) -> list[str]:
        lead = "f" if self.clock else ""
        return [lead + "".join(_CFG_LETTER[c.hal_type] for c in group) for group in self.groups]


def standard_layout(coordinates: str, joints: int, *, depth: int = 16384, first_channel: int = 0,
                    clock: bool = True) -> SamplerLayout:
    """Planner axes, motion status and feeds in one sampler, joint command/feedback in the next.

    `coordinates` is the INI's [TRAJ] COORDINATES (e.g. "XYZ", "XYZAC"); `joints` its [KINS] JOINTS.
    """
    letters = [c for c in coordinates.lower() if c.isalpha()]
    seen: list[str] = []
    for letter in letters:
        if letter not in seen:
            seen.append(letter)
    motion = [Column(f"{a}_{'deg' if a in ROTARY_LETTERS else 'mm'}", f"axis.{a}.pos-cmd", "float") for a in seen]
    motion += [
        Column("current_vel", "motion.current-vel", "float"),
        Column("requested_vel", "motion.requested-vel", "float"),
        Column("feed_upm", "motion.feed-upm", "float"),
        Column("distance_to_go", "motion.distance-to-go", "float"),
        Column("line", "motion.program-line", "s32"),
        Column("motion_type", "motion.motion-type", "s32"),
        Column("in_position", "motion.in-position", "bit"),
        Column("last_period", "motion.servo.last-period", "u32"),
    ]
    joint_cols: list[Column] = []
    for j in range(joints):
        joint_cols.append(Column(f"j{j}_pos", f"joint.{j}.pos-cmd", "float"))
        joint_cols.append(Column(f"j{j}_pos_fb", f"joint.{j}.pos-fb", "float"))
    per = MAX_PINS_PER_SAMPLER - 1  # one pin of each sampler is the clock
    groups = [tuple(cols[i:i + per]) for cols in (motion, joint_cols) for i in range(0, len(cols), per)]
    return SamplerLayout(groups=tuple(groups), depth=depth, first_channel=first_channel, clock=clock)


def recorder_tcl(layout: SamplerLayout, *, thread: str = "servo-thread") -> str:
    """The haltcl text that loads the samplers (and, with `layout.clock`, the clock and the
    motion-time integrator).

    A pin that basic_sim (or the machine's own HAL) already nets keeps its signal: the sampler input
    joins that signal instead of a new one.
    """
    depths = ",".join(str(layout.depth) for _ in layout.groups)
    lines = [
        "# feedlog LinuxCNC recorder (generated by feedlog.ingest.linuxcnc_hal; do not edit)",
        "proc feedlog_link {pin target} {",
        "  set ans [hal show pin $pin]",
        "  set sig \"\"; set sep \"\"",
        "  scan [lindex [split $ans \\n] 2] \"%s %s %s %s %s %s %s\" owner type dir val name sep sig",
        "  if {$sig eq \"\" || ($sep ne \"==>\" && $sep ne \"<==\" && $sep ne \"<=>\")} {",
        "    set sig \"feedlog:$pin\"",
        "    net $sig $pin",
        "  }",
        "  net $sig $target",
        "}",
        f"loadrt sampler depth={depths} cfg={','.join(layout.cfgs)}",
    ]
    # gate closed before any sampler runs: in a running HAL an ungated sampler would fill its FIFO
    # at once (sampler.N.enable defaults to 1, and a new signal takes its first reader's value)
    lines += [f"net {ENABLE_SIGNAL} sampler.{c}.enable" for c in layout.channels]
    lines.append(f"sets {ENABLE_SIGNAL} 0")
    if layout.clock:
        lines += [
            f"loadrt integ names={CLOCK_COMPONENT},{MOTION_TIME_COMPONENT}",
            "loadrt not names=feedlog-moving",
            "loadrt conv_bit_float names=feedlog-moving-f",
            f"setp {CLOCK_COMPONENT}.in 1.0",
            f"addf {CLOCK_COMPONENT} {thread}",
            f"addf feedlog-moving {thread}",
            f"addf feedlog-moving-f {thread}",
            f"addf {MOTION_TIME_COMPONENT} {thread}",
            # LinuxCNC's own motion time: servo periods with in-position false, integrated in HAL
            "feedlog_link motion.in-position feedlog-moving.in",
            "net feedlog:moving feedlog-moving.out feedlog-moving-f.in",
            f"net feedlog:moving-f feedlog-moving-f.out {MOTION_TIME_COMPONENT}.in",
        ]
    first = int(layout.clock)
    for k, (channel, group) in enumerate(zip(layout.channels, layout.groups)):
        lines.append(f"addf sampler.{channel} {thread}")
        if layout.clock:
            lines.append(f"net feedlog:clock sampler.{channel}.pin.0" if k else
                         f"net feedlog:clock {CLOCK_COMPONENT}.out sampler.{channel}.pin.0")
        for i, column in enumerate(group, start=first):
            lines.append(f"feedlog_link {column.pin} sampler.{channel}.pin.{i}")
    return "\n".join(lines) + "\n"


def unload_tcl(layout: SamplerLayout, *, thread: str = "servo-thread") -> str:
    """haltcl that takes the recorder out of a running HAL again (after an attached recording)."""
    lines = [f"delf sampler.{c} {thread}" for c in layout.channels]
    if layout.clock:
        lines += [f"delf {name} {thread}" for name in
                  (CLOCK_COMPONENT, "feedlog-moving", "feedlog-moving-f", MOTION_TIME_COMPONENT)]
        lines += ["unload integ", "unload not", "unload conv_bit_float"]
    lines.append("unload sampler")
    return "\n".join(lines) + "\n"
