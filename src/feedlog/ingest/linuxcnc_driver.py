#!/usr/bin/python3
"""feedlog's LinuxCNC "display": runs one program headless while halsampler records it.

This file runs under Debian's /usr/bin/python3 (the only interpreter with the `linuxcnc` and `hal`
modules), started by LinuxCNC as `[DISPLAY] DISPLAY = driver.py JOB.json` (LinuxCNC passes
`-ini INIFILE` first) or by hand with `--attach JOB.json` next to a running LinuxCNC. It imports
nothing from feedlog: the job file says what to do, the result file says what happened.

Job (JSON): program, channels, sample_files, result, enable_signal, motion_time_pin,
timeout_s, attach (bool: don't home or run, record until the program ends or SIGINT/SIGTERM),
until_program_end (attach: stop when the program ends; else only on a signal), start_when_signal
and start_delay_s (wait for a HAL signal to come on, then this long, before AUTO_RUN; with no channels
the driver is a plain headless operator, used in tests), feed_override (set the feed dial before
AUTO_RUN), feed_override_at and rapid_override_at ([[seconds after AUTO_RUN, dial], ...]: turn the feed or the rapid
dial while the program runs), pause_at ([[seconds after AUTO_RUN, seconds], ...]: pause the program (a feed hold)
and resume it).
Result (JSON): ok, errors [{kind, text}], motion_time_s, overruns, ... written on every exit path.
"""

import json
import os
import signal
import subprocess
import sys
import time

import hal  # Debian's LinuxCNC python
import linuxcnc

POLL_S = 0.005
ERROR_KINDS = {linuxcnc.NML_ERROR: "error", linuxcnc.OPERATOR_ERROR: "error",
               linuxcnc.NML_TEXT: "text", linuxcnc.OPERATOR_TEXT: "text",
               linuxcnc.NML_DISPLAY: "display", linuxcnc.OPERATOR_DISPLAY: "display"}


class Abort(Exception):
    pass


