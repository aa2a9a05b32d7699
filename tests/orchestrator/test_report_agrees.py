"""A report that agrees with itself, checked in headless Chromium's DOM.

A synthetic campaign where the old rules disagreed: event A leads pitch with isolation
off (55 % of the RSS²) and B with it on (95 %); the verdict names the event of the
configuration of largest RSS (off: A), and the figure of that axis must name the same.
Two instruments move alike: their axes share one figure, never two.  A wheel-sweep
campaign's report has a verdict (its worst speeds, in rpm)."""

from __future__ import annotations

import html
import json
import re
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from orchestrator.campaign import campaign_from_dict, run_campaign
from orchestrator.campaign.summary import SUMMARY_SCHEMA
from orchestrator.report import _contents, write_report

AMP = 1e-6   # rad


def runner(scenario, out_dir):
    """Pitch and yaw of SWIR (VNIR: 0.9 of them) from one event's sine; isolation
    (ctrl.gain) divides the isolable event's motion by 1 + gain."""
    p = scenario["fmus"]["dist"]["parameters"]
    gain = scenario["fmus"]["ctrl"]["parameters"]["gain"] if p.get("isolable") else 0.0
    t = np.arange(2001) * 1e-3
    w = 2 * np.pi * p["frequency"]
    a = AMP * p["amplitude"] / (1 + gain)
    pitch, yaw = a * np.sin(w * t), p.get("yaw", 1.0) * a * np.cos(w * t)
    path = Path(out_dir) / "results.parquet"
    pq.write_table(pa.table({"time": t, "sc.swir_pitch": pitch, "sc.swir_yaw": yaw,
                             "sc.vnir_pitch": 0.9 * pitch, "sc.vnir_yaw": 0.9 * yaw}), path)
    return path


def campaign_data() -> dict:
    """The campaign of the module docstring, as data."""
    base = {"experiment": {"stop": 2.0, "output_interval": 1e-3},
            "fmus": {"dist": {"fmu": "d", "period": 1e-3, "parameters": {}},
                     "ctrl": {"fmu": "c", "period": 1e-3, "parameters": {"gain": 0.0}},
                     "sc": {"fmu": "s", "period": 1e-3}}}
    data = {
        "campaign": {"name": "agrees", "scenario": base, "unit": "arcsec"},
        "events": [
            {"name": "A", "overrides": {"dist.amplitude": 1.1, "dist.frequency": 10.0,
                                        "dist.isolable": True}},
            {"name": "B", "overrides": {"dist.amplitude": 1.0, "dist.frequency": 5.0,
                                        "dist.yaw": 2.0}},
        ],
        "configurations": [{"name": "isolation off", "overrides": {"ctrl.gain": 0.0}},
                           {"name": "isolation on", "overrides": {"ctrl.gain": 4.0}}],
        "instruments": [
            {"name": "SWIR", "axes": {"pitch": "sc.swir_pitch", "yaw": "sc.swir_yaw"}},
            {"name": "VNIR", "axes": {"pitch": "sc.vnir_pitch", "yaw": "sc.vnir_yaw"}}],
        "metrics": [{"kind": "peak_to_peak", "windows": [0.5]}],
        "requirements": [{"instrument": i, "metric": "peak_to_peak", "window": 0.5,
                          "value": 0.6} for i in ("SWIR", "VNIR")],
    }
    return data


def campaign(tmp_path, data=None) -> Path:
    """The campaign (``data``, default :func:`campaign_data`) run into ``tmp_path``."""
    out = tmp_path / "camp"
    run_campaign(campaign_from_dict(data or campaign_data()), out, runner, workers=0,
                 progress=False)
    return out


def _cells(row):
    return [html.unescape(re.sub(r"<[^>]+>", "", c))
            for c in re.findall(r"<td[^>]*>(.*?)</td>", row, re.S)]


