"""Campaign files that used to run a wrong case under a right label, or hang.

A configuration that sets a swept parameter ran its cases with the swept value under
its own name; two sweeps of one parameter labelled "p=8.0, p=9.0" and ran 9.0 only; a
sweep of 10**6 values printed nothing for minutes while its cases filled memory.  Each
is refused before any case runs, in one sentence naming the file and the entries.
"""

from __future__ import annotations

import pytest

from orchestrator.campaign import CampaignError
from orchestrator.campaign.cases import load_campaign
from orchestrator.campaign.spec import MAX_CASES

from .test_campaign import campaign_data
from .test_campaign_hardening import _toml


def _refused(tmp_path, data, message):
    path = _toml(tmp_path, data)
    with pytest.raises(CampaignError, match=message) as info:
        load_campaign(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_a_configuration_that_sets_a_swept_parameter_is_refused(tmp_path):
    data = campaign_data()
    data["sweeps"] = [{"parameter": "ctrl.gain", "values": [1.0, 2.0]}]
    _refused(tmp_path, data, r"configuration 'isolation off' sets 'ctrl.gain', which a "
                             r"\[\[sweeps\]\] entry sweeps")


def test_an_event_that_sets_a_swept_parameter_is_refused(tmp_path):
    data = campaign_data()
    data["sweeps"] = [{"parameter": "dist.frequency", "values": [3.0, 4.0]}]
    _refused(tmp_path, data, r"event 'event0' sets 'dist.frequency'")


def test_two_sweeps_of_one_parameter_are_refused(tmp_path):
    data = campaign_data(sweep=True)
    data["sweeps"].append({"parameter": "sc.mass", "values": [3.0]})
    _refused(tmp_path, data, r"sweeps 1 and 2 both sweep 'sc.mass'")


def test_a_sweep_of_other_parameters_still_expands_every_value(tmp_path):
    """The refusals leave a legal campaign alone: 3 events x 2 configurations x 2 masses."""
    camp = load_campaign(_toml(tmp_path, campaign_data(sweep=True)))
    assert len(camp.cases) == 12
    assert {c.sweep for c in camp.cases} == {"sc.mass=1.0", "sc.mass=2.0"}


def test_a_campaign_of_more_cases_than_the_limit_is_refused_at_once(tmp_path):
    """10**6 sweep values: one sentence (the count), not minutes of silent expansion."""
    data = campaign_data(n_events=1)
    data["sweeps"] = [{"parameter": "sc.mass", "values": [1.0 + i for i in range(MAX_CASES)]}]
    _refused(tmp_path, data, rf"expands to {2 * MAX_CASES} cases .* more than the "
                             rf"{MAX_CASES}")
