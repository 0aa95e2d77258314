"""README's "Commands" section, replayed in order as a new user would type them (issue #30): every
command that runs without LinuxCNC exits 0, and each one takes what the one before it wrote.

The commands are read from README.md, not copied here, so a changed README is what is tested. To stay
under two minutes, `recordings/` in the scratch folder holds five of the bundled recordings (with the
manifest, programs and the mystery machine), one of them mix5ax_022, which align refuses at its default
tolerance (a warning, not a failed batch), and `train` gets `--preset quick`.
"""

from __future__ import annotations

import glob
import json
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SUBSET = ("corners_f3000_p001", "pocket_f3000_p001", "mix_001", "test_p001", "mix5ax_022")
REFUSED = "mix5ax_022"


def readme_commands() -> list[str]:
    """The `feedlog ...` lines of README's "## Commands" code block, comments and `[--optional]` parts removed."""
    text = (ROOT / "README.md").read_text()
    section = text.split("\n## Commands", 1)[1]
    block = section.split("```bash\n", 1)[1].split("```", 1)[0]
    commands = []
    for line in block.splitlines():
        if "needs LinuxCNC" in line or "needs a machine" in line:
            continue
        command = re.sub(r"\[[^\]]*\]", "", line.split("#", 1)[0]).strip()
        if command.startswith("feedlog "):
            commands.append(command)
    return commands


def scratch_checkout(tmp_path: Path) -> None:
    """What the commands read, relative to the scratch folder: examples/, tests/fixtures/ and a small recordings/."""
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    (tmp_path / "tests").symlink_to(ROOT / "tests")
    recordings = tmp_path / "recordings"
    recordings.mkdir()
    for name in ("manifest.toml", "held_back.toml", "programs", "configs", "mystery"):
        (recordings / name).symlink_to(ROOT / "recordings" / name)
    for name in SUBSET:
        (recordings / f"{name}.mcap").symlink_to(ROOT / "recordings" / f"{name}.mcap")


def shell_words(command: str, cwd: Path) -> list[str] | None:
    """The arguments as bash gives them (globs expanded, sorted); None when a glob matches nothing there
    (a placeholder such as `exp*.mcap`)."""
    words = []
    for word in shlex.split(command)[1:]:
        if any(c in word for c in "*?["):
            found = sorted(glob.glob(word, root_dir=cwd))
            if not found:
                return None
            words += found
        else:
            words.append(word)
    return words


def test_readme_lists_the_pipeline():
    commands = readme_commands()
    first_words = [c.split()[1] for c in commands]
    for command in ("program", "sim", "record", "import", "info", "align", "train", "predict", "view", "diagnose"):
        assert command in first_words, command
    assert first_words.index("align") < first_words.index("train") < first_words.index("predict")


@pytest.mark.slow
def test_readme_commands_run_in_order_and_chain(tmp_path):
    scratch_checkout(tmp_path)
    ran = []
    for command in readme_commands():
        words = shell_words(command, tmp_path)
        if words is None:
            continue
        if words[0] == "train":
            words += ["--preset", "quick"]
        proc = subprocess.run([sys.executable, "-m", "feedlog", *words], cwd=tmp_path, capture_output=True,
                              text=True, timeout=300)
        assert proc.returncode == 0, (command, proc.stdout[-2000:], proc.stderr[-2000:])
        assert "Traceback" not in proc.stderr, (command, proc.stderr[-2000:])
        ran.append((words, proc))
    commands = [words[0] for words, _ in ran]
    assert commands.count("diagnose") == 2  # the generic-xyz line has placeholder inputs (exp*.mcap)
    assert (tmp_path / "dx-hurco" / "report.md").is_file()   # the NIST Hurco: no program, the data alone
    assert {"program", "sim", "record", "import", "info", "align", "train", "predict", "view"} <= set(commands)
    # align: the refused recording is a warning and a count, --json a summary, not every block of every recording
    align = next(proc for words, proc in ran if words[0] == "align")
    doc = json.loads(align.stdout)
    assert doc["aligned"] == len(SUBSET) - 1 and doc["refused"] == 1 and doc["exit_code"] == 0
    assert [Path(d["recording"]).stem for d in doc["not_aligned"]] == [REFUSED]
    assert len(align.stdout) < 5000
    assert f"{len(SUBSET) - 1} aligned, 1 refused" in align.stderr
    assert f"feedlog align: warning: recordings/{REFUSED}.mcap: " in align.stderr
    assert sorted(p.name for p in (tmp_path / "aligned").iterdir()) == sorted(
        ["dataset", *(n for n in SUBSET if n != REFUSED)])
    # train took align's folders through the glob aligned/* (dataset/ among them) and wrote the model predict used
    train = next(proc for words, proc in ran if words[0] == "train")
    assert f"{len(SUBSET) - 1} aligned recording(s): {len(SUBSET) - 2} for training, 1 held out" in train.stdout
    assert (tmp_path / "models" / "hybrid.pt").is_file() and (tmp_path / "dx" / "profile.toml").is_file()
    assert (tmp_path / "test_p001.rrd").stat().st_size > 0
