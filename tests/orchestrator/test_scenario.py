"""Scenario parsing (pure data, no FMUs)."""

from fractions import Fraction

import pytest
from hypothesis import given, strategies as st

from orchestrator.scenario import (
    ScenarioError,
    load_scenario,
    parse_override,
    scenario_from_dict,
)

TOML = """
[experiment]
stop = 10.0
output_interval = 1e-3
algorithm = "gauss-seidel"

[fmus.structure]
fmu = "truss10_structure"
period = 1e-3

[fmus.ctrl_diag]
fmu = "controller"
rate_hz = 250
parameters = { design = "truss10_strain_diag" }

[[connections]]
from = "structure.strain_diag"
to = "ctrl_diag.y"
gain = 2.0

[[actions]]
time = 2.4
set = { "ctrl_diag.enable" = true }

[record]
variables = ["structure.strain_diag", "ctrl_diag.u"]
"""


def _base():
    return {
        "experiment": {"stop": 1.0, "output_interval": 1e-3},
        "fmus": {"a": {"fmu": "x", "period": 1e-3}, "b": {"fmu": "y", "period": 2e-3}},
        "connections": [{"from": "a.y", "to": "b.u"}],
    }


def test_toml_is_parsed_into_frozen_dataclasses(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(TOML)
    s = load_scenario(path)
    assert s.experiment.stop == 10 and s.experiment.output_interval == Fraction(1, 1000)
    assert [i.name for i in s.instances] == ["structure", "ctrl_diag"]
    assert s.instance("ctrl_diag").period == Fraction(1, 250)
    assert s.instance("ctrl_diag").parameters["design"] == "truss10_strain_diag"
    c = s.connections[0]
    assert (c.source, c.source_var, c.target, c.target_var, c.gain) == (
        "structure", "strain_diag", "ctrl_diag", "y", 2.0)
    assert s.actions[0].time == Fraction(12, 5)
    assert s.actions[0].values[("ctrl_diag", "enable")] is True
    assert s.record == ("structure.strain_diag", "ctrl_diag.u")
    assert s.base_dir == tmp_path
    with pytest.raises(AttributeError):
        s.experiment.stop = 3  # frozen
    with pytest.raises(TypeError):
        s.instance("structure").parameters["x"] = 1  # read-only mapping


def test_dict_round_trip_keeps_exact_times_and_digest():
    s = scenario_from_dict(_base())
    again = scenario_from_dict(s.to_dict())
    assert again == s
    assert again.digest() == s.digest()
    assert s.with_overrides({"a.k": 2.0}).digest() != s.digest()


def test_overrides_from_strings_and_dicts():
    s = scenario_from_dict(_base())
    t = s.with_overrides(["a.k=1e-3", "b.flag=true", "b.name=hello", 'b.q="x y"'])
    assert t.instance("a").parameters["k"] == 1e-3
    assert t.instance("b").parameters["flag"] is True
    assert t.instance("b").parameters["name"] == "hello"
    assert t.instance("b").parameters["q"] == "x y"
    assert s.instance("a").parameters == {}  # original untouched
    with pytest.raises(ScenarioError, match=r"'c.k' names no instance"):
        s.with_overrides({"c.k": 1})
    with pytest.raises(ScenarioError, match="instance.variable=value"):
        parse_override("a.k")


def test_with_experiment_changes_stop_and_algorithm():
    s = scenario_from_dict(_base()).with_experiment(stop=0.5, algorithm="jacobi")
    assert s.experiment.stop == Fraction(1, 2) and s.experiment.algorithm == "jacobi"
    with pytest.raises(ScenarioError, match="not after"):
        s.with_experiment(stop=-1.0)


@pytest.mark.parametrize(
    "mutate, match",
    [
        (lambda d: d["connections"].append({"from": "aa.y", "to": "b.u"}),
         r"unknown instance 'aa' \(did you mean 'a'"),
        (lambda d: d["fmus"]["a"].update(period=-1e-3), "period of instance 'a' is -0.001 s"),
        (lambda d: d["fmus"]["a"].update(rate_hz=10), "exactly one of 'period'"),
        (lambda d: d["experiment"].update(output_interval=0), "output_interval is 0.0 s"),
        (lambda d: d["experiment"].update(stop=-1), r"stop \(-1.0 s\) is not after"),
        (lambda d: d["experiment"].update(algorithm="jakobi"), "did you mean 'jacobi'"),
        (lambda d: d["experiment"].update(stp=1), "unknown key 'stp'"),
        (lambda d: d["fmus"]["a"].update(perod=1), "unknown key 'perod'"),
        (lambda d: d.update(record={"variables": ["bb.x"]}), "unknown instance 'bb'"),
        (lambda d: d.update(record={"variables": ["a.x", "a.x"]}), "more than once"),
        (lambda d: d.update(actions=[{"time": 1, "set": {"q.x": 1}}]), "unknown instance 'q'"),
        (lambda d: d["connections"].append({"from": "a", "to": "b.u"}), "instance.variable"),
        (lambda d: d.update(fmus={}), "no FMU instances"),
    ],
)
def test_structural_errors_are_one_clear_sentence(mutate, match):
    d = _base()
    mutate(d)
    with pytest.raises(ScenarioError, match=match):
        scenario_from_dict(d)


def test_malformed_toml_names_file_and_line(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("[experiment]\nstop = 1.0\noutput_interval = = 1\n")
    with pytest.raises(ScenarioError, match=r"bad.toml.*line 3"):
        load_scenario(path)
    with pytest.raises(ScenarioError, match="does not exist"):
        load_scenario(tmp_path / "missing.toml")


@given(st.one_of(st.floats(allow_nan=False, allow_infinity=False), st.integers(-10**9, 10**9),
                 st.booleans(), st.text(alphabet="abcxyz_ ", min_size=1)))
def test_override_values_round_trip(value):
    import tomli_w

    text = tomli_w.dumps({"v": value})[4:].strip()
    key, parsed = parse_override(f"a.b={text}")
    assert key == "a.b" and parsed == value and type(parsed) is type(value)


def test_a_folder_or_a_binary_file_as_scenario_is_named(tmp_path):
    from orchestrator.scenario import ScenarioError, load_scenario

    with pytest.raises(ScenarioError, match=r"is a folder; expected a TOML scenario file"):
        load_scenario(tmp_path)
    binary = tmp_path / "run.toml"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe\x00binary")
    with pytest.raises(ScenarioError, match=r"run\.toml' is not text \(not UTF-8\)"):
        load_scenario(binary)


_leaf = st.one_of(st.none(), st.booleans(), st.integers(-3, 10**6), st.floats(allow_nan=True),
                  st.text(max_size=8))
_tree = st.recursive(_leaf, lambda inner: st.one_of(
    st.lists(inner, max_size=3),
    st.dictionaries(st.sampled_from(["fmu", "period", "parameters", "from", "to", "gain",
                                     "offset", "stop", "start", "output_interval",
                                     "algorithm", "variables", "time", "set", "x"]),
                    inner, max_size=4)), max_leaves=12)


@given(st.dictionaries(st.sampled_from(["experiment", "fmus", "connections", "record",
                                        "actions", "bogus"]), _tree, max_size=5))
def test_any_scenario_layout_is_a_scenario_or_one_clear_error(data):
    # a mangled scenario file is a Scenario or one ScenarioError sentence, never another
    # exception (the TOML layout as a dict: what tomllib gives the loader)
    mixed = {**_base(), **data}
    try:
        scenario_from_dict(mixed)
    except ScenarioError as exc:
        assert "\n" not in str(exc) and len(str(exc)) < 2000
