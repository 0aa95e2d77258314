"""Fuzz cases for what configures a run: machine profiles (`--profile FILE.toml`), sim settings
(`--set MECH.PARAM=VALUE`) and model checkpoints (`predict --model FILE`)."""

from __future__ import annotations

import io
import random
import zipfile

from tests.fuzz import mutate
from tests.fuzz.cases import EXAMPLES, ROOT, Case, Run

PROFILE = ROOT / "src" / "feedlog" / "profiles" / "linuxcnc-xyz.toml"


def profile_cases(rng: random.Random) -> list[Case]:
    text = PROFILE.read_bytes()
    program = (EXAMPLES / "pocket.ngc").read_bytes()

    def case(name: str, content: bytes, expect: str = "any", *, sim_only: bool = False) -> Case:
        """`sim_only`: the damage is in a [sim.*] table, which `feedlog program` does not read."""
        runs = [Run(["program", "p.ngc", "--json", "--profile", "m.toml"], "any" if sim_only else expect),
                Run(["sim", "p.ngc", "--json", "--profile", "m.toml"], expect)]
        return Case("config", f"profile/{name}", {"m.toml": content, "p.ngc": program}, runs, "m.toml",
                    located=False)

    def swap(old: bytes, new: bytes) -> bytes:
        assert old in text, old
        return text.replace(old, new, 1)

    return [
        case("vel-nan", swap(b"vel_max = 100.0", b"vel_max = nan"), "error"),
        case("vel-inf", swap(b"vel_max = 100.0", b"vel_max = inf"), "error"),
        case("vel-string", swap(b"vel_max = 100.0", b'vel_max = "fast"'), "error"),
        case("vel-bool", swap(b"vel_max = 100.0", b"vel_max = true"), "error"),
        case("vel-1e-300", swap(b"vel_max = 100.0", b"vel_max = 1e-300"), "error"),
        case("acc-negative", swap(b"acc_max = 1000.0", b"acc_max = -1"), "error"),
        case("rapid-string", swap(b"rapid_mm_min = 6000.0", b'rapid_mm_min = "6000"'), "error"),
        case("rapid-1e-300", swap(b"rapid_mm_min = 6000.0", b"rapid_mm_min = 1e-300"), "error"),
        case("period-1e-300", swap(b"interpolation_period_s = 0.001", b"interpolation_period_s = 1e-300"), "error"),
        case("servo-period-1e-12", swap(b"servo_period_s = 0.001", b"servo_period_s = 1e-12"), "error"),
        case("lookahead-string", swap(b"lookahead_blocks = 50", b'lookahead_blocks = "many"'), "error"),
        case("lookahead-float", swap(b"lookahead_blocks = 50", b"lookahead_blocks = 2.5"), "error"),
        case("lookahead-huge", swap(b"lookahead_blocks = 50", b"lookahead_blocks = 99999999999999"), "error"),
        case("limits-nan", swap(b"min_limit = -1000.0", b"min_limit = nan"), "error"),
        case("axes-table-string", swap(b"[axes.z]\nvel_max = 100.0\nacc_max = 1000.0",
                                       b"[axes.w]\nvel_max = 100.0\nacc_max = 1000.0"), "error"),
        case("sim-param-string", text + b"\n[sim.feed_override]\noverride = \"half\"\n", "error", sim_only=True),
        case("sim-param-list", text + b"\n[sim.lookahead]\nlookahead_blocks = [1, 2]\n", "error"),
        case("sim-not-table", text + b"\nsim = 5\n", "error", sim_only=True),
        case("truncated", mutate.truncate(text, rng)),
        case("bitflip", mutate.flip_bits(text, rng, count=2)),
        case("utf16", mutate.reencode(text, "utf-16"), "error"),
        case("bom", mutate.BOM + text),
        case("empty", b"", "error"),
    ]


def setting_cases() -> list[Case]:
    program = (EXAMPLES / "pocket.ngc").read_bytes()
    settings = {
        "lookahead-abc": "lookahead.lookahead_blocks=abc",
        "lookahead-float": "lookahead.lookahead_blocks=2.5",
        "lookahead-zero": "lookahead.lookahead_blocks=0",
        "lookahead-list": "lookahead.lookahead_blocks=[1,2]",
        "override-nan": "feed_override.override=NaN",
        "override-inf": "feed_override.override=Infinity",
        "override-1e-300": "feed_override.override=1e-300",
        "override-string": "feed_override.override=fast",
        "override-null": "feed_override.override=null",
        "lag-not-dict": "following_lag.lag_s=5",
        "offset-short": "trunnion.workpiece_offset_mm=[1]",
    }
    cases = []
    for name, setting in settings.items():
        run = Run(["sim", "p.ngc", "--json", "--profile", "linuxcnc-xyz", "--set", setting], "error")
        parameter = setting.split("=")[0].split(".")[1]
        cases.append(Case("config", f"set/{name}", {"p.ngc": program}, [run], parameter, located=False))
    return cases


def model_cases(rng: random.Random) -> list[Case]:
    import torch

    def saved(obj) -> bytes:
        out = io.BytesIO()
        torch.save(obj, out)
        return out.getvalue()

    def zipped(member: str, data: bytes) -> bytes:
        out = io.BytesIO()
        with zipfile.ZipFile(out, "w") as z:
            z.writestr(member, data)
        return out.getvalue()

    program = (EXAMPLES / "pocket.ngc").read_bytes()
    models = {
        "text": b"hello\n",
        "empty": b"",
        "random-bytes": bytes(rng.randrange(256) for _ in range(3000)),
        "zip-garbage": zipped("archive/data.pkl", b"garbage"),
        "tensor": saved(torch.zeros(3)),
        "wrong-format": saved({"format": "other", "format_version": 1}),
        "version-text": saved({"format": "feedlog-model", "format_version": "5"}),
        "version-future": saved({"format": "feedlog-model", "format_version": 99}),
        "missing-fields": saved({"format": "feedlog-model", "format_version": 5, "model": "mlp"}),
        "unknown-model": saved({"format": "feedlog-model", "format_version": 5, "model": "gpt", "config": {}}),
    }
    return [Case("config", f"model/{name}", {"p.ngc": program, "m.pt": data},
                 [Run(["predict", "p.ngc", "--model", "m.pt", "--json", "-o", "o.parquet"], "error")], "m.pt",
                 located=False)
            for name, data in models.items()]


def build(rng: random.Random) -> list[Case]:
    return profile_cases(rng) + setting_cases() + model_cases(rng)
