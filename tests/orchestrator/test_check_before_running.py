"""A campaign's names are checked against its FMUs before any case runs: a misspelt
instrument variable is refused in one sentence with the closest name, and no case runs."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from orchestrator.campaign import CampaignError, load_campaign, run_campaign
from orchestrator.campaign.runner import MasterRunner
from orchestrator.cli import main as cli_main

ROOT = Path(__file__).resolve().parents[2]


def misspelt(tmp_path: Path, old: str, new: str) -> Path:
    """The shipped quick truss campaign with one name changed, its scenario absolute."""
    text = (ROOT / "campaigns" / "truss10_quick.toml").read_text()
    text = text.replace('"../scenarios/truss10_campaign.toml"',
                        repr(str(ROOT / "scenarios" / "truss10_campaign.toml")))
    assert old in text
    path = tmp_path / "c.toml"
    path.write_text(text.replace(old, new, 1))
    return path


class CountingRunner(MasterRunner):
    """The master runner, counting the cases it is asked to run."""

    calls = 0

    def __call__(self, scenario, out_dir):
        CountingRunner.calls += 1
        return super().__call__(scenario, out_dir)


@pytest.fixture
def fmus(suite_fmus, suite_fmu_dir):
    suite_fmus("truss10_structure", "piezo_p243_40", "piezo_p243_30", "excitation",
               "controller_truss10_strain_diag", "controller_truss10_strain_long")
    return suite_fmu_dir


def test_a_misspelt_instrument_variable_is_refused_before_any_case(tmp_path, fmus):
    camp = load_campaign(misspelt(tmp_path, "structure.los_tip_roll", "structure.los_tip_rol"))
    runner = CountingRunner(camp.scenario_dir, fmu_dir=fmus)
    with pytest.raises(CampaignError) as info:
        run_campaign(camp, tmp_path / "out", runner, workers=0, progress=False)
    text = str(info.value)
    assert re.search(r"instrument 'tip' axis 'roll': FMU truss10_structure.fmu of instance "
                     r"'structure' has no variable 'los_tip_rol' \(did you mean "
                     r"'los_tip_roll'", text), text
    assert "[record]" not in text          # no advice to record a name that does not exist
    assert CountingRunner.calls == 0
    assert not (tmp_path / "out" / "cases").exists()


def test_an_instrument_variable_not_recorded_says_to_record_it(tmp_path, fmus):
    # an output of the truss FMU that the scenario does not record
    from orchestrator.cosim import read_fmu_info

    info = read_fmu_info(fmus / "truss10_structure.fmu")
    recorded = {"los_tip_roll", "los_tip_pitch", "los_tip_yaw"}
    other = sorted(n for n, v in info.variables.items()
                   if v.causality == "output" and n not in recorded)[0]
    camp = load_campaign(misspelt(tmp_path, "structure.los_tip_yaw", f"structure.{other}"))
    with pytest.raises(CampaignError, match=rf"structure.{other} is not recorded; add it to "
                                            r"\[record\] variables"):
        run_campaign(camp, tmp_path / "out", MasterRunner(camp.scenario_dir, fmu_dir=fmus),
                     workers=0, progress=False)


def test_the_command_refuses_a_misspelt_instrument_in_one_sentence(tmp_path, fmus, capsys):
    path = misspelt(tmp_path, "structure.los_tip_pitch", "structure.los_tip_pich")
    code = cli_main(["campaign", str(path), "--out", str(tmp_path / "o"), "--workers", "0",
                     "--fmu-dir", str(fmus), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert "has no variable 'los_tip_pich' (did you mean 'los_tip_pitch'" in err
    cases = tmp_path / "o" / "cases"
    assert not cases.exists() or not any(cases.iterdir())


def test_a_misspelt_instance_in_an_instrument_gets_the_closest_instance(tmp_path, fmus):
    camp = load_campaign(misspelt(tmp_path, "structure.los_tip_roll", "structur.los_tip_roll"))
    with pytest.raises(CampaignError, match=r"names instance 'structur', which the base "
                                            r"scenario does not have \(did you mean "
                                            r"'structure'"):
        run_campaign(camp, tmp_path / "out", MasterRunner(camp.scenario_dir, fmu_dir=fmus),
                     workers=0, progress=False)


def test_an_unrecorded_output_is_refused_for_cases_but_not_for_a_wheel_sweep(tmp_path, fmus):
    camp = load_campaign(ROOT / "campaigns" / "truss10_quick.toml")
    runner = MasterRunner(camp.scenario_dir, fmu_dir=fmus)
    base = camp.cases[0].scenario
    assert runner.output_problem(base, "structure.los_tip_roll") is None
    base["record"]["variables"].remove("structure.los_tip_roll")
    assert "is not recorded" in runner.output_problem(base, "structure.los_tip_roll")
    assert runner.output_problem(base, "structure.los_tip_roll", recorded=False) is None
    assert "no variable 'los_tip_rol'" in runner.output_problem(
        base, "structure.los_tip_rol", recorded=False)


def test_a_campaign_of_wheel_sweeps_alone_is_checked_on_its_sweep_scenario():
    """No case: the instruments are checked on the first sweep's scenario, unrecorded."""
    import dataclasses

    from orchestrator.campaign.engine import _check_overrides

    camp = load_campaign(ROOT / "campaigns" / "truss10_quick.toml")
    sweep = {"name": "w", "configuration": "c", "scenario": camp.cases[0].scenario}
    wheel_only = dataclasses.replace(camp, cases=(), wheel_sweeps=(sweep,))
    asked = []

    class Runner:
        def output_problem(self, scenario, ref, recorded=True):
            asked.append((scenario is sweep["scenario"], ref, recorded))
            return "FMU x has no variable 'los_tip_rol'" if ref.endswith("roll") else None

    with pytest.raises(CampaignError, match=r"instrument 'tip' axis 'roll': FMU x has no "):
        _check_overrides(wheel_only, Runner())
    assert asked[0] == (True, "structure.los_tip_roll", False)
