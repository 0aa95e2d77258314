"""Errors that said the wrong thing (issue #30): a recording given as a part program, the letter O typed
for a zero, a folder given as a recording. Each is one line naming the file and what is really wrong."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from feedlog.cli import main

ROOT = Path(__file__).resolve().parents[1]
RECORDING = ROOT / "recordings" / "test_p001.mcap"


def _one_error(capsys, command: str) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"feedlog {command}: error: "), err
    return err[0]


@pytest.fixture(scope="module")
def model(tmp_path_factory) -> Path:
    """A small trained MLP checkpoint for `predict` (read before the program)."""
    from feedlog.train import make_model, save_checkpoint
    from feedlog.train.dataset import fingerprint
    from feedlog.train.synthetic import synthetic_set

    train = [t for t in synthetic_set(n_train=2, n_test=1, n_blocks=60, seed=7) if t.split == "train"]
    mlp = make_model("mlp", epochs=2)
    mlp.fit(train, progress=False)
    mlp.fingerprint = fingerprint(train, mlp.required_columns + ["duration_s"])
    return save_checkpoint(mlp, tmp_path_factory.mktemp("model") / "m.pt")


@pytest.mark.parametrize("command", ["program", "sim", "predict"])
def test_a_recording_given_as_the_part_program(command, capsys, model):
    argv = {"program": ["program", str(RECORDING)],
            "sim": ["sim", str(RECORDING), "--profile", "linuxcnc-xyz"],
            "predict": ["predict", str(RECORDING), "--model", str(model), "--profile", "linuxcnc-xyz"]}[command]
    assert main(argv) == 2
    line = _one_error(capsys, command)
    assert re.search(rf"{re.escape(str(RECORDING))}:\d+: not a text part program: the file holds binary data, "
                     r"a NUL byte here \(an MCAP file", line)
    assert "'%'" not in line


def test_any_binary_file_is_not_a_part_program(tmp_path, capsys):
    path = tmp_path / "image.ngc"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + bytes(range(256)))
    assert main(["program", str(path)]) == 2
    assert _one_error(capsys, "program").endswith(f"{path}:3: not a text part program: the file holds binary "
                                                  "data, a NUL byte here")  # the line of the first NUL
    path.write_bytes(b"G1 X1 F100\n(caf\xe9 latin-1 comment)\nM2\n")  # not UTF-8, but text
    assert main(["program", str(path)]) == 0


def test_the_letter_o_for_a_zero_is_a_malformed_word_not_control_flow(tmp_path, capsys):
    path = tmp_path / "typo.ngc"
    path.write_text("G21 G90\nG1 X4O F100\nM2\n")
    assert main(["program", str(path)]) == 2
    line = _one_error(capsys, "program")
    assert f"{path}:2: malformed word" in line and "letter O where a zero was meant" in line
    assert "O-word" not in line
    path.write_text("G21 G90\no100 sub\nG1 X1 F100\no100 endsub\nM2\n")  # real O-word control flow: read
    assert main(["program", str(path)]) == 0
    capsys.readouterr()
    path.write_text("G21 G90\no100 frobnicate\nM2\n")                   # an O-word LinuxCNC does not know
    assert main(["program", str(path)]) == 2
    err = _one_error(capsys, "program")
    assert f"{path}:2: " in err and ("O-word" in err or "O line" in err) and "frobnicate" in err


@pytest.mark.parametrize("command", ["info", "diagnose"])
def test_a_folder_given_as_a_recording(command, tmp_path, capsys):
    folder = tmp_path / "recordings"
    folder.mkdir()
    argv = ["info", str(folder)] if command == "info" else ["diagnose", str(folder), "--profile", "linuxcnc-xyz",
                                                            "-o", str(tmp_path / "dx")]
    assert main(argv) == 2
    line = _one_error(capsys, command)
    assert f"{folder}: is a folder, not a recording file" in line and "no such" not in line
