"""A campaign of sweeps ends with its verdict on the terminal: per instrument axis, each
configuration's worst sweep point against the requirement, the numbers of the report's
verdict table (it printed nothing after the case count).  Its report draws a swept
parameter in the unit its FMU declares."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import tomli_w

from orchestrator.campaign import ANGLE_UNITS, load_campaign, run_campaign
from orchestrator.campaign.linear import LinearRunner
from orchestrator.report import _contents, write_report
from orchestrator.cli import main as cli_main
from orchestrator.cli.campaign import budget_lines
from orchestrator.report_verdict import verdicts

from .test_campaign import campaign_data


def swept(tmp_path):
    """Two events (5 and 10 Hz) of one swept amplitude, 1 and 3 µrad."""
    data = campaign_data(n_events=2)
    for event in data["events"]:
        del event["overrides"]["dist.amplitude"]
    data["sweeps"] = [{"parameter": "dist.amplitude", "values": [1e-6, 3e-6]}]
    path = tmp_path / "c.toml"
    path.write_text(tomli_w.dumps(data))
    return path


def test_a_sweep_campaign_ends_with_the_worst_point_of_each_configuration(tmp_path, capsys):
    out_dir = tmp_path / "o"
    code = cli_main(["campaign", str(swept(tmp_path)), "--out", str(out_dir), "--workers",
                     "0", "--runner", "tests.orchestrator.test_campaign:synthetic_runner",
                     "--quiet"])
    out = capsys.readouterr().out
    assert code == 0, out
    lines = out.splitlines()
    head = lines.index("budget (peak_to_peak over 0.2 s, RSS over events, arcsec; the "
                       "worst sweep point of each configuration):")
    pitch = next(ln for ln in lines[head:] if ln.startswith("  A pitch: "))
    # two sines of amplitude a, crests on the 1 ms grid: peak-to-peak 2a each, RSS
    # sqrt(2) 2a; isolation on divides by 1 + gain = 4; the worst point is a = 3 µrad
    off = math.sqrt(2) * 2 * 3e-6 * ANGLE_UNITS["arcsec"]
    assert pitch == (f"  A pitch: isolation off {off:.3g} (FAIL) at dist.amplitude=3e-06 | "
                     f"isolation on {off / 4:.3g} (PASS) at dist.amplitude=3e-06  "
                     "requirement 1")
    # the report's verdict table holds the same numbers
    rows = pq.read_table(out_dir / "summary.parquet").to_pylist()
    configs, axes = verdicts(rows, "peak_to_peak", 0.2)
    a_pitch = next(v for v in axes if (v.instrument, v.axis) == ("A", "pitch"))
    assert configs == ["isolation off", "isolation on"]
    assert a_pitch.rss == pytest.approx((off, off / 4), rel=1e-6)
    assert a_pitch.passed == (False, True)
    # and the report opens with that verdict, each configuration's worst point named
    text = write_report(out_dir, "md").read_text()
    verdict = text[text.index("## Verdict"):].split("\n## ")[0]
    assert "3 instrument axes, 3 failing in at least one configuration" in verdict
    row = next(ln for ln in verdict.splitlines() if ln.startswith("| A | pitch |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[2:4] == [f"{off:.4g}", f"{off / 4:.4g}"]
    assert "dist.amplitude=3e-06 \\| dist.amplitude=3e-06" in row


def test_a_swept_parameter_is_drawn_in_the_unit_its_fmu_declares(tmp_path, suite_fmus,
                                                                  suite_fmu_dir):
    """The shipped quick truss campaign on the linear engine, the diagonal's drive swept
    over 8.0 and 8.4 Hz (the excitation FMU declares freq1 in Hz): the sweep figure's
    axis and its worst points say Hz (they said 'excitation.freq1' alone)."""
    suite_fmus("truss10_structure", "piezo_p243_40", "piezo_p243_30", "excitation",
               "controller_truss10_strain_diag", "controller_truss10_strain_long")
    root = Path(__file__).resolve().parents[2]
    text = (root / "campaigns" / "truss10_quick.toml").read_text().replace(
        '"../scenarios/truss10_campaign.toml"',
        repr(str(root / "scenarios" / "truss10_campaign.toml")))
    text += '\n[[sweeps]]\nparameter = "excitation.freq1"\nvalues = [8.0, 8.4]\n'
    path = tmp_path / "c.toml"
    path.write_text(text)
    camp = load_campaign(path)
    out = tmp_path / "o"
    res = run_campaign(camp, out, LinearRunner(camp.scenario_dir, fmu_dir=suite_fmu_dir),
                       progress=False)
    assert (res.n_run, res.n_failed) == (8, 0)
    assert json.loads((out / "campaign.json").read_text())["sweep_units"] == \
        {"excitation.freq1": "Hz"}
    (fig,) = [f for sec, _, f in _contents(out)["figures"] if sec == "sweep"]
    assert fig.axes[-1].get_xlabel() == "excitation.freq1 (Hz)"
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    worst = [t for t in legend if t.startswith("control ")]
    assert len(worst) == 2 and all(t.endswith(" Hz") for t in worst), legend
    # the verdict's worst points and the terminal's lines say it too
    text = write_report(out, "md").read_text()
    row = next(ln for ln in text.splitlines() if ln.startswith("| tip | roll |"))
    assert "excitation.freq1=8.4 Hz \\| excitation.freq1=8.4 Hz" in row
    roll = next(ln for ln in budget_lines(out / "summary.parquet") if "tip roll" in ln)
    assert roll.count(" at excitation.freq1=8.4 Hz") == 2, roll
