"""Record a LinuxCNC that is already running (a real machine, or a sim someone else started).

`attach_linuxcnc()` loads feedlog's recorder into the live HAL (`haltcl record.tcl`), runs the driver
in attach mode (it does not home or start anything: it records from now until the running program
ends, or until SIGINT/SIGTERM/timeout), takes the recorder out of the HAL again and writes the
recording. It must run where `halcmd` reaches that LinuxCNC: same host and, when LinuxCNC runs as
root, the same `RTAPI_UID` / `RTAPI_FIFO_PATH` environment. docs/linuxcnc.md shows the manual steps.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from feedlog.errors import IngestError
from feedlog.ingest.linuxcnc import finish, keep_captures_on_failure, profile_toml_for, write_session
from feedlog.ingest.linuxcnc_capture import has_samples, load_capture
from feedlog.ingest.linuxcnc_hal import ENABLE_SIGNAL, MOTION_TIME_COMPONENT, recorder_tcl, standard_layout, \
    unload_tcl
from feedlog.ingest.linuxcnc_session import DEBIAN_PYTHON, DRIVER_SOURCE, MachineIni, linuxcnc_available, \
    session_error, wait_with_stop

# components the recorder loads; if the machine's HAL already has one, the recorder cannot load it again
CLOCK_MODULES = ("integ", "not", "conv_bit_float")


def _halcmd(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    out = subprocess.run(["halcmd", *args], capture_output=True, text=True, timeout=20)
    if check and out.returncode != 0:
        raise IngestError(f"halcmd {' '.join(args)} failed: {(out.stderr or out.stdout).strip()}")
    return out


def loaded_components() -> set[str]:
    """Names of the HAL components of the running LinuxCNC (IngestError when none runs here)."""
    out = _halcmd("list", "comp", check=False)
    if out.returncode != 0 or "motmod" not in out.stdout.split():
        raise IngestError("no running LinuxCNC found (halcmd cannot see motmod); start LinuxCNC first, "
                          "as the same user and with the same RTAPI_FIFO_PATH")
    return set(out.stdout.split())


def wait_for_servo_thread(timeout_s: float = 30.0) -> None:
    """Wait until the servo thread runs: LinuxCNC starts its threads after loading all HAL files."""
    end = time.monotonic() + timeout_s
    while True:
        out = _halcmd("getp", "motion.servo.last-period", check=False)
        try:
            if out.returncode == 0 and int(out.stdout.split()[0]) > 0:
                return
        except (ValueError, IndexError):
            pass
        if time.monotonic() > end:
            raise IngestError("LinuxCNC's servo thread is not running (motion.servo.last-period stays 0)")
        time.sleep(0.2)


def attach_linuxcnc(ini: str | Path, out: str | Path, *, program: str | Path | None = None,
                    profile: str | None = None, timeout_s: float = 3600.0, until_program_end: bool = True,
                    overwrite: bool = False, compression: str = "zstd", notes: str = "",
                    stop_event: threading.Event | None = None) -> dict[str, Any]:
    """Record the running LinuxCNC configured by `ini` into `out`; return the summary.

    `program` is attached when given; otherwise the file LinuxCNC has open is attached if readable.
    """
    reason = linuxcnc_available()
    if reason:
        raise IngestError(reason)
    ini_cfg = MachineIni.read(ini)
    out = Path(out)
    if out.exists() and not overwrite:
        raise IngestError("output exists; pass --overwrite to replace it", file=str(out))
    profile_name, profile_toml = profile_toml_for(profile, ini_cfg)
    loaded_components()
    wait_for_servo_thread()
    comps = loaded_components()
    if "sampler" in comps:
        raise IngestError("the running HAL already has a sampler component (halscope/halsampler in use?); "
                          "unload it or record with the manual steps in docs/linuxcnc.md")
    clock = not any(m in comps for m in CLOCK_MODULES)
    layout = standard_layout(ini_cfg.coordinates, ini_cfg.joints, clock=clock)
    workdir = Path(tempfile.mkdtemp(prefix="feedlog-attach-"))
    sample_files = [workdir / f"sampler{c}.txt" for c in layout.channels]
    try:
        (workdir / "record.tcl").write_text(recorder_tcl(layout))
        (workdir / "unload.tcl").write_text(unload_tcl(layout))
        driver = workdir / "driver.py"
        shutil.copyfile(DRIVER_SOURCE, driver)
        job = {"attach": True, "until_program_end": until_program_end, "channels": layout.channels,
               "sample_files": [str(p) for p in sample_files], "result": str(workdir / "result.json"),
               "enable_signal": ENABLE_SIGNAL, "timeout_s": timeout_s, "stop_file": str(workdir / "stop"),
               "motion_time_pin": f"{MOTION_TIME_COMPONENT}.out" if clock else None}
        (workdir / "job.json").write_text(json.dumps(job))
        loaded = subprocess.run(["haltcl", str(workdir / "record.tcl")], capture_output=True, text=True, timeout=60)
        if loaded.returncode != 0:
            subprocess.run(["haltcl", str(workdir / "unload.tcl")], capture_output=True, timeout=60)
            raise IngestError(f"loading the recorder into the running HAL failed: "
                              f"{(loaded.stderr or loaded.stdout).strip()[-400:]}")
        t0 = time.monotonic()
        try:
            log_path = workdir / "driver.log"
            with open(log_path, "w") as log_file:
                proc = subprocess.Popen([DEBIAN_PYTHON, str(driver), "--attach", str(workdir / "job.json")],
                                        stdout=log_file, stderr=subprocess.STDOUT)
                try:
                    wait_with_stop(proc, timeout_s + 60, stop_event, workdir / "stop")
                except KeyboardInterrupt:  # the user stops the recording: let the driver finish its files
                    (workdir / "stop").touch()
                    proc.wait(timeout=60)
            log = log_path.read_text(errors="replace")
        finally:
            subprocess.run(["haltcl", str(workdir / "unload.tcl")], capture_output=True, timeout=60)
        wall_s = time.monotonic() - t0
        result_path = Path(job["result"])
        if result_path.exists():
            report = json.loads(result_path.read_text())
        else:  # keep whatever was sampled
            report = {"ok": False, "errors": [], "phase": "attach",
                      "abort": f"the attached recorder stopped without a report: {(log or '').strip()[-400:]}"}
        program_path = Path(program) if program else (Path(report["program_file"]) if report.get("program_file")
                                                      else None)
        sampled = has_samples(sample_files)
        error = session_error(report, program_path or Path("<running program>"), sampled=sampled)
        program_bytes = program_path.read_bytes() if program_path and program_path.is_file() else None
        if error is not None and not sampled:
            raise error
        with keep_captures_on_failure(workdir):
            streams, missing = load_capture(sample_files, layout, period_ns=ini_cfg.servo_period_ns,
                                            linear_units=ini_cfg.linear_units, source=str(out))
            summary = write_session(streams, missing, report, ini=ini_cfg,
                                    program=program_path.name if program_path else "",
                                    program_bytes=program_bytes, profile_name=profile_name,
                                    profile_toml=profile_toml, out=out, overwrite=overwrite,
                                    compression=compression, notes=notes or "attached to a running LinuxCNC",
                                    error=error, wall_s=wall_s)
    except BaseException:
        if not any(p.exists() and p.stat().st_size for p in sample_files):
            shutil.rmtree(workdir, ignore_errors=True)  # nothing sampled: nothing to keep
        raise
    shutil.rmtree(workdir, ignore_errors=True)
    return finish(summary, error, out)


__all__ = ["attach_linuxcnc", "loaded_components", "wait_for_servo_thread"]
