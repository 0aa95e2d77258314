"""`feedlog.registry.Registry`: the one way named entries (models, shipped profiles) are added, found, listed."""

from __future__ import annotations

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
