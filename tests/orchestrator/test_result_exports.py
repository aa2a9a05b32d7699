"""A campaign's results where engineers load them: readable case folders, and
``jitterfmu campaign --format csv|mat`` beside the Parquet files.

The references are the Parquet files the campaign wrote (read back with pyarrow)."""

from __future__ import annotations

import re

import numpy as np
import pyarrow.parquet as pq
import scipy.io

from orchestrator.campaign import campaign_from_dict, run_campaign
from orchestrator.campaign.export import export_results
from orchestrator.cli import main as cli_main
from orchestrator.results import read_columns, read_units, write_table

from .test_campaign import campaign_data, synthetic_runner


def test_case_folders_read_as_their_case(tmp_path):
    camp = campaign_from_dict(campaign_data(n_events=2, sweep=True))
    run_campaign(camp, tmp_path, synthetic_runner, workers=0, progress=False)
    folders = sorted(p.name for p in (tmp_path / "cases").iterdir())
    assert len(folders) == len(camp.cases) == 8
    one = next(c for c in camp.cases if c.label == "event1 | isolation on | sc.mass=2.0")
    assert re.fullmatch(r"event1_isolation_on_sc_mass_2_0-[0-9a-f]{16}", one.key)
    assert one.key in folders
    # the digest still tells apart cases whose labels read alike once slugged
    assert len({f.rsplit("-", 1)[1] for f in folders}) == 8


def test_campaign_results_as_csv_and_mat(tmp_path):
    camp = campaign_from_dict(campaign_data(n_events=2))
    run_campaign(camp, tmp_path, synthetic_runner, workers=0, progress=False)
    case = tmp_path / "cases" / camp.cases[0].key
    # a case's table with units, as the master writes them
    cols = read_columns(case / "results.parquet")
    units = {"time": "s", "sc.los_a_pitch": "rad", "sc.los_a_yaw": "rad", "sc.los_b_roll": "rad"}
    write_table(cols, case / "results.parquet", units=units)
    csv_files = export_results(tmp_path, "csv")
    assert case / "results.csv" in csv_files and len(csv_files) == len(camp.cases)
    back = read_columns(case / "results.csv")
    for name, col in cols.items():
        np.testing.assert_array_equal(back[name], col)          # 17 digits: lossless
    assert read_units(case / "results.csv") == units
    mat_files = export_results(tmp_path, "mat")
    assert tmp_path / "campaign.mat" in mat_files
    assert read_units(case / "results.mat") == units
    np.testing.assert_array_equal(read_columns(case / "results.mat")["sc.los_b_roll"],
                                  cols["sc.los_b_roll"])
    m = scipy.io.loadmat(tmp_path / "campaign.mat", simplify_cells=True)
    rows = pq.read_table(tmp_path / "summary.parquet").to_pylist()
    per_case = [r for r in rows if r["event"] != "RSS"]
    budget = [r for r in rows if r["event"] == "RSS"]
    np.testing.assert_array_equal(m["summary"]["value"], [r["value"] for r in per_case])
    np.testing.assert_array_equal(m["budget"]["value"], [r["value"] for r in budget])
    assert list(m["summary"]["case"]) == [r["case"] for r in per_case]
    assert m["units"]["summary"]["value"] == "arcsec" and m["units"]["summary"]["window"] == "s"
    np.testing.assert_array_equal(m["budget"]["pass_"],
                                  [np.nan if r["pass"] is None else float(r["pass"])
                                   for r in budget])
    assert list(m["cases"]["key"]) == [c.key for c in camp.cases]
    assert export_results(tmp_path, "parquet") == []


def test_monte_carlo_samples_as_csv_and_mat(tmp_path):
    """The per-sample table (the layout mcresults writes) in both formats."""
    import pyarrow as pa

    n = 5
    table = pa.table({"sample": np.arange(n), "configuration": ["off"] * n,
                      "instrument": ["SWIR"] * n, "axis": ["roll"] * n,
                      "metric": ["peak_to_peak"] * n, "window": [1.8] * n,
                      "unit": ["arcsec"] * n, "value": [1.0, 2.0, np.inf, 0.5, 3.0],
                      "record_value": [1.0, 2.0, 9.0, 0.5, 3.0],
                      "unstable": [False, False, True, False, False]})
    pq.write_table(table, tmp_path / "uncertainty_samples.parquet")
    (csv_file,) = export_results(tmp_path, "csv")
    assert csv_file.name == "uncertainty_samples.csv"
    lines = csv_file.read_text().splitlines()
    assert len(lines) == n + 1 and "inf" in lines[3].lower()
    export_results(tmp_path, "mat")
    m = scipy.io.loadmat(tmp_path / "campaign.mat", simplify_cells=True)
    np.testing.assert_array_equal(m["samples"]["value"], table.column("value").to_numpy())
    np.testing.assert_array_equal(m["samples"]["unstable"], [0, 0, 1, 0, 0])
    assert m["units"]["samples"]["value"] == "arcsec"


def test_cli_format_mat(tmp_path, capsys):
    import tomli_w

    path = tmp_path / "c.toml"
    path.write_text(tomli_w.dumps(campaign_data(n_events=1)))
    out = tmp_path / "o"
    code = cli_main(["campaign", str(path), "--out", str(out), "--workers", "0", "--runner",
                     "tests.orchestrator.test_campaign:synthetic_runner", "--quiet",
                     "--format", "mat"])
    assert code == 0
    printed = capsys.readouterr().out
    assert f"results as mat: 3 file(s), {out / 'campaign.mat'}" in printed
    assert len(list(out.glob("cases/*/results.mat"))) == 2
