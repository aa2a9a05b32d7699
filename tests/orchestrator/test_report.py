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
    yaw = 0.0 if p.get("pitch_only") else 1.0   # an event that moves pitch alone
    path = Path(out_dir) / "results.parquet"
    pq.write_table(pa.table({"time": t, "sc.pitch": a * np.sin(w * t),
                             "sc.yaw": yaw * a * np.cos(w * t)}), path)
    return path


def make_campaign(tmp_path, with_frf=True, sad_pitch=False):
    """The synthetic campaign; ``sad_pitch``: the SAD moves pitch alone, 6x as much, so
    that it dominates pitch while VNIR pointing dominates yaw."""
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
    if sad_pitch:
        data["events"][1]["overrides"].update({"dist.amplitude": 6e-6,
                                               "dist.pitch_only": True})
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


# ----------------------------------------------------------------------------- verdict first


def _drawn(fig):
    """The figure laid out and drawn as the report draws it (Agg canvas)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig).draw()
    return fig


def test_report_opens_with_the_verdict_one_row_per_instrument_axis(campaign_dir):
    text = write_report(campaign_dir, "html").read_text(encoding="utf-8")
    tables = re.findall(r"<table class=\"(\w*)\"><thead><tr>(.*?)</tr></thead><tbody>(.*?)"
                        r"</tbody>", text)
    cls, head, body = tables[0]
    assert cls == "verdict"
    heads = re.findall(r"<th>(.*?)</th>", head)
    assert heads[:4] == ["instrument", "axis", "RSS isolation off", "RSS isolation on"]
    assert "requirement" in heads and heads[-1].startswith("dominant event")
    rows = [re.findall(r"<td[^>]*>(.*?)</td>", r) for r in body.split("</tr>") if r]
    assert [r[:2] for r in rows] == [["SWIR", "pitch"], ["SWIR", "yaw"]]
    # off: 2e-6 sqrt(17) rad = 1.70 arcsec > 1.2 fails; on: a fifth of it passes
    rss = 2e-6 * np.sqrt(17) * ANGLE_UNITS["arcsec"]
    for r in rows:
        assert r[2:5] == [f"{rss:.4g}", f"{rss / 5:.4g}", "-80.0 %"]
        assert r[heads.index("verdict isolation off")] == "FAIL"
        # the failed cryocooler case is missing: above the requirement already fails,
        # below it cannot pass
        assert r[heads.index("verdict isolation on")] == "incomplete"
        assert r[-1] == "VNIR pointing (94 % | 94 %)"
    # the per-configuration table and every row come after the verdict and the figures,
    # folded
    first_img, first_details = text.index("<img"), text.index("<details>")
    assert text.index("<table") < first_img < first_details
    for title in ("Budget by configuration", "All results"):
        assert text.index(f"<summary><b>{title}</b>") > first_details
    assert text.count("<details>") == text.count("</details>") == 2


def test_markdown_has_the_verdict_first_and_the_long_tables_at_the_end(campaign_dir,
                                                                        tmp_path):
    text = write_report(campaign_dir, "md", tmp_path / "r.md").read_text(encoding="utf-8")
    first_table = text.index("\n| ")
    assert text[first_table:].startswith("\n| instrument | axis | RSS isolation off |")
    last_image = text.rindex("![")
    assert text.index("## Verdict") < first_table < last_image
    assert last_image < text.index("## Budget by configuration") < text.index("## All results")


def test_figures_follow_the_dominant_event_of_each_axis(tmp_path):
    """SAD dominates pitch, VNIR pointing yaw: one history per event, each with its worst
    window shaded and the requirement band (1.2 arcsec p-p) over that window; the
    configurations in distinct colours and line styles, the legend's the same."""
    from orchestrator.report import _contents
    from orchestrator.report_figures import scatter_axes

    out = make_campaign(tmp_path, with_frf=False, sad_pitch=True)
    figures = {title: fig for sec, title, fig in _contents(out)["figures"]}
    sad = "Time history of SAD, the dominant event of SWIR pitch"
    assert sad in figures
    assert "Time history of VNIR pointing, the dominant event of SWIR yaw" in figures
    assert not any("pitch, SWIR yaw" in t for t in figures)
    (ax,) = figures[sad].axes
    boxes = [p for p in ax.patches if not p.get_fill()]
    shaded = [p for p in ax.patches if p.get_fill()]
    assert len(boxes) == 2 and len(shaded) == 2          # one per configuration
    arcsec = ANGLE_UNITS["arcsec"]
    for box in boxes:
        assert box.get_height() == pytest.approx(1.2)
        assert box.get_width() == pytest.approx(0.2)      # the metric's window
        # centred on the window's mid-range: 0 for a sine over whole periods
        assert box.get_y() + box.get_height() / 2 == pytest.approx(0.0, abs=1e-3 * arcsec)
    # off and on in their own colour and line style: equal traces stay distinct
    traces = [ln for ln in ax.get_lines() if len(ln.get_xdata()) > 2]
    assert len({(ln.get_color(), ln.get_linestyle()) for ln in traces}) == 2
    assert len({ln.get_linestyle() for ln in traces}) == 2
    # the legend below the panels, inside the figure, each entry drawn as its trace
    _drawn(figures[sad])
    (legend,) = figures[sad].legends
    entries = {t.get_text(): h for t, h in zip(legend.get_texts(), legend.legend_handles)}
    assert {"isolation off", "isolation on"} <= set(entries)
    for trace, name in zip(traces, ("isolation off", "isolation on")):
        assert (entries[name].get_color(), entries[name].get_linestyle()) == \
            (trace.get_color(), trace.get_linestyle())
    fig_box = figures[sad].bbox
    lb = legend.get_window_extent()
    assert lb.x0 >= fig_box.x0 and lb.x1 <= fig_box.x1 and lb.y0 >= fig_box.y0
    # the scatter: the image plane over each configuration's worst 0.2 s window, in the
    # requirement's box centred there
    title, scatter = next((t, f) for t, f in figures.items() if "boresight" in t)
    assert "over the worst 0.2 s window" in title
    (sax,) = scatter.axes
    assert (sax.get_xlabel(), sax.get_ylabel()) == ("pitch (arcsec)", "yaw (arcsec)")
    boxes = [p for p in sax.patches if not p.get_fill()]
    assert len(boxes) == 2
    for box in boxes:
        assert (box.get_width(), box.get_height()) == pytest.approx((1.2, 1.2))
    for trace in sax.get_lines():        # 0.2 s at 1 ms: the window's 201 samples only
        assert len(trace.get_xdata()) == 201
    assert scatter_axes({"yaw": 0, "pitch": 0, "roll": 0}) == ("roll", "pitch")  # Fig. 16


