"""Many recordings' overlays in one .rrd file: each recording its own Rerun recording id (named after
it), one blueprint for all of them.

Rerun's SDK writes one recording per stream. Each recording's stream is read as bytes
(`binary_stream`) and piped into `rerun rrd merge` (Rerun's own command line, shipped with
rerun-sdk), which writes one file with every recording, one blueprint and one index (footer), so
Rerun's viewer lists the recordings by name and `rerun.chunk.RrdReader` reads each. The streams go
one after another: only one recording's overlays are in this process at a time. The file is written
under a temporary name and renamed when complete (`feedlog.atomic`): a failed write, or a merge that
fails, leaves nothing.

The blueprint's views have relative origins (`/feed`, `/axes/x`, ...) and a Rerun blueprint belongs to
an application id (`DEMO_APPLICATION_ID`): the one layout shows whichever recording is selected. Each
series' legend label and colour travel once in it (view overrides) instead of once per recording.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import rerun as rr

from feedlog.atomic import atomic_output
from feedlog.errors import OutputError
from feedlog.rerun_stream import new_stream
from feedlog.viz.overlay import Style, log_view, series_blueprint
from feedlog.viz.prepare import ViewData

DEMO_APPLICATION_ID = "feedlog-demo"   # the demo's layout is its own: not applied to `feedlog view`'s recordings
AXIS_ORDER = "xyzabcuvw"
MERGE_COMMAND = (sys.executable, "-m", "rerun_cli", "rrd", "merge", "-o")   # + the output path; reads stdin


@contextlib.contextmanager
def rrd_bundle(path: str | os.PathLike, *, application_id: str = DEMO_APPLICATION_ID,
               title: str = "toolpath") -> Iterator[RrdBundle]:
    """`with rrd_bundle(path) as bundle: bundle.add(data, columns=800) ...`: one .rrd at `path`, a
    recording per `add`, complete when the block ends (nothing at `path` when it raises)."""
    with atomic_output(path) as temporary:
        bundle = RrdBundle(Path(path), temporary, application_id=application_id, title=title)
        try:
            yield bundle
            bundle.finish()
        finally:
            bundle.stop()


class RrdBundle:
    """The recordings written so far, piped into `rerun rrd merge` writing `temporary`; the blueprint
    goes last (it needs every recording's axes and series styles). Made by `rrd_bundle`."""

    def __init__(self, path: Path, temporary: Path, *, application_id: str, title: str) -> None:
        self.path, self.application_id, self.title = path, application_id, title
        self.styles: dict[str, Style] = {}
        self.axes: set[str] = set()
        self.residuals = False
        self.names: list[str] = []
        self._last: tuple[rr.RecordingStream, rr.BinaryStream] | None = None
        self._errors = tempfile.TemporaryFile()
        try:
            self._merge = subprocess.Popen(
                [*MERGE_COMMAND, str(temporary)],
                stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=self._errors,
                env={**os.environ, "RUST_LOG": "warn"})
        except OSError as exc:
            self._errors.close()
            raise OutputError(f"cannot start Rerun's merge ({exc}); nothing was written", file=str(path)) from None

    def add(self, data: ViewData, *, columns: int | None = None) -> dict[str, int]:
        """Log one recording's overlays as a recording of its own (`log_view`); returns its counts."""
        self._flush_last()
        stream = new_stream(data.name, application_id=self.application_id)
        binary = stream.binary_stream()
        stream.send_recording_name(data.name)
        counts = log_view(data, stream, columns=columns, styles=self.styles)
        self._last = (stream, binary)
        self.axes.update(data.axes)
        self.residuals = self.residuals or bool(data.residuals)
        self.names.append(data.name)
        return counts

    def finish(self) -> None:
        """The blueprint (with the last recording's stream), the last bytes, and the merge's end."""
        try:
            if self._last is not None:
                axes = sorted(self.axes, key=lambda a: (AXIS_ORDER.find(a), a))
                self._last[0].send_blueprint(series_blueprint(axes, residuals=self.residuals, title=self.title,
                                                              styles=self.styles), make_active=True,
                                             make_default=True)
            self._flush_last()
            self._merge.stdin.close()
            code = self._merge.wait()
        except OSError as exc:  # the merge went away (a full disk ends it)
            raise OutputError(f"cannot write the output ({self._reason() or exc}); nothing was written",
                              file=str(self.path)) from None
        if code != 0:
            raise OutputError(f"cannot write the output (Rerun's merge: {self._reason() or f'exit code {code}'}); "
                              "nothing was written", file=str(self.path))

    def stop(self) -> None:
        """End the merge if it still runs (an error on the way) and free what this bundle holds."""
        self._last = None
        if self._merge.poll() is None:
            self._merge.kill()
            self._merge.wait()
        if self._merge.stdin is not None and not self._merge.stdin.closed:
            with contextlib.suppress(OSError):
                self._merge.stdin.close()
        self._errors.close()

    def _flush_last(self) -> None:
        """The previous recording's bytes into the merge; its stream is dropped (Rerun holds a finished
        stream's memory until then)."""
        if self._last is None:
            return
        stream, binary = self._last
        self._last = None
        self._merge.stdin.write(binary.read() or b"")
        stream.disconnect()

    def _reason(self) -> str:
        """The last line the merge printed on its error output."""
        self._errors.seek(0)
        lines = [line.strip() for line in self._errors.read().decode(errors="replace").splitlines() if line.strip()]
        return lines[-1] if lines else ""
