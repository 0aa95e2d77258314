"""`feedlog.registry.Registry`: the one way named entries (models, shipped profiles) are added, found, listed."""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

from feedlog.errors import FeedlogError, ModelError, ProfileError
from feedlog.registry import Registry, unknown_name


class Thing:
    pass


class Other:
    pass


def test_order_lookup_and_the_unknown_name_error():
    reg: Registry[type] = Registry("widget", error=ModelError)
    reg.add("b", Thing)
    reg.add("a", Other)
    assert reg.names() == ["b", "a"] and list(reg) == ["b", "a"] and len(reg) == 2
    assert reg.get("a") is Other and reg["b"] is Thing and "a" in reg and "c" not in reg
    with pytest.raises(ModelError, match=r"^unknown widget 'c'; known: b, a$"):
        reg.get("c")


def test_a_name_taken_by_another_entry_is_refused_the_same_entry_is_not():
    reg: Registry[type] = Registry("widget")
    reg.add("x", Thing)
    assert reg.add("x", Thing) is Thing
    with pytest.raises(FeedlogError, match="widget name 'x' is already registered by Thing"):
        reg.add("x", Other)
    assert reg.get("x") is Thing


def test_load_runs_once_on_first_use_and_again_after_a_failure():
    calls = []

    def load(reg: Registry[int]) -> None:
        calls.append(1)
        if len(calls) == 1:
            reg.add("half", 1)
            raise ImportError("optional backend missing")
        reg.add("one", 1)
        assert reg.get("one") == 1   # a loader may look up what it added
    reg: Registry[int] = Registry("number", load=load, known_word="shipped", hint=" (or a path)")
    assert calls == []
    with pytest.raises(ImportError):
        reg.names()
    assert reg.names() == ["half", "one"] and reg.names() == ["half", "one"]
    assert len(calls) == 2
    with pytest.raises(FeedlogError, match=r"unknown number 'two'; shipped: half, one \(or a path\)$"):
        reg.get("two")


def test_threads_asking_at_once_wait_for_one_load_and_see_it_whole():
    # two LinuxCNC sessions recorded from two threads both looked up a shipped profile on first use: the
    # second saw the registry cleared of its loader but not yet filled ("shipped: " with nothing after it)
    started, calls = threading.Event(), []

    def load(reg: Registry[int]) -> None:
        calls.append(1)
        started.set()
        time.sleep(0.2)            # the other thread asks meanwhile
        reg.add("one", 1)
    reg: Registry[int] = Registry("number", load=load)
    with ThreadPoolExecutor(2) as pool:
        first = pool.submit(reg.get, "one")
        started.wait(5)
        second = pool.submit(reg.get, "one")
        assert (first.result(), second.result()) == (1, 1)
    assert calls == [1]


def test_unknown_name_is_the_error_of_the_string_registries_too():
    from feedlog.sim.mechanism import mechanism_class

    with pytest.raises(FeedlogError) as info:
        mechanism_class("no_such")
    from feedlog.sim.mechanism import REGISTRY
    assert str(info.value) == str(unknown_name("sim mechanism", "no_such", sorted(REGISTRY)))


def test_profiles_and_models_are_registries():
    from feedlog.profile import SHIPPED, load_profile, shipped_profiles
    from feedlog.train.registry import MODELS, make_model, model_names

    assert isinstance(SHIPPED, Registry) and isinstance(MODELS, Registry)
    assert shipped_profiles() == sorted(shipped_profiles()) and "linuxcnc-xyz" in shipped_profiles()
    assert load_profile("linuxcnc-xyz").name == "linuxcnc-xyz"
    with pytest.raises(ProfileError, match=r"unknown machine profile 'nope'; shipped: chien-ac, .* \(or give a path"):
        load_profile("nope")
    assert {"mlp", "hybrid", "bilstm-block", "bilstm-final"} <= set(model_names())
    with pytest.raises(ModelError, match=r"unknown model 'gpt'; known: .*mlp"):
        make_model("gpt")
    with pytest.raises(ModelError, match="model name 'mlp' is already registered by"):
        MODELS.add("mlp", Thing)


# -- lazy "module:attribute" entries: the registries of commands, readers, sources, mechanisms, families, stages


@pytest.fixture
def plugin_dir(tmp_path, monkeypatch):
    """A folder on sys.path for modules a test writes (each name unique to the test)."""
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


def test_a_lazy_entry_is_imported_on_first_get_and_listed_in_order(plugin_dir):
    import sys

    (plugin_dir / "reg_plugin_a.py").write_text("class Widget:\n    pass\n")
    reg = Registry.lazy("widget", {"z": "reg_plugin_a:Widget", "a": ("reg_plugin_a", "the module itself")})
    assert reg.names() == ["z", "a"] and "reg_plugin_a" not in sys.modules
    assert reg.target("z") == "reg_plugin_a:Widget" and reg.doc("a") == "the module itself" and reg.doc("z") == ""
    widget = reg.get("z")
    assert widget.__name__ == "Widget" and reg["a"] is sys.modules["reg_plugin_a"]
    reg.add_lazy("z", "reg_plugin_a:Widget")          # the same target again: nothing changes
    with pytest.raises(FeedlogError, match=r"^widget name 'z' is already registered by reg_plugin_a:Widget$"):
        reg.add_lazy("z", "reg_plugin_a:Other")