class Driver:
    def __init__(self, job):
        self.job = job
        self.result = {"ok": False, "errors": [], "messages": [], "phase": "start",
                       "linuxcnc_version": str(getattr(linuxcnc, "version", ""))}
        self.samplers = []
        self.stop_requested = False
        self.stat = linuxcnc.stat()
        self.cmd = linuxcnc.command()
        self.err = linuxcnc.error_channel()
        self.deadline = time.monotonic() + float(job.get("timeout_s", 600))
        # hal.get_value needs this process to be a HAL component
        self.comp = hal.component(f"feedlog-driver-{os.getpid()}")
        self.comp.ready()

    # ---- helpers
    def poll_errors(self, fatal=True):
        while True:
            item = self.err.poll()
            if not item:
                return
            kind, text = item
            self.stat.poll()  # the line numbers as of the error
            entry = {"kind": ERROR_KINDS.get(kind, str(kind)), "text": str(text).strip(),
                     "motion_line": int(getattr(self.stat, "motion_line", 0) or 0),
                     "current_line": int(getattr(self.stat, "current_line", 0) or 0),
                     "read_line": int(getattr(self.stat, "read_line", 0) or 0)}
            if entry["kind"] == "error":
                self.result["errors"].append(entry)
                if fatal:
                    raise Abort(entry["text"])
            else:
                self.result["messages"].append(entry)

    def check_stop(self):
        stop_file = self.job.get("stop_file")
        if stop_file and os.path.exists(stop_file):
            self.stop_requested = True
        return self.stop_requested

    def abort_if_stopped(self, when):
        """Abort the run if a stop was requested; `when` says where ("before ...", "while waiting for ...")."""
        if self.check_stop():
            self.result["stopped"] = True
            raise Abort(f"stopped on request {when}")

    def wait(self, what, predicate, timeout_s):
        end = min(time.monotonic() + timeout_s, self.deadline)
        while True:
            self.stat.poll()
            self.poll_errors()
            if predicate(self.stat):
                return
            self.abort_if_stopped(f"while waiting for {what}")
            if time.monotonic() > end:
                raise Abort(f"timed out waiting for {what}")
            time.sleep(POLL_S)

    def halcmd(self, *args):
        out = subprocess.run(["halcmd", *args], capture_output=True, text=True, timeout=10)
        if out.returncode != 0:
            raise Abort(f"halcmd {' '.join(args)} failed: {out.stderr.strip() or out.stdout.strip()}")
        return out.stdout.strip()

    def value(self, name):
        return hal.get_value(name)

    # ---- phases
    def start_samplers(self):
        for channel, path in zip(self.job["channels"], self.job["sample_files"]):
            f = open(path, "w")
            proc = subprocess.Popen(["halsampler", "-t", "-c", str(channel)], stdout=f,
                                    stderr=subprocess.PIPE)
            self.samplers.append((channel, proc, f))

    def stop_samplers(self):
        if self.job.get("enable_signal"):
            try:
                self.halcmd("sets", self.job["enable_signal"], "0")
            except Exception as exc:  # keep going: the data recorded so far must reach disk
                self.result["messages"].append({"kind": "text", "text": f"disable failed: {exc}"})
        end = time.monotonic() + 5.0
        for channel, _, _ in self.samplers:
            while time.monotonic() < end:
                try:
                    if int(self.value(f"sampler.{channel}.curr-depth")) == 0:
                        break
                except Exception:
                    break
                time.sleep(0.01)
        time.sleep(0.2)
        overruns = 0
        for channel, proc, f in self.samplers:
            try:
                overruns += int(self.value(f"sampler.{channel}.overruns"))
            except Exception:
                pass
            proc.send_signal(signal.SIGINT)
            try:
                _, err = proc.communicate(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
                _, err = proc.communicate()
            f.close()
            text = err.decode(errors="replace").strip() if err else ""
            if text:
                self.result["messages"].append({"kind": "text", "text": f"halsampler {channel}: {text}"})
        self.result["overruns"] = overruns
        self.samplers = []

    def wait_for_signal(self, name):
        end = min(time.monotonic() + 60, self.deadline)
        while time.monotonic() < end and not self.check_stop():
            try:
                if self.value(name):
                    return
            except Exception:  # the signal does not exist yet
                pass
            time.sleep(0.05)
        raise Abort(f"signal {name} did not come on")

    def motion_time(self):
        pin = self.job.get("motion_time_pin")
        return float(self.value(pin)) if pin else float("nan")

    def prepare_machine(self):
        self.result["phase"] = "startup"
        self.wait("task to come up", lambda s: True, 30)
        self.cmd.state(linuxcnc.STATE_ESTOP_RESET)
        self.wait("estop reset", lambda s: s.task_state == linuxcnc.STATE_ESTOP_RESET, 10)
        self.cmd.state(linuxcnc.STATE_ON)
        self.wait("machine on", lambda s: s.task_state == linuxcnc.STATE_ON, 10)
        self.cmd.mode(linuxcnc.MODE_MANUAL)
        self.wait("manual mode", lambda s: s.task_mode == linuxcnc.MODE_MANUAL, 10)
        self.cmd.teleop_enable(False)
        self.cmd.home(-1)
        self.wait("homing", lambda s: all(s.homed[j] for j in range(s.joints)), 30)
        self.cmd.teleop_enable(True)
        self.cmd.mode(linuxcnc.MODE_AUTO)
        self.wait("auto mode", lambda s: s.task_mode == linuxcnc.MODE_AUTO, 10)

    def run_program(self):
        self.result["phase"] = "open"
        self.cmd.program_open(self.job["program"])
        self.wait("program open", lambda s: s.file != "", 10)
        self.poll_errors()
        self.result["phase"] = "run"
        if self.job["channels"]:
            self.abort_if_stopped("before recording")
            self.start_samplers()
            time.sleep(0.3)  # halsampler attached before the gate opens
            self.halcmd("sets", self.job["enable_signal"], "1")
            time.sleep(0.05)
        if self.job.get("start_when_signal"):  # operator mode: run once a recorder has opened its gate
            self.wait_for_signal(self.job["start_when_signal"])
        time.sleep(float(self.job.get("start_delay_s", 0.0)))
        if self.job.get("feed_override") is not None:  # the operator's feed dial
            scale = float(self.job["feed_override"])
            self.cmd.feedrate(scale)
            self.wait("feed override", lambda s: abs(s.feedrate - scale) < 1e-9, 5)
            self.result["feed_override"] = scale
        self.result["program_file"] = self.stat.file
        self.result["motion_time_start_s"] = self.motion_time()
        self.result["run_wall_start"] = time.time()
        self.abort_if_stopped("before the program started")
        self.cmd.auto(linuxcnc.AUTO_RUN, 0)
        try:  # a program without motion may be over before the first poll sees it run
            self.wait("program start", lambda s: s.interp_state != linuxcnc.INTERP_IDLE or s.queue > 0, 1.0)
        except Abort as exc:
            if self.result["errors"] or self.stop_requested:
                raise
            self.result["messages"].append({"kind": "text", "text": f"program start not seen: {exc}"})
        self.wait_done()

    def turn_dials(self):
        """The operator turning a dial mid-program: each [after_s, scale] of `feed_override_at` (the feed
        dial) and `rapid_override_at` (the rapid dial) once its time since AUTO_RUN has come (polled with
        the program's end)."""
        for plan_key, turns_key, turn in (("feed_override_at", "feed_override_turns", self.cmd.feedrate),
                                          ("rapid_override_at", "rapid_override_turns", self.cmd.rapidrate)):
            plan = self.job.get(plan_key) or []
            turns = self.result.setdefault(turns_key, []) if plan else []
            if len(turns) < len(plan) and time.time() - self.result["run_wall_start"] >= float(plan[len(turns)][0]):
                scale = float(plan[len(turns)][1])
                turn(scale)
                turns.append({"after_s": float(plan[len(turns)][0]), "scale": scale,
                              "motion_time_s": self.motion_time()})

    def hold_feed(self):
        """The operator pausing the program mid-run (a feed hold): each [after_s, duration_s] of `pause_at`
        pauses it once its time since AUTO_RUN has come and resumes it duration_s later."""
        holds = self.result.setdefault("feed_holds", [])
        plan = self.job.get("pause_at") or []
        now = time.time() - self.result["run_wall_start"]
        if holds and "resumed_motion_time_s" not in holds[-1]:
            if now >= holds[-1]["after_s"] + holds[-1]["duration_s"]:
                self.cmd.auto(linuxcnc.AUTO_RESUME)
                holds[-1]["resumed_motion_time_s"] = self.motion_time()
        elif len(holds) < len(plan) and now >= float(plan[len(holds)][0]):
            self.cmd.auto(linuxcnc.AUTO_PAUSE)
            holds.append({"after_s": float(plan[len(holds)][0]), "duration_s": float(plan[len(holds)][1]),
                          "motion_time_s": self.motion_time()})

    def wait_done(self):
        def done(s):
            if self.job.get("feed_override_at") or self.job.get("rapid_override_at"):
                self.turn_dials()
            if self.job.get("pause_at"):
                self.hold_feed()
            return (s.interp_state == linuxcnc.INTERP_IDLE and s.queue == 0 and s.inpos
                    and s.exec_state == linuxcnc.EXEC_DONE)
        try:
            self.wait("program end", done, self.deadline - time.monotonic())
        except Abort as exc:  # say which end condition LinuxCNC left unset
            if self.result["errors"] or self.stop_requested:
                raise
            s = self.stat
            raise Abort(f"{exc} (interp_state {s.interp_state}, idle is {linuxcnc.INTERP_IDLE}; queue {s.queue}; "
                        f"inpos {s.inpos}; exec_state {s.exec_state}, done is {linuxcnc.EXEC_DONE}; "
                        f"motion_line {s.motion_line})") from None
        s = self.stat  # as polled when the end was seen (what the tests and docs check)
        self.result["end_state"] = {"interp_state": s.interp_state, "queue": s.queue, "inpos": bool(s.inpos),
                                    "exec_state": s.exec_state, "state": s.state, "motion_line": s.motion_line,
                                    "current_line": s.current_line, "queue_full": bool(s.queue_full)}
        time.sleep(0.05)  # a few servo periods of standstill after the last move
        self.result["motion_time_end_s"] = self.motion_time()
        self.result["run_wall_end"] = time.time()

    def attach(self):
        """Record a running LinuxCNC: from now until its program ends (or we are stopped)."""
        self.result["phase"] = "attach"
        self.start_samplers()
        time.sleep(0.3)
        self.halcmd("sets", self.job["enable_signal"], "1")
        self.result["motion_time_start_s"] = self.motion_time()
        self.result["run_wall_start"] = time.time()
        seen_running = False
        while not self.check_stop() and time.monotonic() < self.deadline:
            self.stat.poll()
            if self.stat.file:
                self.result["program_file"] = self.stat.file
            self.poll_errors(fatal=False)
            running = self.stat.interp_state != linuxcnc.INTERP_IDLE or self.stat.queue > 0
            seen_running = seen_running or running
            if seen_running and not running and self.stat.inpos and self.job.get("until_program_end", True):
                break
            time.sleep(0.02)
        self.result["stopped"] = self.stop_requested
        time.sleep(0.05)
        self.result["motion_time_end_s"] = self.motion_time()
        self.result["run_wall_end"] = time.time()

    def finish(self):
        if self.result.get("stopped") and not self.job.get("attach"):
            try:
                self.cmd.abort()  # stop the machine where it is
                time.sleep(0.1)
            except Exception:
                pass
        if self.samplers:
            self.stop_samplers()
        if not self.job.get("attach"):
            try:
                self.cmd.state(linuxcnc.STATE_ESTOP)
            except Exception:
                pass
        with open(self.job["result"] + ".part", "w") as f:
            json.dump(self.result, f)
        os.replace(self.job["result"] + ".part", self.job["result"])


def main(argv):
    args = [a for a in argv if a != "--attach"]
    if "-ini" in args:
        i = args.index("-ini")
        del args[i:i + 2]
    if len(args) != 1:
        print("usage: linuxcnc_driver.py [-ini INI] [--attach] JOB.json", file=sys.stderr)
        return 2
    with open(args[0]) as f:
        job = json.load(f)
    job["attach"] = job.get("attach") or "--attach" in argv
    driver = Driver(job)

    def on_signal(signum, frame):
        driver.stop_requested = True
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        if job["attach"]:
            driver.attach()
        else:
            driver.prepare_machine()
            driver.run_program()
        driver.result["ok"] = not driver.result["errors"]
    except Abort as exc:
        driver.result["abort"] = str(exc)
    except Exception as exc:  # report anything to the recorder rather than dying silently
        driver.result["abort"] = f"{type(exc).__name__}: {exc}"
    finally:
        try:
            driver.poll_errors(fatal=False)
        except Exception:
            pass
        driver.finish()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
