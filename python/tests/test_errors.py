"""Scenario errors raise gripsim.ScenarioError naming the file, key and value."""

import pytest

import gripsim
from conftest import scenario


def test_a_bad_key_raises_with_file_key_and_value():
    path = scenario("jaw-grasp-hold")
    sc = gripsim.Scenario.load(path)
    with pytest.raises(gripsim.ScenarioError) as e:
        sc.set("solve.dtt", 1e-4)
    err = e.value
    assert err.file == str(path)
    assert err.key == "solve.dtt"
    assert err.value == "0.0001"
    assert "`dt`" in err.hint
    assert isinstance(err, ValueError)
    # The scenario is as it was.
    assert sc.sets == []


def test_a_bad_value_raises_with_file_key_and_value():
    sc = gripsim.Scenario.load(scenario("jaw-grasp-hold"))
    with pytest.raises(gripsim.ScenarioError) as e:
        sc.set("solve.dt", -1.0)
    assert e.value.key == "solve.dt"
    assert e.value.value == "-1.0"


def test_a_bad_file_names_the_key_and_value():
    text = scenario("jaw-grasp-hold").read_text().replace("[solve]", "[solve]\nbogus = 3", 1)
    with pytest.raises(gripsim.ScenarioError) as e:
        gripsim.Scenario.from_toml(text, name="mine.toml")
    assert e.value.file == "mine.toml"
    assert e.value.key == "solve.bogus"


def test_a_missing_file_raises_a_scenario_error(tmp):
    with pytest.raises(gripsim.ScenarioError) as e:
        gripsim.Scenario.load(tmp / "nope.toml")
    assert "nope.toml" in e.value.file
