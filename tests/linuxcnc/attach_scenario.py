"""A machine someone else started, and feedlog attaching to it (run by test_linuxcnc_attach.py).

Usage: python attach_scenario.py MACHINE.ini PROGRAM.ngc OUT.mcap RESULT.json [--machine-uses-integ]
Starts LinuxCNC headless with a plain operator (feedlog's driver without samplers: it homes, waits
until a recorder has opened its gate, runs the program and exits), attaches feedlog's recorder to the running HAL, and
writes attach_linuxcnc()'s summary or error to RESULT.json. Runs inside the test's namespaces.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from feedlog.errors import FeedlogError
from feedlog.ingest.linuxcnc_attach import attach_linuxcnc, loaded_components
from feedlog.ingest.linuxcnc_session import DRIVER_SOURCE, MachineIni


def main(ini_path: str, program: str, out: str, result: str, *options: str) -> int:
    work = Path(tempfile.mkdtemp(prefix="feedlog-operator-", dir="/var/tmp"))
    work.chmod(0o755)
    driver = work / "driver.py"
    shutil.copyfile(DRIVER_SOURCE, driver)
    driver.chmod(0o755)
    job = {"program": program, "channels": [], "sample_files": [], "result": str(work / "operator.json"),
           "enable_signal": None, "motion_time_pin": None, "timeout_s": 60,
           "start_when_signal": "feedlog-enable", "start_delay_s": 0.3}
    (work / "job.json").write_text(json.dumps(job))
    ini = MachineIni.read(ini_path)
    text = ini.rewritten(display=f"{driver} {work / 'job.json'}", recorder=None)
    if "--machine-uses-integ" in options:  # the machine's own HAL already loads integ: no clock for us
        (work / "own.hal").write_text("loadrt integ names=own-integ\naddf own-integ servo-thread\n")
        lines = text.splitlines()
        at = next(i for i, line in enumerate(lines) if "basic_sim.tcl" in line)
        text = "\n".join(lines[:at + 1] + [f"HALFILE = {work / 'own.hal'}"] + lines[at + 1:]) + "\n"
    (work / "machine.ini").write_text(text)
    (work / "feedlog.tbl").write_text("T1 P1 D6.0\n")
    fifo = work / "fifo"
    fifo.mkdir(mode=0o777)
    fifo.chmod(0o777)
    os.environ.update(HOME=str(work), RTAPI_FIFO_PATH=str(fifo / "rtapi_fifo"))
    if os.geteuid() == 0:
        os.environ["RTAPI_UID"] = "65534"
    log = open(work / "linuxcnc.log", "w")
    machine = subprocess.Popen(["linuxcnc", "-r", str(work / "machine.ini")], cwd=work, stdout=log,
                               stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    outcome: dict = {}
    try:
        deadline = time.monotonic() + 30
        while True:  # up when the operator (the display, started last) has joined the HAL
            try:
                if any(c.startswith("feedlog-driver-") for c in loaded_components()):
                    break
            except FeedlogError:
                pass
            if time.monotonic() > deadline or machine.poll() is not None:
                raise FeedlogError("the operator's LinuxCNC did not come up")
            time.sleep(0.2)
        outcome["summary"] = attach_linuxcnc(ini_path, out, program=program, timeout_s=60)
    except FeedlogError as exc:
        outcome["error"] = str(exc)
    finally:
        machine.wait(timeout=90)
        log.close()
        outcome["operator"] = json.loads((work / "operator.json").read_text()) \
            if (work / "operator.json").exists() else None
        outcome["linuxcnc_log"] = (work / "linuxcnc.log").read_text()[-2000:]
        Path(result).write_text(json.dumps(outcome))
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
