"""Each engine's settings are declared once (loopcheck.settings.option) and read three ways: its table
of the scene file, its command-line flags and the help. The same value given by the table and by
the flag gives the same settings; every option has a flag and a key (or says why not); a bad
value names the key. (Planted: dropping ``sample_interval``'s flag from ``add_flags`` fails
test_a_value_reads_the_same_from_the_table_and_the_flag; a table value passed through
unchecked fails test_a_bad_table_value_names_its_key.)"""

from __future__ import annotations

import warnings

import pytest

from loopcheck.compare import cli
from loopcheck.compare.settings import engine_settings
from loopcheck.errors import IgnoredSettingWarning
from loopcheck.registry import ENGINES, engine_of
from loopcheck.scene import SceneError
from loopcheck.scenefile import scene_from_dict
from loopcheck.settings import given_flags, options

from helpers import seed_dict

# A value other than the default for every option of every engine, as the scene file and the
# command line write it; the engine's command (loopcheck reduced, loopcheck mujoco) takes the flags.
VALUES = {
    "reduced": {"method": ("rkn4", ["rkn4"]), "rtol": (1e-6, ["1e-6"]), "step": (2.5e-4, ["2.5e-4"]),
                "sample_interval": (5e-4, ["5e-4"])},
    "mujoco": {"integrator": ("euler", ["euler"]), "timestep": (5e-4, ["5e-4"]),
               "solref": ([0.004, 0.5], ["0.004", "0.5"]),
               "solimp": ([0.95, 0.99, 0.002, 0.4, 3.0], ["0.95", "0.99", "0.002", "0.4", "3"]),
               "iterations": (7, ["7"]), "tolerance": (1e-9, ["1e-9"]), "refsafe": (False, []),
               "diagexact": (True, []), "max_constraint_violation": (1e-4, ["1e-4"]),
               "max_energy_residual": (1e-2, ["1e-2"])},
    "pin": {"method": ("radau", ["radau"]), "rtol": (1e-9, ["1e-9"]), "atol": (1e-11, ["1e-11"]),
            "sample_interval": (5e-4, ["5e-4"]), "baumgarte_kp": (50.0, ["50"]), "baumgarte_kd": (10.0, ["10"]),
            "proximal_mu": (1e-10, ["1e-10"]), "proximal_accuracy": (1e-10, ["1e-10"]),
            "proximal_iterations": (5, ["5"]), "max_evaluations": (1000, ["1000"]),
            "max_constraint_violation": (1e-5, ["1e-5"]), "max_energy_residual": (1e-5, ["1e-5"])},
}
# the ports take the MuJoCo-family model's options, but for what they do not implement (REFUSED)
VALUES["mjx"] = {**VALUES["mujoco"], "precision": ("float32", ["float32"])}
VALUES["mjwarp"] = dict(VALUES["mujoco"])
REFUSED = {"mjx": {"diagexact"}, "mjwarp": {"diagexact"}}  # only the default is valid: a value is refused
for _engine, _names in REFUSED.items():
    for _name in _names:
        del VALUES[_engine][_name]
API_ONLY = {"reduced": {"check_error"}, "mujoco": set(), "pin": set(), "mjx": set(), "mjwarp": set()}  # neither a key nor a flag: cost studies set it


def _flag(name: str, value) -> list[str]:
    word = name.replace("_", "-")
    return [f"--no-{word}"] if value is False else [f"--{word}"]


def test_every_option_is_covered_here():
    for name, engine in ENGINES.items():
        declared = {o.name for o in options(engine.settings)}
        assert declared == set(VALUES[name]) | API_ONLY[name] | REFUSED.get(name, set()), name
        assert all(o.flag == o.table == (o.name not in API_ONLY[name]) for o in options(engine.settings))


@pytest.mark.parametrize("engine, option", [(e, o) for e in VALUES for o in VALUES[e]])
def test_a_value_reads_the_same_from_the_table_and_the_flag(engine, option):
    value, words = VALUES[engine][option]
    base = {"method": "rkn4"} if engine == "reduced" and option == "step" else {}
    data = seed_dict()
    data[engine] = {**base, option: value}
    from_table = scene_from_dict(data)
    argv = [engine, *_flag(option, value), *words] + (["--method", "rkn4"] if base else [])
    args = cli.build_parser().parse_args(argv)
    plain = scene_from_dict(seed_dict())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IgnoredSettingWarning)
        by_table = engine_settings(engine, from_table)
        by_flag = engine_settings(engine, plain, **given_flags(args, ENGINES[engine].settings))
        default = engine_settings(engine, plain)
    expected = tuple(value) if isinstance(value, list) else value
    assert getattr(by_table, option) == getattr(by_flag, option) == expected
    assert by_table == by_flag and by_table != default
    assert engine_of(by_flag) is ENGINES[engine]


