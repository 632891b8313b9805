"""The registry behind `make_policy` and `load_variant`: names added without editing ToddlerBot, factories imported
only when their name is used, a name registered once, unknown and duplicate names refused in one line."""

import sys

import pytest

from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies import make_policy, policy_names, register_policy
from toddlerbot.policies.stand import StandPolicy
from toddlerbot.registry import Registry
from toddlerbot.robot.description import load_variant, register_variant, variant_names
from toddlerbot.runtime.commands import CommandSchedule
from toddlerbot.runtime.runner import run_policy
from toddlerbot.sim.mujoco_robot import MuJoCoRobot

SCALES = """
calls = []


def scale(x, factor=2):
    calls.append(x)
    return factor * x
"""


@pytest.fixture
def scales_module(tmp_path, monkeypatch):
    """A module `reg_scales` on the path, not yet imported (and forgotten again after the test)."""
    (tmp_path / "reg_scales.py").write_text(SCALES)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "reg_scales", raising=False)
    yield "reg_scales"
    sys.modules.pop("reg_scales", None)


def test_a_string_factory_is_imported_on_first_use_only(scales_module):
    registry = Registry("scale")
    registry.register("double", f"{scales_module}:scale")
    assert registry.names() == ("double",) and "double" in registry
    assert scales_module not in sys.modules  # registering and listing import nothing
    assert registry.get("double")(21) == 42
    module = sys.modules[scales_module]
    assert registry.get("double")(5) == 10 and module.calls == [21, 5]  # imported once, the same function


def test_callables_and_the_decorator_register_in_order():
    registry = Registry("scale")
    registry.register("triple", lambda x: 3 * x)

    @registry.register("square")
    def square(x):
        return x * x

    assert square(4) == 16  # the decorator hands the function back
    assert registry.names() == ("triple", "square")
    assert [registry.get(name)(5) for name in registry.names()] == [15, 25]


def test_a_name_is_registered_once():
    registry = Registry("scale")
    registry.register("double", "reg_scales:scale")
    with pytest.raises(ToddlerbotError) as exc:
        registry.register("double", lambda x: 2 * x)
    assert str(exc.value) == "scale 'double' is already registered (to reg_scales:scale)"
    assert registry.names() == ("double",)


def test_unknown_names_and_bad_targets_are_one_line(scales_module):
    registry = Registry("scale")
    registry.register("double", f"{scales_module}:scale")
    registry.register("half", f"{scales_module}:halve")
    registry.register("gone", "reg_no_such_module:scale")
    with pytest.raises(ToddlerbotError) as unknown:
        registry.get("quadruple")
    assert str(unknown.value) == "unknown scale 'quadruple'; expected one of double, half, gone"
    with pytest.raises(ToddlerbotError) as missing:
        registry.get("half")
    assert str(missing.value) == "scale 'half': reg_scales has no attribute 'halve'"
    with pytest.raises(ToddlerbotError, match=r"^scale 'gone': cannot import reg_no_such_module \(No module"):
        registry.get("gone")
    for name, target, message in (("two words", "m:f", "scale name 'two words': expected letters, digits"),
                                  ("double2", "reg_scales.scale", "scale 'double2': 'reg_scales.scale' is not "
                                                                  "'module:attribute'"),
                                  ("double3", 2.0, "scale 'double3': expected a callable or 'module:attribute', "
                                                   "got float")):
        with pytest.raises(ToddlerbotError) as bad:
            registry.register(name, target)
        assert str(bad.value).startswith(message) and "\n" not in str(bad.value)
    assert registry.names() == ("double", "half", "gone")


def _install(site, group: str, points: dict[str, str]) -> None:
    """What pip writes for a package declaring entry points: a dist-info folder with entry_points.txt."""
    dist_info = site / "reg_plugin-1.0.dist-info"
    dist_info.mkdir()
    (dist_info / "METADATA").write_text("Metadata-Version: 2.1\nName: reg-plugin\nVersion: 1.0\n")
    (dist_info / "entry_points.txt").write_text(f"[{group}]\n" + "".join(f"{k} = {v}\n" for k, v in points.items()))


def test_installed_entry_points_are_listed_without_importing(scales_module, tmp_path):
    _install(tmp_path, "reg.scales", {"double": f"{scales_module}:scale"})
    registry = Registry("scale", entry_point_group="reg.scales")
    registry.register("triple", lambda x: 3 * x)
    assert registry.names() == ("triple", "double")  # the plugins are read on first use, after the built-ins
    assert scales_module not in sys.modules
    assert registry.get("double")(4) == 8


def test_an_entry_point_cannot_take_a_registered_name(scales_module, tmp_path):
    _install(tmp_path, "reg.scales", {"triple": f"{scales_module}:scale"})
    registry = Registry("scale", entry_point_group="reg.scales")
    registry.register("triple", "reg_builtin:triple")
    with pytest.raises(ToddlerbotError) as exc:
        registry.names()
    assert str(exc.value) == ("scale 'triple' from reg-plugin (reg_scales:scale) is already registered "
                              "(to reg_builtin:triple)")


def test_make_policy_builds_a_registered_policy_and_refuses_built_in_names(restored_registries):
    robot = MuJoCoRobot()
    built = []

    class Sway(StandPolicy):
        name = "sway"

    def sway(robot, motion=None):  # names --motion, so it receives it; --weights it does not name
        built.append(motion)
        return Sway(robot)

    register_policy("sway", sway)
    assert policy_names() == ("stand", "replay", "walk-zmp", "walk-rl", "dp", "get-up", "track", "sway")
    policy = make_policy("sway", robot, motion="wave", weights="ignored.npz")
    assert built == ["wave"] and policy.name == "sway"
    result = run_policy(robot, policy, CommandSchedule.parse("0:0,0,0"), 1.0)
    assert not result.fell and len(result.log.time) == 50
    with pytest.raises(ToddlerbotError) as exc:
        register_policy("stand", sway)
    assert str(exc.value) == "policy 'stand' is already registered (to toddlerbot.policies.stand:StandPolicy)"
    with pytest.raises(ToddlerbotError) as unknown:
        make_policy("dance", robot)
    assert str(unknown.value) == ("unknown policy 'dance'; expected one of stand, replay, walk-zmp, walk-rl, dp, "
                                  "get-up, track, sway")


def test_a_registered_variant_builds_its_base_and_spec_variant(restored_registries):
    register_variant("gripper-fixed", lambda description: (description.with_variant("gripper"), "fixed"))
    assert variant_names() == ("floating", "fixed", "gripper", "gripper-fixed")
    floating, floating_base = load_variant("floating")
    gripper, base = load_variant("gripper-fixed")
    assert (floating_base, base) == ("floating", "fixed")
    assert len(gripper.motor_names) == len(floating.motor_names) + 2  # two gripper motors
    assert gripper.model(base, scene=False).nq == gripper.model("floating", scene=False).nq - 7  # no free joint
    with pytest.raises(ToddlerbotError) as exc:
        load_variant("wings")
    assert str(exc.value) == "unknown variant 'wings'; expected one of floating, fixed, gripper, gripper-fixed"
