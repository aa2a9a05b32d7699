"""A stage of minutes without a bar says how far it is: ``testbed-robust --design``
(8-15 minutes over six band pairs) names each band with its count, which the heartbeat
repeats while the band runs.  The design's numerics are replaced by stand-ins here: the
test is of what the stage says, not of the design (test_testbed_robust.py)."""

from __future__ import annotations

from orchestrator.experiments import testbed_margins as tm


def test_each_band_of_the_structure_designs_says_its_count(monkeypatch, capsys):
    found = {"gains": (1.0, 0.5), "reduction_pct": 40.0}
    monkeypatch.setattr(tm, "linear_plant", lambda model: "nominal")
    monkeypatch.setattr(tm, "design_within_structure", lambda *a, **k: [found])
    monkeypatch.setattr(tm, "_refined", lambda plant, best, band: best)
    monkeypatch.setattr(tm, "_design_law", lambda *a, **k: None)
    monkeypatch.setattr(tm, "stability_limit", lambda *a, **k: 2.0)
    monkeypatch.setattr(tm, "boresight_reduction", lambda *a, **k: 30.0)
    plants = dict.fromkeys(("f1 z1", "f0.95 z0.5", "f1 z0.5", "f1.05 z0.5"))
    out = tm.structure_designs(None, plants, bands=((20.0, 60.0), (22.5, 45.0)))
    assert [d["band"] for d in out] == [[20.0, 60.0], [22.5, 45.0]]
    said = [ln for ln in capsys.readouterr().err.splitlines() if "structure" in ln]
    assert said == [
        "jitterfmu: testbed-robust: the law within the paper's structure at 20/60 Hz "
        "(band 1 of 2)",
        "jitterfmu: testbed-robust: the law within the paper's structure at 22.5/45 Hz "
        "(band 2 of 2)"]