def _verdict(dom):
    table = re.search(r'<table class="verdict">(.*?)</table>', dom, re.S).group(1)
    head = [html.unescape(h) for h in re.findall(r"<th>(.*?)</th>", table)]
    rows = [_cells(r) for r in re.findall(r"<tr>(.*?)</tr>", table, re.S)[1:]]
    return head, rows


def test_table_and_figures_name_one_dominant_event_and_no_figure_twice(tmp_path):
    from .browser import render

    out = campaign(tmp_path)
    dom, _ = render(write_report(out, "html"), tmp_path / "shot")
    head, rows = _verdict(dom)
    assert [r[:2] for r in rows] == [["SWIR", "pitch"], ["SWIR", "yaw"], ["VNIR", "pitch"],
                                     ["VNIR", "yaw"]]
    lead = {(r[0], r[1]): r[-1].split(" (")[0] for r in rows}
    # pitch: A leads isolation off (its RSS is the larger), B leads isolation on
    assert lead[("SWIR", "pitch")] == "A" and "B leads isolation on" in rows[0][-1]
    assert lead[("SWIR", "yaw")] == "B"
    captions = [html.unescape(c) for c in re.findall(r"<figcaption>(.*?)</figcaption>", dom)]
    histories = [c for c in captions if c.startswith("Time history of ")]
    named = {}
    for c in histories:
        event, _, axes = c[len("Time history of "):].partition(", the dominant event of ")
        for ia in axes.split(", "):
            inst, axis = ia.split(" ")
            assert (inst, axis) not in named, f"{ia} drawn twice"
            named[(inst, axis)] = event
    assert named == lead                 # every axis, the table's event
    assert len(histories) == 2           # A (pitch), B (yaw): VNIR folded into SWIR's
    assert len(captions) == len(set(captions))
    # the figures' own titles name the same event
    figures = {t: f for _, t, f in _contents(out)["figures"]}
    for title, fig in figures.items():
        if title.startswith("Time history of "):
            event = title[len("Time history of "):].split(",")[0]
            assert fig._suptitle.get_text().startswith(f"Dominant event {event}:")
    # no two figures with the same picture
    images = re.findall(r"src='data:image/png;base64,([A-Za-z0-9+/=]+)'",
                        (out / "report.html").read_text())
    assert len(images) == len(set(images)) == len(captions)


def test_spectra_axes_show_their_content(tmp_path):
    """The cumulative RMS is flat over at most half the frequency axis (log scale): it
    reaches 99.5 % of its end past the axis's middle, and before the axis ends."""
    out = campaign(tmp_path)
    for title, fig in ((t, f) for _, t, f in _contents(out)["figures"]):
        if not title.startswith("PSD and cumulative RMS"):
            continue
        for ax in fig.axes[1::2]:                    # the cumulative RMS column
            lo, hi = (np.log10(v) for v in ax.get_xlim())
            for line in ax.get_lines():
                f, c = line.get_xdata(), line.get_ydata()
                f995 = f[np.searchsorted(c, 0.995 * c[-1])]
                frac = (np.log10(f995) - lo) / (hi - lo)
                assert 0.5 <= frac < 1.0, (title, frac)
            assert "arcsec" in ax.get_ylabel()


