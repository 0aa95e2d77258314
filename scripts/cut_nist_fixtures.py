#!/usr/bin/env python3
"""Cut tests/fixtures/ingest/nist/ from a clone of the NIST smart manufacturing test bed repository.

The files are public domain (US Government work, github.com/usnistgov/smstestbed). This script
copies them byte for byte from one pinned commit of a clone (a bare mirror is fine: it reads with
`git show COMMIT:PATH`), and cuts the one large file to its first lines, so that anybody can check the
fixtures against the source:

    python3 scripts/cut_nist_fixtures.py /path/to/smstestbed      # a clone or bare mirror
    python3 scripts/cut_nist_fixtures.py /path/to/smstestbed --check   # compare, write nothing

What is taken (see tests/fixtures/ingest/nist/README.md):
- `tdp/mtc/Split/Box-OP2-Hurco02-01of20.txt`: whole (Split SHDR of the box part's operation 2, part 1 of 20);
- `tdp/mtc/NC-Code/NIST_MTC_CRADA_BOX_REV-A OP2 (Front).NC`: whole (the published program of that operation);
- `raw/Mazak01/Mazak01-20161006-20161007.txt`: its first 4000 lines (2016-10-05T05:27 .. 2016-10-06T10:23 UTC);
- `mtconnect/agent/Devices.xml`: whole (the test bed agent's device file: the probe the live-source tests serve).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

COMMIT = "968279f14ebe96c03c8877eeb1901cf6b4c8fbab"
OUT = Path(__file__).resolve().parents[1] / "tests" / "fixtures" / "ingest" / "nist"
# source path in the repository -> (fixture name, number of lines kept or None for the whole file)
FILES = {
    "tdp/mtc/Split/Box-OP2-Hurco02-01of20.txt": ("Box-OP2-Hurco02-01of20.txt", None),
    "tdp/mtc/NC-Code/NIST_MTC_CRADA_BOX_REV-A OP2 (Front).NC": ("NIST_MTC_CRADA_BOX_REV-A OP2 (Front).NC", None),
    "raw/Mazak01/Mazak01-20161006-20161007.txt": ("Mazak01-20161006-head4000.txt", 4000),
    "mtconnect/agent/Devices.xml": ("Devices.xml", None),
}


def cut(repo: Path, source: str, lines: int | None) -> bytes:
    data = subprocess.run(["git", f"--git-dir={_git_dir(repo)}", "show", f"{COMMIT}:{source}"],
                          check=True, capture_output=True).stdout
    if lines is None:
        return data
    return b"".join(data.splitlines(keepends=True)[:lines])


def _git_dir(repo: Path) -> Path:
    return repo / ".git" if (repo / ".git").exists() else repo


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("repo", type=Path, help="clone or bare mirror of github.com/usnistgov/smstestbed")
    parser.add_argument("--check", action="store_true", help="compare with the fixtures, write nothing")
    args = parser.parse_args()
    differ = 0
    for source, (name, lines) in FILES.items():
        data = cut(args.repo, source, lines)
        target = OUT / name
        if args.check:
            same = target.is_file() and target.read_bytes() == data
            differ += not same
            print(f"{'same' if same else 'DIFFERS'}  {name}")
        else:
            OUT.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data)
            print(f"wrote {target} ({len(data)} bytes)")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
