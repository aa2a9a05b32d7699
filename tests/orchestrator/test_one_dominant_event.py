"""The EOS budget's printed table names each axis's dominant event by the report's rule
(the largest share in the configuration of larger RSS), not by isolation off alone.

A synthetic campaign where the two rules differ: on pitch, event B leads with isolation
off (1.0 against 0.9) and the isolation makes event A twice as large (gain -0.5), so the
configuration of larger RSS is isolation on, which A leads."""

from __future__ import annotations

from orchestrator.experiments.eos_budget import OFF, ON, budget_table, format_table
from orchestrator.report_verdict import verdicts

from .test_report_agrees import campaign, campaign_data


def test_the_budget_table_names_the_reports_dominant_event(tmp_path):
    import pyarrow.parquet as pq

    data = campaign_data()
    assert [c["name"] for c in data["configurations"]] == [OFF, ON]
    data["events"][0]["overrides"]["dist.amplitude"] = 0.9
    data["configurations"][1]["overrides"]["ctrl.gain"] = -0.5
    data["instruments"] = [{"name": "SWIR", "axes": {"pitch": "sc.swir_pitch"}}]
    data["requirements"] = data["requirements"][:1]
    out = campaign(tmp_path, data)
    (row,) = budget_table(out, "peak_to_peak", 0.5)
    off, on = row["events_off"], row["events_on"]
    assert max(off, key=off.get) == "B"                 # isolation off alone: B
    assert row["rss_on"] > row["rss_off"] and max(on, key=on.get) == "A"
    assert row["dominant"] == "A"
    (line,) = verdicts(pq.read_table(out / "summary.parquet").to_pylist(),
                       "peak_to_peak", 0.5)[1]
    assert line.lead == "A"                             # the report's verdict table
    text = format_table([row]).splitlines()
    assert text[1].endswith("dominant event") and text[-1].endswith(" A")