def test_wheel_sweep_report_has_a_verdict_in_rpm(tmp_path):
    from .browser import render

    out = tmp_path / "wheel"
    out.mkdir()
    (out / "campaign.json").write_text(json.dumps({
        "name": "rwa", "unit": "arcsec", "cases": [], "engine": "linear",
        "instruments": {"VNIR": {"roll": "sc.r", "pitch": "sc.p"}},
        "requirements": [{"instrument": "VNIR", "metric": "peak_to_peak", "window": 1.8,
                          "value": 2.0}],
        "metrics": [["peak_to_peak", 1.8]]}))
    pq.write_table(pa.Table.from_pylist([], schema=SUMMARY_SCHEMA), out / "summary.parquet")
    rpm = np.linspace(0, 6000, 61)
    rows = []
    for cf, scale in (("isolation off", 1.0), ("isolation on", 0.4)):
        for axis, peak in (("roll", 5255.0), ("pitch", 1200.0)):
            y = scale * 3.0 / (1 + ((rpm - peak) / 300) ** 2)
            rows += [{"sweep": "RWA speed", "configuration": cf, "instrument": "VNIR",
                      "axis": axis, "metric": "peak_to_peak", "window": 1.8, "rpm": float(r),
                      "unit": "arcsec", "value": float(v), "requirement": 2.0}
                     for r, v in zip(rpm, y)]
    pq.write_table(pa.Table.from_pylist(rows), out / "wheel_sweeps.parquet")
    dom, _ = render(write_report(out, "html"), tmp_path / "shot")
    head, vrows = _verdict(dom)
    assert head[:4] == ["instrument", "axis", "worst isolation off", "worst isolation on"]
    assert len(vrows) == 2
    roll = next(r for r in vrows if r[1] == "roll")
    worst = 3.0 / (1 + (45 / 300) ** 2)      # the grid's nearest speed, 5300 rpm
    assert roll[2] == f"{worst:.4g}" and roll[3] == f"{0.4 * worst:.4g}"
    assert roll[head.index("verdict isolation off")] == "FAIL"
    assert roll[head.index("verdict isolation on")] == "pass"
    assert roll[head.index("worst at (per configuration)")] == \
        "RWA speed at 5300 rpm | RWA speed at 5300 rpm"
    assert "2 instrument axes, 2 failing" in dom and "0 cases" not in dom
    figures = dict((t, f) for _, t, f in _contents(out)["figures"])
    fig = figures["VNIR: RWA speed, steady state"]
    texts = [t.get_text() for ax in fig.axes for t in ax.get_legend().get_texts()]
    assert any(re.search(r"at \d+ rpm$", t) for t in texts), texts


def test_transfer_figure_axes_carry_the_fmus_units(suite_fmus):
    """analyze --plot: the units the FMUs declare (the excitation's V, the structure's
    rad), not 'output / input' or 'unit^2/Hz'."""
    from orchestrator import load_scenario, prepare
    from orchestrator.analysis.spectra import Transfer
    from orchestrator.report_sweeps import plan_units, transfer_figure

    fmus = suite_fmus("truss10_structure", "piezo_p243_40", "piezo_p243_30",
                      "controller_truss10_strain_diag", "controller_truss10_strain_long",
                      "excitation")
    plan = prepare(load_scenario("scenarios/truss10_closed_loop.toml"),
                   next(iter(fmus.values())).parent)
    names = ["excitation.v1", "structure.los_tip_roll", "structure.strain_diag"]
    units = plan_units(plan, names)
    assert units == {"excitation.v1": "V", "structure.los_tip_roll": "rad",
                     "structure.strain_diag": "1"}
    f = np.geomspace(1, 100, 20)
    one = Transfer(np.ones((1, 1, f.size), complex), f, ("excitation.v1",),
                   ("structure.los_tip_roll",), np.zeros((1, 1, f.size)))
    fig = transfer_figure(one, np.ones((1, f.size)), np.ones((1, f.size)), units)
    assert [ax.get_ylabel() for ax in fig.axes] == ["|H| (rad/V)", "PSD (rad²/Hz)",
                                                    "cumulative RMS (rad)"]
    two = Transfer(np.ones((2, 1, f.size), complex), f, ("excitation.v1",),
                   ("structure.los_tip_roll", "structure.strain_diag"),
                   np.zeros((2, 1, f.size)))
    fig = transfer_figure(two, np.ones((2, f.size)), np.ones((2, f.size)), units)
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert legend == ["excitation.v1 -> structure.los_tip_roll (rad/V)",
                      "excitation.v1 -> structure.strain_diag (1/V)"]
    assert "unit in legend" in fig.axes[2].get_ylabel()
