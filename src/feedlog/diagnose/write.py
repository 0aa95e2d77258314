"""Writing a diagnosis to its output folder, all or nothing.

Everything goes into a temporary sibling folder first (`report.md`, `plots/`, `diagnose.json`,
`profile.toml`, `diagnose.rrd`, and `learned.pt` when a learned correction generalised); only a
complete folder is renamed into place, so a failure or an interrupt never leaves half of a
diagnosis behind. An existing folder is replaced only with `overwrite`.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from pathlib import Path

from feedlog.diagnose.cases import DiagnoseError
from feedlog.errors import OutputError
from feedlog.diagnose.summary import to_json

PROFILE = "profile.toml"


def profile_text(dx) -> str:
    head = [f"# {dx.extended.name}: {dx.profile.name} extended by feedlog diagnose on "
            f"{len(dx.cases)} recording(s): {', '.join(c.name for c in dx.cases)}"]
    if dx.diff:
        head += [f"#   {k}: {a!r} -> {b!r}" for k, a, b in dx.diff]
    else:
        head.append("#   no change: the given profile explains the recordings")
    for f in dx.findings:
        head.append(f"#   cause {f.parameter}: held-out gain {f.gain_pct:.1f} %, interval {f.interval}")
    return "\n".join(head) + "\n" + dx.extended.to_toml()


def write_outputs(dx, out: str | Path, *, overwrite: bool = False, rrd: bool = True) -> dict[str, str]:
    """Write the diagnosis into folder `out`; returns name -> path of what was written."""
    out = Path(out)
    if out.exists() and not overwrite and (not out.is_dir() or any(out.iterdir())):
        raise DiagnoseError(f"{out} exists; pass --overwrite to replace it")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    except OSError as exc:
        raise OutputError(f"cannot create the output folder: {exc.strerror or exc}", file=str(out)) from None
    try:
        dx.profile_out = str(out / PROFILE)
        (tmp / PROFILE).write_text(profile_text(dx))
        from feedlog.diagnose.report import write_report  # matplotlib loads on use

        write_report(dx, tmp)
        if rrd:
            from feedlog.diagnose.rerun_view import save_rrd

            save_rrd(dx, tmp / "diagnose.rrd")
        learned = next((u.get("learned_correction") for u in dx.unexplained if u.get("learned_correction")), None)
        if dx.learned_model is not None and learned and learned.get("gain_pct", 0) > 0:
            from feedlog.train.checkpoint import save_checkpoint

            save_checkpoint(dx.learned_model, tmp / "learned.pt")
        (tmp / "diagnose.json").write_text(json.dumps(to_json(dx), indent=1, allow_nan=False) + "\n")
        if out.exists():
            old = out.with_name(f".{out.name}.old-{tmp.name[-8:]}")
            out.rename(old)
            tmp.rename(out)
            shutil.rmtree(old, ignore_errors=True)
        else:
            tmp.rename(out)
    except OSError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        raise OutputError(f"cannot write the diagnosis: {exc.strerror or exc}", file=str(out)) from None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return {p.name: str(out / p.name) for p in out.iterdir()}
