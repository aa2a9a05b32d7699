"""``jitterfmu campaign`` with an ``[uncertainty]`` on a co-simulated campaign: an
uncertain input its FMU cannot take is refused before any case runs (it was refused
after every case had co-simulated), and the Monte Carlo finds its FMUs in ``--fmu-dir``
as the cases do (it searched the default folders only)."""

from __future__ import annotations

from pathlib import Path

import pytest

from orchestrator.cli import main as cli_main

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def fmus(suite_fmus, suite_fmu_dir):
    suite_fmus("truss10_structure", "piezo_p243_40", "piezo_p243_30", "excitation",
               "controller_truss10_strain_diag", "controller_truss10_strain_long")
    return suite_fmu_dir


def files(tmp_path: Path, parameter: str) -> tuple:
    """The shipped quick truss campaign (co-simulated, its scenario absolute) and an
    uncertainty file of 3 samples with one ``[[uncertainty.parameters]]`` entry."""
    text = (ROOT / "campaigns" / "truss10_quick.toml").read_text().replace(
        '"../scenarios/truss10_campaign.toml"',
        repr(str(ROOT / "scenarios" / "truss10_campaign.toml")))
    camp = tmp_path / "c.toml"
    camp.write_text(text)
    unc = tmp_path / "u.toml"
    unc.write_text("[uncertainty]\nsamples = 3\nseed = 1\n\n[[uncertainty.parameters]]\n"
                   + parameter)
    return camp, unc


def test_an_uncertain_input_the_fmu_cannot_take_is_refused_before_any_case(
        tmp_path, fmus, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)           # no fmus/ folder here: only --fmu-dir has them
    camp, unc = files(tmp_path, 'name = "ph"\nkind = "phase"\ninstances = ["ctrl_diag"]\n')
    code = cli_main(["campaign", str(camp), "--uncertainty", str(unc), "--out",
                     str(tmp_path / "o"), "--fmu-dir", str(fmus), "--workers", "0",
                     "--quiet"])
    out, err = capsys.readouterr()
    assert code == 2
    assert ("uncertain 'ph' (phase) sets seed of ctrl_diag, whose FMU "
            "'controller_truss10_strain_diag' has no such parameter") in err
    assert "cases:" not in out and "budget (" not in out
    cases = tmp_path / "o" / "cases"
    assert not cases.exists() or not any(cases.iterdir())


def test_the_monte_carlo_of_a_cosimulated_campaign_reads_fmu_dir(tmp_path, fmus, capsys,
                                                                  monkeypatch):
    monkeypatch.chdir(tmp_path)
    camp, unc = files(tmp_path, 'name = "f"\nkind = "modal_frequency"\nper_mode = true\n'
                                'distribution = "uniform"\nlow = 0.97\nhigh = 1.03\n')
    code = cli_main(["campaign", str(camp), "--uncertainty", str(unc), "--out",
                     str(tmp_path / "o"), "--fmu-dir", str(fmus), "--workers", "0",
                     "--quiet"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "4 cases: 4 run" in out and "uncertainty: 3 samples in " in out
    assert (tmp_path / "o" / "uncertainty.json").is_file()
