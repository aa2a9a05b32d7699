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


# ----------------------------------------------------------------------------- [uncertainty]


def _unc(**item):
    from .test_uncertainty import _campaign
    p = {"name": "g", "kind": "gain", "instances": ["ctrl_diag"], "distribution": "uniform",
         "low": 0.5, "high": 1.5, **item}
    return _campaign({"samples": 8, "seed": 1, "parameters": [p]})


@pytest.mark.parametrize("item, message", [
    ({"kind": "modal_frequency", "per_mode": "false", "instances": []},
     r"per_mode is 'false'; expected true or false \(without quotes\)"),
    ({"low": True}, r"low is True; expected a number"),
    ({"low": "abc"}, r"low is 'abc'; expected a number"),
    ({"low": [1]}, r"low is \[1\]; expected a number"),
    ({"low": -1e308, "high": 1e308}, r"is uniform on \[-1e\+308, 1e\+308\], wider than a float"),
    ({"distribution": "normal", "mean": 1.0, "std": float("nan")},
     r"std is nan; expected a finite number"),
    ({"kind": "modal_frequency", "instances": [], "band": [0, "x"]},
     r"band is \[0, 'x'\]; expected \[low, high\] in Hz"),
])
def test_ill_typed_uncertainty_values_are_one_sentence(tmp_path, item, message):
    _refused(tmp_path, _unc(**item), r"uncertain parameter 1 " + message)


def test_a_draw_beyond_a_float_is_refused_and_a_huge_one_counts_as_unstable(
        tmp_path, suite_fmus, suite_fmu_dir):
    """A lognormal gain of sigma 300 draws inf: one sentence before any sample runs.
    Sigma 30 draws gains up to ~1e30 whose loop maps overflow: those samples count as
    unstable (and past every limit) and the run finishes instead of aborting."""
    import json

    import numpy as np

    from orchestrator.campaign import LinearRunner, campaign_from_dict, run_campaign
    from orchestrator.campaign.montecarlo import run_uncertainty

    from .test_truss10_campaign import FMUS
    suite_fmus(*FMUS)

    def run(sigma, name):
        data = _unc(distribution="lognormal", median=1.0, sigma=sigma)
        del data["uncertainty"]["parameters"][0]["low"], data["uncertainty"]["parameters"][0]["high"]
        data["uncertainty"]["samples"] = 20
        camp = campaign_from_dict(data)
        runner = LinearRunner(camp.scenario_dir, fmu_dir=suite_fmu_dir)
        run_campaign(camp, tmp_path / name, runner, progress=False)
        with np.errstate(all="ignore"):
            return run_uncertainty(camp, tmp_path / name, runner, progress=False)

    with pytest.raises(CampaignError, match=r"uncertain 'g' draws inf for sample \d+, beyond "
                                            r"what a float holds"):
        run(300.0, "inf")
    rep = json.loads(run(30.0, "huge").read_text())
    # half the draws are gains above 1 (median 1): the loop (stable to 2.8) is unstable
    assert 5 <= rep["unstable"]["on"] <= 15


# ----------------------------------------------------------------------------- wheel sweeps


@pytest.mark.parametrize("rpm, message", [
    ([0.0, 1e9], r"wheel sweep 1 rpm is \[0.0, 1000000000.0\]; the top speed must lie between "
                 r"0.001 rpm and 30000 rpm"),
    ([0.0, 1e300], r"the top speed must lie between"),
    ([0.0, 1e-300], r"the top speed must lie between"),
])
def test_a_wheel_sweep_beyond_the_sources_nyquist_speed_or_standing_still_is_refused(
        tmp_path, rpm, message):
    """The synthetic campaign's source runs at 1 ms: 500 Hz is 30000 rpm of turn rate.
    (1e9 rpm reported 1.24e9 arcsec: the line aliased to a low frequency.)"""
    data = campaign_data(n_events=1)
    data["wheel_sweeps"] = [{"instance": "dist", "rpm": rpm, "points": 3}]
    _refused(tmp_path, data, message)


def test_a_wheel_sweep_inside_the_range_is_read(tmp_path):
    data = campaign_data(n_events=1)
    data["wheel_sweeps"] = [{"instance": "dist", "rpm": [0.0, 6000.0], "points": 3}]
    camp = load_campaign(_toml(tmp_path, data))
    assert [w["rpm"] for w in camp.wheel_sweeps] == [(0.0, 6000.0)] * 2


@pytest.mark.parametrize("sweep, message", [
    ({"instance": "dsit"}, r"wheel sweep 1 instance is 'dsit' \(did you mean 'dist'\?\); "
                           r"expected a source instance of the base scenario \(instances: "
                           r"ctrl, dist, sc\)"),
    ({"instance": "dist", "open": ["ctr"]}, r"wheel sweep 1 open is \['ctr'\] \(did you "
                                            r"mean 'ctrl'\?\); expected a list of instances"),
    ({"instance": "dist", "overrides": {"dst.amplitude": 1.0}},
     r"override 'dst.amplitude' names an instance the base scenario does not have \(did "
     r"you mean 'dist'\?\)"),
])
def test_a_misspelt_name_in_a_wheel_sweep_gets_the_closest_instance(tmp_path, sweep, message):
    data = campaign_data(n_events=1)
    data["wheel_sweeps"] = [{**sweep, "rpm": [0.0, 6000.0], "points": 3}]
    _refused(tmp_path, data, message)