def test_the_unknown_name_lists_in_order_added_or_sorted():
    targets = {"b": "json:dumps", "a": "json:loads"}
    with pytest.raises(FeedlogError, match=r"^unknown widget 'c'; known: b, a$"):
        Registry.lazy("widget", targets).get("c")
    with pytest.raises(ModelError, match=r"^unknown widget 'c'; known: a, b$"):
        Registry.lazy("widget", targets, error=ModelError, sort_known=True).get("c")


@pytest.mark.parametrize(("target", "why"), [
    ("feedlog.no_such_module:Thing", r"feedlog.no_such_module cannot be imported: No module named "
                                     r"'feedlog.no_such_module'"),
    ("feedlog.no_such_package.mod:Thing", r"feedlog.no_such_package.mod cannot be imported: No module named "
                                          r"'feedlog.no_such_package'"),
    ("feedlog.units:no_such_function", r"feedlog.units has no no_such_function"),
])
def test_an_entry_naming_a_missing_module_or_attribute_is_one_error_naming_registry_and_entry(target, why):
    reg = Registry.lazy("widget", {"ok": "json:dumps", "broken": target}, error=ModelError)
    with pytest.raises(ModelError) as info:
        reg.get("broken")
    assert str(info.value) == f"widget 'broken': {target} is not available ({why.replace(chr(92), '')})"
    assert "\n" not in str(info.value) and info.value.__cause__ is None
    assert reg.get_optional("broken") is None and reg.get_optional("ok") is reg.get("ok")


def test_a_dependency_missing_inside_an_existing_module_is_not_taken_for_a_missing_entry(plugin_dir):
    (plugin_dir / "reg_plugin_b.py").write_text("import reg_no_such_dependency_b\n")
    reg = Registry.lazy("widget", {"b": "reg_plugin_b:Thing"})
    with pytest.raises(ModuleNotFoundError, match="reg_no_such_dependency_b"):
        reg.get("b")
    with pytest.raises(ModuleNotFoundError, match="reg_no_such_dependency_b"):
        reg.get_optional("b")


def test_copy_keeps_settings_and_swaps_targets_without_touching_the_original():
    reg = Registry.lazy("widget", {"b": "json:dumps", "a": "json:loads"}, error=ModelError, sort_known=True)
    other = reg.copy({"a": "json:no_such"})
    assert other.names() == ["b", "a"] and reg.target("a") == "json:loads"
    with pytest.raises(ModelError, match=r"^widget 'a': json:no_such is not available \(json has no no_such\)$"):
        other.get("a")
    with pytest.raises(ModelError, match=r"^unknown widget 'c'; known: a, b$"):
        other.get("c")


def _real_registries():
    from feedlog.cli import COMMANDS
    from feedlog.diagnose.hypothesis import FAMILIES
    from feedlog.ingest.cli_record import SOURCES
    from feedlog.ingest.readers import READERS
    from feedlog.sim.mechanism import REGISTRY
    from feedlog.viz.stages import STAGE_FUNCTIONS

    return {"command": COMMANDS, "reader": READERS, "record source": SOURCES, "sim mechanism": REGISTRY,
            "hypothesis family": FAMILIES, "stage function": STAGE_FUNCTIONS}


def test_every_lazy_registry_is_one_registry_and_every_target_resolves():
    import importlib.util

    for what, reg in _real_registries().items():
        assert isinstance(reg, Registry) and reg.what == what and len(reg) >= 4, what
        for name in reg:
            if what == "command":   # found, not imported (tests/test_cli_vocabulary.py configures each one)
                assert importlib.util.find_spec(reg.target(name)) is not None, name
            else:
                assert reg.get(name) is not None, f"{what} {name!r}"


@pytest.mark.parametrize("what", ["reader", "record source", "sim mechanism", "hypothesis family",
                                  "stage function"])
def test_a_broken_entry_of_each_real_registry_names_the_registry_and_the_entry(what):
    reg = _real_registries()[what]
    name = reg.names()[0]
    broken = reg.copy({name: "feedlog.no_such_module:Thing"})
    if what == "record source":          # an absent source is left out of `feedlog record --source`
        assert broken.get_optional(name) is None
    with pytest.raises(FeedlogError) as info:
        broken.get(name)
    message = str(info.value)
    if what == "stage function":         # the demo's report line: which function, and why
        assert message == ("feedlog.no_such_module.Thing is not available (feedlog.no_such_module cannot be "
                           "imported: No module named 'feedlog.no_such_module')")
    else:
        assert message.startswith(f"{what} {name!r}: feedlog.no_such_module:Thing is not available ("), message


def test_a_command_whose_module_is_absent_is_one_line_and_exit_2(monkeypatch, capsys):
    from feedlog import cli

    monkeypatch.setattr(cli, "COMMANDS", cli.COMMANDS.copy({"info": "feedlog.ingest.no_such_cli"}))
    assert cli.main(["info", "x.mcap"]) == 2
    assert capsys.readouterr().err == "feedlog info: error: feedlog info is not available in this version\n"