def test_every_configuration_has_a_change_heat_map(campaign_dir):
    """Five configurations: the baseline heat map and four of change, each named by its
    configuration; the legend above the bars stays inside the figure."""
    rows = _budget_rows(campaign_dir)
    names = ["isolation off", "isolation on", "isolation on, soft mounts",
             "isolation on, stiff mounts", "isolation on, gain 2"]
    many = [r for r in rows if r["configuration"] == "isolation off"]
    many += [dict(r, configuration=n) for n in names[1:] for r in rows
             if r["configuration"] == "isolation on"]
    inst = {"SWIR": {"pitch": "", "yaw": ""}}
    fig = _budget_figure(many, inst, "arcsec", "peak_to_peak", 0.2)
    labels = {ax.get_label() for ax in fig.axes}
    assert {f"change:{n}" for n in names[1:]} <= labels
    rss = next(ax for ax in fig.axes if ax.get_label() == "rss")
    _drawn(fig)
    lb, fb = rss.get_legend().get_window_extent(), fig.bbox
    assert lb.x0 >= fb.x0 and lb.x1 <= fb.x1 and lb.y1 <= fb.y1


def test_sweep_legends_stay_inside_the_figure():
    from orchestrator.report_sweeps import _figure

    x = np.linspace(0, 6000, 50)
    curves = {a: [("isolation off", x, 1 + np.sin(x / 900), 1.5),
                  ("isolation on", x, 0.5 + np.sin(x / 900) / 2, 1.5)] for a in ("roll",
                                                                                   "yaw")}
    fig = _drawn(_figure(curves, "VNIR", ["roll", "yaw"], "wheel speed (rpm)", "arcsec",
                         "RWA"))
    for ax in fig.axes:
        lb = ax.get_legend().get_window_extent()
        assert lb.x0 >= fig.bbox.x0 and lb.x1 <= fig.bbox.x1
        assert not lb.overlaps(ax.get_window_extent())    # beside the panel, not on it
        texts = [t.get_text() for t in ax.get_legend().get_texts()]
        assert texts[0].startswith("isolation off: worst 2 arcsec at ")


def test_report_in_a_browser_shows_the_verdict_in_the_first_screen(campaign_dir, tmp_path):
    """Headless Chromium renders report.html: its DOM's first table is the verdict, and
    the 1280x900 screenshot (tmp_path/shot/report.png) is not blank and shows both
    verdict rows' pass/FAIL cells."""
    from .browser import ink, render, verdict_bands

    dom, png = render(write_report(campaign_dir, "html"), tmp_path / "shot")
    assert dom.index('<table class="verdict">') == dom.index("<table")
    assert ink(png) > 0.02
    assert verdict_bands(png) == 2
