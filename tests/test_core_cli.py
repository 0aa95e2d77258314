"""The feedlog command: registry, one-line errors (exit code 2 for bad input, 1 for a failed write), help."""

from __future__ import annotations

import subprocess
import sys


from feedlog import cli


def test_every_registered_command_names_a_feedlog_module():
    for name in cli.COMMANDS:
        assert cli.COMMANDS.target(name).startswith("feedlog."), name
        assert cli.COMMANDS.doc(name)


def test_profile_command_lists_shipped_profiles(capsys):
    assert cli.main(["profile"]) == 0
    assert capsys.readouterr().out.split() == ["chien-ac", "generic-xyz", "generic-xyzac", "linuxcnc-xyz", "linuxcnc-xyzac"]


def test_our_error_is_one_line_and_exit_code_2(capsys):
    assert cli.main(["profile", "no-such-machine"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err.startswith("feedlog profile: error: unknown machine profile 'no-such-machine'")
    assert "Traceback" not in err


def test_no_command_prints_help_and_exits_2(capsys):
    assert cli.main([]) == 2
    assert "program" in capsys.readouterr().out


def test_installed_entry_point_runs():
    out = subprocess.run([sys.executable, "-m", "feedlog", "profile", "linuxcnc-xyz", "--json"],
                         capture_output=True, text=True, check=True).stdout
    assert '"name": "linuxcnc-xyz"' in out


def test_readme_starts_with_two_commands_and_ci_runs_the_second(repo_root):
    lines = (repo_root / "README.md").read_text().splitlines()
    start = lines.index("```bash")
    commands = lines[start + 1:start + 3]
    assert lines[start + 3] == "```"
    assert "pip install" in commands[0] and "torch==2.13.0" in commands[0]
    assert "pytest" in commands[1] and "torch==2.13.0" in commands[1]
    ci = (repo_root / ".ci" / "run").read_text()
    assert "grep -m1 -E '^python3 -m venv .venv .*pytest' README.md" in ci