@pytest.mark.parametrize("engine, key, value, words", [
    ("mujoco", "timestep", "1ms", "'mujoco.timestep' must be a number, got a string"),
    ("mujoco", "iterations", 1.5, "'mujoco.iterations' must be a whole number from 1 to 10000"),
    ("mujoco", "refsafe", 1, "'mujoco.refsafe' must be true or false, got an integer"),
    ("mujoco", "solimp", [0.9, 0.95], "'mujoco.solimp' must be an array of 5 numbers"),
    ("mujoco", "integrator", "rk45", "'mujoco.integrator' must be one of euler, implicit, implicitfast, rk4"),
    ("mujoco", "stepsize", 1e-3, "unknown key 'mujoco.stepsize'"),
    ("reduced", "rtol", -1e-9, "'reduced.rtol' must be positive"),
    ("reduced", "step", 2.0, "'reduced.step' = 2 is out of range"),
    ("reduced", "sample_interval", 0.9, "'reduced.sample_interval' = 0.9 s is longer than 'simulation.horizon'"),
])
def test_a_bad_table_value_names_its_key(engine, key, value, words):
    data = seed_dict()
    data[engine] = {key: value}
    data["simulation"]["horizon"] = 0.5
    with pytest.raises(SceneError) as caught:
        scene_from_dict(data)
    assert words in str(caught.value)


@pytest.mark.parametrize("engine, key, value, words", [
    ("mjx", "diagexact", True, "[mjx] diagexact: MJX does not implement MuJoCo's exact constraint diagonal"),
    ("mjwarp", "diagexact", True, "[mjwarp] diagexact: MJWarp does not implement MuJoCo's exact constraint"),
    ("mjx", "integrator", "implicit", "'mjx.integrator' must be one of euler, implicitfast, rk4"),
])
def test_what_a_port_does_not_implement_is_refused_naming_it(engine, key, value, words):
    data = seed_dict()
    data[engine] = {key: value}
    with pytest.raises(SceneError) as caught:
        engine_settings(engine, scene_from_dict(data, source="my.toml"))
    assert words in str(caught.value) and "\n" not in str(caught.value)


def test_a_table_the_settings_refuse_names_the_file_and_table():
    data = seed_dict()
    data["mujoco"] = {"solimp": [0.99, 0.9, 0.001, 0.5, 2.0]}  # dmin > dmax: a rule between values
    scene = scene_from_dict(data, source="my.toml")
    with pytest.raises(SceneError, match=r"^my.toml: \[mujoco\] solimp dmin, dmax must satisfy"):
        engine_settings("mujoco", scene)


def test_every_flag_is_in_the_help_of_each_command_that_runs_the_engine():
    parser = cli.build_parser()
    commands = next(a for a in parser._actions if a.dest == "command").choices
    for command, engine, prefix in (("reduced", "reduced", ""), ("mujoco", "mujoco", ""),
                                    ("run", "reduced", cli.REFERENCE_PREFIX), ("run", "mujoco", ""),
                                    ("check", "reduced", cli.REFERENCE_PREFIX), ("check", "mujoco", "")):
        flags = {f for a in commands[command]._actions for f in a.option_strings}
        for o in options(ENGINES[engine].settings):
            if o.flag:
                word = f"{prefix}{o.name.replace('_', '-')}"
                assert (f"--{word}" if not (o.kind == "bool" and o.default) else f"--no-{word}") in flags, \
                    (command, o.name)


def test_the_impedance_limits_written_in_the_settings_are_mujocos():
    import mujoco

    from loopcheck.reference_models.settings import MAX_IMPEDANCE, MIN_IMPEDANCE

    assert (MIN_IMPEDANCE, MAX_IMPEDANCE) == (mujoco.mjMINIMP, mujoco.mjMAXIMP)


def test_the_ports_take_the_scenes_mujoco_settings_under_their_own():
    """MJX and MJWarp run the MuJoCo engine's model with the same settings: a scene's [mujoco]
    model options are their defaults, their own table and flags come over them, and an engine
    that is not a MuJoCo port (pin) takes none of them. (Planted: no inheritance fails the first
    assertion; inheritance over the port's own table fails the second.)"""
    data = seed_dict()
    data["mujoco"] = {"timestep": 2.5e-4, "iterations": 7}
    data["mjwarp"] = {"timestep": 5e-4}
    scene = scene_from_dict(data)
    mjx = engine_settings("mjx", scene)
    assert (mjx.timestep, mjx.iterations) == (2.5e-4, 7)
    assert (engine_settings("mjwarp", scene).timestep, engine_settings("mjwarp", scene).iterations) == (5e-4, 7)
    assert engine_settings("mjx", scene, timestep=1e-3).timestep == 1e-3
    data["mujoco"] = {"integrator": "implicit"}  # MuJoCo has it, MJX does not: the message says where it came from
    with pytest.raises(SceneError, match=r"^<memory>: \[mjx\] \(with \[mujoco\] integrator\)"):
        engine_settings("mjx", scene_from_dict(data))
