"""The layered house: every `feedlog` import points to its own layer or a lower one.

Layers, lowest first (docs/architecture.md, "Layers", says why):

    base < toolpath < sim < ingest < align < train < diagnose < viz < application

- base: the `feedlog` top-level modules (errors, units, profile, recording, storage, ...) and
  `feedlog.profiles` (the shipped profile files);
- one layer per stage package, in the order data flows through them (sim turns a program into
  motion and a simulated recording; ingest may simulate as a live source; align needs programs,
  recordings and the sim's trajectory; train learns from align's tables; diagnose re-simulates,
  re-aligns and falls back on a learner; viz shows all of it);
- application: the `feedlog` command (`feedlog.cli`, `python -m feedlog`) and the demo, which runs
  every stage (`feedlog.viz.demo`).

A module may import its own layer and any lower one, never a higher one. Imports are found with `ast`
everywhere in a module (top level, function bodies, `if TYPE_CHECKING:` blocks) and in registry
strings: a string constant that names a feedlog module (`"feedlog.sim.cam"`,
`"feedlog.sim.cam:CamEstimate"`) or a pair `("feedlog.train", "predict_program")`. No package imports
another package's `_private` name (the base modules count as one package, `feedlog`).
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass
from pathlib import Path


SRC = Path(__file__).resolve().parents[1] / "src"
ROOT = SRC / "feedlog"

LAYERS: tuple[str, ...] = ("base", "toolpath", "sim", "ingest", "align", "train", "diagnose", "viz", "application")
# modules above the layer of their folder (the folder is where they live, the layer what they may import)
APPLICATION_MODULES = ("feedlog.cli", "feedlog.__main__", "feedlog.viz.demo")
BASE_PACKAGES = ("feedlog.profiles",)

# "feedlog.a.b" or "feedlog.a.b:attribute", the whole string
MODULE_STRING = re.compile(r"^feedlog(?:\.[A-Za-z_]\w*)+(?::([A-Za-z_]\w*))?$")


@dataclass(frozen=True)
class Import:
    file: Path
    line: int
    importer: str   # dotted module name of the importing file
    target: str     # dotted module name imported (or the module a registry string names)
    name: str = ""  # the name taken from it, when there is one

    def where(self) -> str:
        try:
            return f"{self.file.relative_to(SRC.parent)}:{self.line}"
        except ValueError:
            return f"{self.file}:{self.line}"


def module_name(path: Path, root: Path = ROOT) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def layer_of(module: str, root: Path = ROOT) -> str:
    """The layer of a dotted feedlog module name (a module or a name inside it)."""
    if any(module == m or module.startswith(m + ".") for m in APPLICATION_MODULES):
        return "application"
    if any(module == p or module.startswith(p + ".") for p in BASE_PACKAGES):
        return "base"
    parts = module.split(".")
    if len(parts) == 1 or (root / parts[1]).with_suffix(".py").is_file():
        return "base"
    if (root / parts[1]).is_dir():
        if parts[1] not in LAYERS:
            raise AssertionError(f"feedlog.{parts[1]} is in no layer: add it to LAYERS in tests/test_layers.py "
                                 "and to docs/architecture.md")
        return parts[1]
    return "base"  # a name that is no module (an attribute of feedlog itself)


def package_of(module: str, root: Path = ROOT) -> str:
    """`feedlog.<stage>` for a module in a stage package, `feedlog` for the base modules."""
    parts = module.split(".")
    if len(parts) > 1 and (root / parts[1]).is_dir():
        return ".".join(parts[:2])
    return "feedlog"


def _resolve_relative(importer: str, is_package: bool, level: int, module: str | None) -> str:
    base = importer.split(".") if is_package else importer.split(".")[:-1]
    base = base[: len(base) - (level - 1)] if level > 1 else base
    return ".".join(base + ([module] if module else []))


def imports_of(path: Path, root: Path = ROOT, source: str | None = None) -> list[Import]:
    """Every feedlog import of one module: statements anywhere, registry strings and pairs."""
    text = path.read_text(encoding="utf-8") if source is None else source
    tree = ast.parse(text, filename=str(path))
    importer = module_name(path, root)
    is_package = path.name == "__init__.py"
    found: list[Import] = []
    paired: set[int] = set()  # string constants already read as the module of a ("module", "Name") pair
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [Import(path, node.lineno, importer, a.name) for a in node.names
                      if a.name.split(".")[0] == "feedlog"]
        elif isinstance(node, ast.ImportFrom):
            target = (_resolve_relative(importer, is_package, node.level, node.module) if node.level
                      else node.module or "")
            if target.split(".")[0] != "feedlog":
                continue
            for alias in node.names:
                if alias.name == "*":
                    found.append(Import(path, node.lineno, importer, target))
                    continue
                sub = f"{target}.{alias.name}"  # `from feedlog.x import y` may import the module feedlog.x.y
                is_module = (root.parent / Path(*sub.split("."))).with_suffix(".py").is_file() or \
                    (root.parent / Path(*sub.split("."))).is_dir()
                found.append(Import(path, node.lineno, importer, sub) if is_module
                             else Import(path, node.lineno, importer, target, alias.name))
        elif isinstance(node, ast.Tuple) and len(node.elts) == 2 and all(
                isinstance(e, ast.Constant) and isinstance(e.value, str) for e in node.elts):
            module, name = (e.value for e in node.elts)
            if MODULE_STRING.match(module) and ":" not in module and re.fullmatch(r"[A-Za-z_]\w*", name):
                found.append(Import(path, node.lineno, importer, module, name))
                paired.add(id(node.elts[0]))
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in paired:
            match = MODULE_STRING.match(node.value)
            if match and _names_a_module(node.value.split(":")[0], root):
                found.append(Import(path, node.lineno, importer, node.value.split(":")[0], match.group(1) or ""))
    return sorted(found, key=lambda imp: imp.line)


def _names_a_module(dotted: str, root: Path) -> bool:
    """Whether `dotted` starts with a feedlog module or package (so "feedlog.toml" is no import)."""
    top = dotted.split(".")[1]
    return (root / top).is_dir() or (root / top).with_suffix(".py").is_file()


def all_imports(root: Path = ROOT) -> list[Import]:
    return [imp for path in sorted(root.rglob("*.py")) for imp in imports_of(path, root)]


def layer_violations(imports: list[Import], root: Path = ROOT) -> list[str]:
    """`file:line: importer (layer) imports target (higher layer)` for every import that points up."""
    out = []
    for imp in imports:
        mine, theirs = layer_of(imp.importer, root), layer_of(imp.target, root)
        if LAYERS.index(theirs) > LAYERS.index(mine):
            what = f"{imp.target}:{imp.name}" if imp.name else imp.target
            out.append(f"{imp.where()}: {imp.importer} ({mine}) imports {what} ({theirs}, a higher layer)")
    return out


def private_violations(imports: list[Import], root: Path = ROOT) -> list[str]:
    """`file:line: ...` for every `_private` name (or module) taken from another package."""
    out = []
    for imp in imports:
        if package_of(imp.importer, root) == package_of(imp.target, root):
            continue
        private = [p for p in imp.target.split(".") if p.startswith("_") and not p.startswith("__")]
        if imp.name.startswith("_") and not imp.name.startswith("__"):
            private.append(imp.name)
        if private:
            out.append(f"{imp.where()}: {imp.importer} imports {', '.join(private)} from {imp.target}, "
                       f"private to {package_of(imp.target, root)}")
    return out


def _report(problems: list[str]) -> str:
    return f"{len(problems)} import(s) break the layering (tests/test_layers.py, docs/architecture.md):\n" + \
        "\n".join(problems)


def test_every_feedlog_import_points_to_its_own_layer_or_a_lower_one():
    problems = layer_violations(all_imports())
    assert not problems, _report(problems)


def test_no_package_imports_another_packages_private_names():
    problems = private_violations(all_imports())
    assert not problems, _report(problems)


def test_every_package_has_a_layer():
    for folder in sorted(p for p in ROOT.iterdir() if p.is_dir() and (p / "__init__.py").is_file()):
        assert layer_of(f"feedlog.{folder.name}") in LAYERS


# the checker itself: it finds what it is meant to find, wherever it hides

def _fake_tree(tmp_path: Path, files: dict[str, str]) -> Path:
    root = tmp_path / "feedlog"
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    for folder in [root, *(p for p in root.rglob("*") if p.is_dir())]:
        (folder / "__init__.py").touch()
    return root


def test_the_checker_finds_upward_imports_anywhere_in_a_module(tmp_path):
    root = _fake_tree(tmp_path, {
        "errors.py": "",
        "sim/a.py": (
            "from typing import TYPE_CHECKING\n"
            "from feedlog.errors import E\n"          # down: fine
            "if TYPE_CHECKING:\n"
            "    from feedlog.ingest.rec import R\n"  # up, line 4
            "def f():\n"
            "    import feedlog.align.x\n"            # up, line 6
            # up, up, and a file name that is no import
            "REG = {'a': 'feedlog.train.m:Cls', 'b': ('feedlog.viz.v', 'g'), 'c': 'feedlog.toml'}\n"
        ),
        "ingest/rec.py": "from . import helpers\nfrom ..sim.a import _hidden\n",  # same layer; lower but private
        "ingest/helpers.py": "",
        "align/x.py": "", "train/m.py": "", "viz/v.py": "",
    })
    imports = all_imports(root)
    up = layer_violations(imports, root)
    assert [p.split(": ")[0].split("/")[-1] for p in up] == ["a.py:4", "a.py:6", "a.py:7", "a.py:7"], up
    assert any("feedlog.train.m:Cls (train" in p for p in up) and any("feedlog.viz.v:g (viz" in p for p in up)
    private = private_violations(imports, root)
    assert len(private) == 1 and "rec.py:2" in private[0] and "_hidden" in private[0], private


def test_the_layer_order_is_the_documented_one():
    text = (SRC.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    assert " < ".join(LAYERS) in text, "docs/architecture.md must show the layer order tests/test_layers.py checks"
