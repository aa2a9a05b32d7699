"""Tests of the campaign report (HTML and Markdown) on a synthetic campaign."""

from __future__ import annotations

import base64
import re
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from orchestrator.campaign import ANGLE_UNITS, campaign_from_dict, run_campaign
from orchestrator.cli import main as cli_main
from orchestrator.report import ReportError, _budget_figure, budget_grid, write_report

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def sine_runner(scenario, out_dir):
    """LOS pitch/yaw of a circular boresight motion; 'dist.fail' raises."""
    p = scenario["fmus"]["dist"]["parameters"]
    if p.get("fail"):
        raise RuntimeError("cryocooler model has no data")
    a = p["amplitude"] / (1 + scenario["fmus"]["ctrl"]["parameters"]["gain"])
    t = np.arange(1001) * 1e-3
    w = 2 * np.pi * p["frequency"]
    path = Path(out_dir) / "results.parquet"
    pq.write_table(pa.table({"time": t, "sc.pitch": a * np.sin(w * t),
                             "sc.yaw": a * np.cos(w * t)}), path)
    return path


def make_campaign(tmp_path, with_frf=True):
    base = {"experiment": {"stop": 1.0, "output_interval": 1e-3},
            "fmus": {"dist": {"fmu": "d", "period": 1e-3, "parameters": {}},
                     "ctrl": {"fmu": "c", "period": 1e-3, "parameters": {"gain": 0.0}},
                     "sc": {"fmu": "s", "period": 1e-3}}}
    data = {
        "campaign": {"name": "report demo", "scenario": base, "unit": "arcsec"},
        "events": [
            {"name": "VNIR pointing", "overrides": {"dist.amplitude": 4e-6, "dist.frequency": 10.0}},
            {"name": "SAD", "overrides": {"dist.amplitude": 1e-6, "dist.frequency": 5.0}},
            {"name": "SWIR cryocooler", "overrides": {"dist.amplitude": 1e-6,
                                                      "dist.frequency": 50.0, "dist.fail": True}},
        ],
        "configurations": [{"name": "isolation off", "overrides": {"ctrl.gain": 0.0}},
                           {"name": "isolation on", "overrides": {"ctrl.gain": 4.0}}],
        "instruments": [{"name": "SWIR", "axes": {"pitch": "sc.pitch", "yaw": "sc.yaw"}}],
        "metrics": [{"kind": "peak_to_peak", "windows": [0.2]}],
        "requirements": [{"instrument": "SWIR", "metric": "peak_to_peak", "window": 0.2,
                          "value": 1.2}],
    }
    out = tmp_path / "camp"
    run_campaign(campaign_from_dict(data), out, sine_runner, workers=0, progress=False)
    if with_frf:
        (out / "frf").mkdir()
        f = np.linspace(0.5, 200, 400)
        h = 1 / (1 - (f / 45) ** 2 + 0.1j * f / 45)
        pq.write_table(pa.table({"frequency": f, "mount3.re": h.real, "mount3.im": h.imag}),
                       out / "frf" / "transmissibility.parquet")
    return out


@pytest.fixture(scope="module")
def campaign_dir(tmp_path_factory):
    return make_campaign(tmp_path_factory.mktemp("report"))


def test_html_report_is_self_contained_with_table_and_images(campaign_dir):
    path = write_report(campaign_dir, "html")
    text = path.read_text(encoding="utf-8")
    assert path == campaign_dir / "report.html"
    # budget: VNIR 2*4e-6 rad and SAD 2*1e-6 rad peak-to-peak, RSS = 2e-6 sqrt(17) rad
    rss = 2e-6 * np.sqrt(17) * ANGLE_UNITS["arcsec"]
    assert f"<td>{rss:.4g}</td>" in text and "<td>1.2</td>" in text
    assert f"{100 * (1.2 - rss) / 1.2:.1f} %" in text
    assert "FAIL" in text and "VNIR pointing (94 %)" in text  # 16/17 of the square
    # isolation on divides the amplitude by 5: the change column says -80 %
    assert "<td>-80.0 %</td>" in text and "change vs first configuration" in text
    assert "RuntimeError: cryocooler model has no data" in text
    images = re.findall(r"src='data:image/png;base64,([A-Za-z0-9+/=]+)'", text)
    # budget chart, time history, its PSD and cumulative RMS, boresight scatter,
    # transmissibility
    assert len(images) == 5
    assert "PSD and cumulative RMS" in text
    assert all(base64.b64decode(b)[:8] == PNG_MAGIC for b in images)
    assert not re.search(r"src=['\"](?!data:)", text)  # nothing loaded from elsewhere


def _budget_rows(campaign_dir):
    rows = pq.read_table(campaign_dir / "summary.parquet").to_pylist()
    return [r for r in rows if r["metric"] == "peak_to_peak"]


