"""The `feedlog` command: a thin layer that parses arguments and calls one library function.

Subcommands live with the stage they belong to. Each is a module with
`configure(parser: argparse.ArgumentParser) -> None` and `run(args: argparse.Namespace) -> int`,
registered below by name and imported only when used, so `feedlog program` does not pay for torch.
Our errors (FeedlogError) become one line on stderr and an exit code: 2 for input or arguments that
cannot be used (as argparse does for usage errors), 1 for an output that could not be written
(`OutputError`: disk full, permissions). Anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import argparse
import sys
from types import ModuleType

from feedlog import __version__
from feedlog.errors import FeedlogError
from feedlog.registry import Registry, TargetMissing


def _not_in_this_version(name: str, missing: TargetMissing) -> FeedlogError:
    return FeedlogError(f"feedlog {name} is not available in this version")


# name -> (module, one-line help). One line per subcommand.
COMMANDS: Registry[ModuleType] = Registry.lazy("command", {
    "program": ("feedlog.toolpath.cli", "summarise a part program (blocks, length, CAM time)"),
    "profile": ("feedlog.profile_cli", "show a machine profile, or list the shipped ones"),
    "sim": ("feedlog.sim.cli", "simulate the NC interpolator on a part program"),
    "import": ("feedlog.ingest.cli_import", "convert MCAP, CAN or CSV data into a feedlog recording"),
    "info": ("feedlog.ingest.cli_info", "summarise a recording"),
    "record": ("feedlog.ingest.cli_record", "record a live session (CAN bus, sim, LinuxCNC)"),
    "align": ("feedlog.align.cli", "align recordings with their part program"),
    "train": ("feedlog.train.cli_train", "train feed and cycle-time models on aligned data"),
    "predict": ("feedlog.train.cli_predict", "predict cycle time of a part program with a trained model"),
    "diagnose": ("feedlog.diagnose.cli", "find what the simulation gets wrong on recordings, name the cause, "
                 "extend the profile"),
    "view": ("feedlog.viz.cli", "show a recording in Rerun"),
    "demo": ("feedlog.viz.demo", "run the whole pipeline on the bundled recordings"),
}, unavailable=_not_in_this_version)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="feedlog", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"feedlog {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        sub.add_parser(name, help=COMMANDS.doc(name), add_help=False)
    return parser


def one_line(text: str) -> str:
    """A message on one line: line breaks inside it (quoted input, library text) become spaces."""
    return " ".join(part.strip() for part in text.splitlines() if part.strip())


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    top = build_parser()
    if not argv or argv[0] not in COMMANDS:
        top.parse_args(argv)  # prints help, version or a usage error
        top.print_help()
        return 2
    name, rest = argv[0], argv[1:]
    try:
        module = COMMANDS.get(name)
        parser = argparse.ArgumentParser(prog=f"feedlog {name}", description=COMMANDS.doc(name))
        module.configure(parser)
        args = parser.parse_args(rest)
        return int(module.run(args) or 0)
    except FeedlogError as exc:
        print(f"feedlog {name}: error: {one_line(str(exc))}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print(f"feedlog {name}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
