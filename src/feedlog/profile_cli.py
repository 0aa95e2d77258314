"""`feedlog profile [NAME|PATH] [--json]`: show a machine profile or list the shipped ones."""

from __future__ import annotations

import argparse
import json

from feedlog.profile import load_profile, shipped_profiles


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("profile", nargs="?", help="short name (e.g. linuxcnc-xyz) or path to a TOML file")
    parser.add_argument("--json", action="store_true", help="print the profile as JSON")


def run(args: argparse.Namespace) -> int:
    if args.profile is None:
        for name in shipped_profiles():
            print(name)
        return 0
    profile = load_profile(args.profile)
    print(json.dumps(profile.to_dict(), indent=2) if args.json else profile.to_toml(), end="")
    return 0
