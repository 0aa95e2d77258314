"""Issue #19: the seeded fuzz corpus through the `feedlog` command. Every run ends in exit 0 with a sane
output or in one clear error line (file and place named, exit code 2, nothing left behind).

Each input type runs in a worker process (`python -m tests.fuzz.runner --kind K --jsonl`) whose address
space is capped, so an allocation sized by a corrupt length field fails the test instead of the machine.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections import Counter

import pytest

from tests.fuzz.cases import ROOT, Case, Run
from tests.fuzz.runner import GOOD, KINDS, _Hang, build, classify

pytestmark = pytest.mark.timeout(600)


@pytest.mark.parametrize("kind", KINDS)
def test_every_mutated_input_ends_in_a_sane_result_or_one_clear_error(kind):
    proc = subprocess.run([sys.executable, "-m", "tests.fuzz.runner", "--kind", kind, "--jsonl"], cwd=ROOT,
                          capture_output=True, text=True, timeout=580)
    assert proc.returncode == 0, proc.stderr[-3000:]
    outcomes = [json.loads(line) for line in proc.stdout.splitlines()]
    bad = [o for o in outcomes if o["result"] not in GOOD]
    assert not bad, f"{len(bad)} of {len(outcomes)} runs:\n" + "\n".join(
        f"{o['result']}: {o['case']}: feedlog {' '.join(o['argv'])}: {o['detail']}" for o in bad[:25])
    assert {o["case"] for o in outcomes} == {c.name for c in build(kind)}
    results = Counter(o["result"] for o in outcomes)
    assert results["ok"] > 0 and results["clear_error"] > 0, results


def test_the_corpus_is_large_and_the_same_every_time():
    corpora = {kind: build(kind) for kind in KINDS if kind != "config"}
    sizes = {kind: len(cases) for kind, cases in corpora.items()}
    assert sum(sizes.values()) >= 250 and min(sizes.values()) >= 40, sizes
    again = build("mcap")
    assert [(c.name, c.files) for c in again] == [(c.name, c.files) for c in corpora["mcap"]]
    names = [c.name for cases in corpora.values() for c in cases]
    assert len(names) == len(set(names))


# the harness itself must be able to fail: each bad outcome is recognised

CASE = Case("csv", "csv/probe", {"d.csv": b"t,x\n0,1\n"}, [Run(["import", "d.csv", "-o", "out.mcap"])], "d.csv")


def _classify(tmp_path, code, stdout="", stderr="", escaped=None, run=None, files=()):
    for name in files:
        (tmp_path / name).write_bytes(b"x")
    for name, data in CASE.files.items():
        (tmp_path / name).write_bytes(data)
    return classify(CASE, run or CASE.runs[0], code, stdout, stderr, escaped, tmp_path)[0]


def test_the_harness_flags_tracebacks_hangs_and_unclear_errors(tmp_path):
    assert _classify(tmp_path, None, escaped=ValueError("boom")) == "traceback"
    assert _classify(tmp_path, None, escaped=_Hang()) == "hang"
    assert _classify(tmp_path, 2, stderr="feedlog import: error: d.csv:3: bad\nmore\n") == "unclear"
    assert _classify(tmp_path, 2, stderr="feedlog import: error: something failed\n") == "unclear"  # no file
    assert _classify(tmp_path, 2, stderr="feedlog import: error: d.csv: failed\n") == "unclear"  # no place
    assert _classify(tmp_path, 1, stderr="feedlog import: error: d.csv:3: bad row\n") == "exit1_error"
    assert _classify(tmp_path, 2, stderr="feedlog import: error: d.csv:3: bad row\n") == "clear_error"
    assert _classify(tmp_path, 2, stderr="feedlog import: error: d.csv:3: bad row\n",
                     files=["out.mcap.1a2b.partial"]) == "unclear"  # a partial output left behind


def test_the_harness_flags_non_finite_json_and_silent_success(tmp_path):
    program = Run(["program", "t.ngc", "--json"])
    nan_doc = '{"cam_time_s": NaN, "length_mm": 1.0, "blocks": 1}'
    assert _classify(tmp_path, 0, stdout=nan_doc, run=program) == "silent"
    huge = '{"cam_time_s": 1e15, "length_mm": 1.0, "blocks": 1}'
    assert _classify(tmp_path, 0, stdout=huge, run=program) == "silent"
    fine = '{"cam_time_s": 2.5, "length_mm": 1.0, "blocks": 1}'
    assert _classify(tmp_path, 0, stdout=fine, run=program) == "ok"
    assert _classify(tmp_path, 0, stdout=fine, run=Run(program.argv, "error")) == "silent"
    info = Run(["info", "r.mcap", "--json"])
    doc = {"streams": [{"name": "axes", "t_start_ns": -2**63, "t_end_ns": 0, "samples": 2}], "dropped_frames": 0}
    assert _classify(tmp_path, 0, stdout=json.dumps(doc), run=info) == "silent"
    assert _classify(tmp_path, 0, run=CASE.runs[0]) == "silent"  # exit 0 but no recording written