def test_budget_grid_holds_every_group_event_and_axis(campaign_dir):
    grid = budget_grid(_budget_rows(campaign_dir), {"SWIR": {"pitch": "", "yaw": ""}})
    assert grid.groups == (("isolation off", ""), ("isolation on", ""))
    assert grid.columns == (("SWIR", "pitch"), ("SWIR", "yaw"))
    # the failed SWIR cryocooler case has no rows: no row in the grid either
    assert grid.events == ("VNIR pointing", "SAD", "RSS")
    # a circle of radius a: pitch and yaw peak-to-peak 2a; isolation on divides a by 5
    arcsec = ANGLE_UNITS["arcsec"]
    off = np.array([8e-6, 2e-6, 2e-6 * np.sqrt(17)]) * arcsec
    np.testing.assert_allclose(grid.values[0], np.c_[off, off], rtol=1e-3)
    np.testing.assert_allclose(grid.values[1], np.c_[off, off] / 5, rtol=1e-3)
    np.testing.assert_array_equal(grid.requirement, [1.2, 1.2])
    np.testing.assert_allclose(grid.change_pct(1), -80.0, rtol=1e-6)  # (1/5 - 1) * 100


def test_budget_grid_leaves_a_missing_case_empty(campaign_dir):
    rows = [r for r in _budget_rows(campaign_dir)
            if not (r["event"] == "SAD" and r["configuration"] == "isolation on")]
    grid = budget_grid(rows, {"SWIR": {"pitch": "", "yaw": ""}})
    assert np.isnan(grid.values[1, 1]).all() and np.isnan(grid.change_pct(1)[1]).all()
    assert np.isfinite(grid.values[0, 1]).all()


def test_budget_chart_draws_off_and_on_for_every_instrument_and_axis(campaign_dir):
    rows = _budget_rows(campaign_dir)
    grid = budget_grid(rows, {"SWIR": {"pitch": "", "yaw": ""}})
    fig = _budget_figure(rows, {"SWIR": {"pitch": "", "yaw": ""}}, "arcsec",
                         "peak_to_peak", 0.2)
    axes = {ax.get_label(): ax for ax in fig.axes if ax.get_label()}
    assert {"rss", "events", "change:isolation on"} <= set(axes)
    assert "change:isolation off" not in axes  # the baseline is not compared with itself
    rss = axes["rss"]
    # one bar per configuration for every instrument and axis, side by side
    assert [c.get_label() for c in rss.containers] == ["isolation off", "isolation on"]
    for gi, bars in enumerate(rss.containers):
        assert len(bars) == len(grid.columns)
        np.testing.assert_allclose([b.get_height() for b in bars], grid.values[gi, -1])
    xs = np.array([[b.get_x() + b.get_width() / 2 for b in c] for c in rss.containers])
    assert np.all(np.abs(xs[1] - xs[0]) < 0.5)  # each pair shares its column
    assert rss.get_yscale() == "log"
    assert [t.get_text() for t in rss.get_xticklabels()] == ["pitch", "yaw"]
    lo, hi = rss.get_ylim()
    assert lo <= grid.values[1, -1].min() and hi >= grid.requirement.max()
    # the legend sits above the plotting area, not over the bars
    legend = rss.get_legend()
    assert legend is not None and {t.get_text() for t in legend.get_texts()} == {
        "isolation off", "isolation on", "requirement"}
    # heat maps: every event and the RSS of "isolation off", and the change of "on"
    ev = axes["events"].images[0].get_array()
    np.testing.assert_allclose(ev, grid.values[0])
    assert [t.get_text() for t in axes["events"].get_yticklabels()] == list(grid.events)
    ch = axes["change:isolation on"].images[0].get_array()
    np.testing.assert_allclose(ch, -80.0, rtol=1e-6)
    # cell texts, then the instrument name under its axes
    assert [t.get_text() for t in axes["change:isolation on"].texts] == ["-80"] * 6 + ["SWIR"]


def test_markdown_report_links_existing_pngs(campaign_dir, tmp_path):
    path = write_report(campaign_dir, "md", tmp_path / "r" / "jitter.md")
    text = path.read_text(encoding="utf-8")
    assert text.startswith("# Jitter report: report demo")
    assert "| instrument | axis | configuration | RSS |" in text
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert len(links) == 5
    for link in links:
        assert (path.parent / link).read_bytes()[:8] == PNG_MAGIC


def test_report_without_frf_folder_has_no_frf_section(tmp_path):
    out = make_campaign(tmp_path, with_frf=False)
    text = write_report(out, "html").read_text(encoding="utf-8")
    assert "Frequency responses" not in text
    assert text.count("data:image/png;base64,") == 4


def test_report_cli_and_errors(campaign_dir, tmp_path, capsys):
    assert cli_main(["report", str(campaign_dir), "--format", "md"]) == 0
    assert "report.md" in capsys.readouterr().out
    with pytest.raises(ReportError, match="summary.parquet|campaign.json"):
        write_report(tmp_path, "html")
    with pytest.raises(ReportError, match="pdf"):
        write_report(campaign_dir, "pdf")
    assert cli_main(["report", str(tmp_path / "none")]) == 2
    assert "run 'jitterfmu campaign' first" in capsys.readouterr().err
