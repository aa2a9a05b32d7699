"""The key reference (docs/reference.md, jitterfmu keys) lists every key the parsers of
scenario, campaign, uncertainty and sweep files accept, with its type, unit, default,
allowed values and an example."""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import pytest

from orchestrator import schema
from orchestrator.campaign import campaign_from_dict
from orchestrator.cli import main
from orchestrator.scenario import scenario_from_dict
from tests.orchestrator.test_campaign import campaign_data

ROOT = Path(__file__).resolve().parents[2]


def every_table_used() -> tuple[dict, dict]:
    """A scenario and a campaign that use every table the parsers know."""
    camp = campaign_data(n_events=2, sweep=True)
    base = camp["campaign"]["scenario"]
    base["fmus"]["sc"]["rate_hz"] = 1000.0
    del base["fmus"]["sc"]["period"]
    base["connections"] = [{"from": "dist.y", "to": "sc.u", "gain": 2.0}]
    base["actions"] = [{"time": 0.5, "set": {"ctrl.gain": 1.0}}]
    camp["wheel_sweeps"] = [{"instance": "dist", "rpm": [0.0, 3000.0], "points": 3}]
    camp["uncertainty"] = {"samples": 10, "parameters": [
        {"kind": "amplitude", "instances": ["dist"], "distribution": "uniform",
         "low": 0.9, "high": 1.1}]}
    return copy.deepcopy(base), camp


def test_every_key_a_parser_accepts_is_in_the_reference(monkeypatch):
    """The parsers' key checks are recorded while they read files using every table;
    each set of keys they accept must be one table of the reference, and every table
    of the reference must be one a parser checks."""
    import orchestrator.campaign.spec_base as spec_base
    import orchestrator.scenario.toml as toml_parser

    accepted = []
    for module in (toml_parser, spec_base):
        real = module.check_keys

        def recording(table, allowed, what, *args, _real=real, **kwargs):
            accepted.append((what, tuple(allowed)))
            return _real(table, allowed, what, *args, **kwargs)
        monkeypatch.setattr(module, "check_keys", recording)
    scenario, campaign = every_table_used()
    scenario_from_dict(scenario)
    campaign_from_dict(campaign)
    documented = {frozenset(k.name for k in t.keys): t.name
                  for _, tables in schema.FILES.values() for t in tables if t.keys}
    undocumented = [(what, keys) for what, keys in accepted
                    if frozenset(keys) not in documented]
    assert not undocumented, undocumented
    checked = {documented[frozenset(keys)] for _, keys in accepted}
    assert checked == set(documented.values())


def test_a_key_added_to_a_parser_alone_fails_the_check(monkeypatch):
    """The check above bites: a parser that accepts one key more than the reference."""
    import orchestrator.campaign.spec as spec

    monkeypatch.setitem(spec._ITEM_KEYS, "metrics", spec._ITEM_KEYS["metrics"] + ("lag",))
    with pytest.raises(AssertionError, match="lag"):
        test_every_key_a_parser_accepts_is_in_the_reference(monkeypatch)


def test_every_key_has_a_type_a_default_and_a_toml_example():
    for kind, (what, tables) in schema.FILES.items():
        assert what
        for t in tables:
            assert t.text and (t.keys or t.names), t.name
            for k in t.keys:
                assert k.type and k.text and k.default and k.example, (t.name, k.name)
                assert k.name in k.example, (t.name, k.name)
                tomllib.loads(k.example)          # valid TOML
            if t.keys and not t.name.startswith("("):
                tomllib.loads(t.example())        # and the table composed of them


def test_the_reference_page_is_the_generated_one():
    page = (ROOT / "docs" / "reference.md").read_text(encoding="utf-8")
    assert page == schema.markdown(), ("docs/reference.md is stale; write it again: "
                                       ".venv/bin/jitterfmu keys --markdown > docs/reference.md")


def test_the_keys_command_prints_one_kind(capsys):
    assert main(["keys", "campaign"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("CAMPAIGN FILE: ")
    assert "  verify          integer; default: 2; >= 0" in out
    assert "[[uncertainty.parameters]]" not in out
