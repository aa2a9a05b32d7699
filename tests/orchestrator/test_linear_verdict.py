"""A run whose closed loop the linear engine finds unstable ends ``unstable``.

The truss's diagonal strain loop is stable up to a gain of 2.8 (the linear engine's
margin).  At 2.9 it grows, slowly: over 2 s closed it sat at the slew limit for 7 % of
the run, under the 10 % that ends a run held at its limits, so it ended ``ok``.
References: the co-simulation itself (the loop's command decays after switch-on at 2.7 and
does not at 2.9) and the margin of the loop found by the linear engine's gain search.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from orchestrator import load_scenario, run_scenario
from orchestrator.linearcheck import UnstableLoopWarning, _has_feedback, linear_verdict

pytestmark = pytest.mark.slow

TRUSS = "scenarios/truss10_closed_loop.toml"
NAMES = ("truss10_structure", "piezo_p243_40", "piezo_p243_30",
         "controller_truss10_strain_diag", "controller_truss10_strain_long", "excitation")
T_ON = 4.5   # the scenario's controllers switch on here


@pytest.fixture(scope="module")
def folder(suite_fmus):
    """The native FMUs, and their Python twins the linear engine reads the models from."""
    suite_fmus(*NAMES, kind="python")
    return next(iter(suite_fmus(*NAMES).values())).parent


def _run(folder, out, gain, stop):
    sc = load_scenario(TRUSS).with_overrides({"ctrl_diag.gain": gain})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = run_scenario(sc.with_experiment(stop=stop), out, fmu_dir=folder)
    return result, [w for w in caught if issubclass(w.category, UnstableLoopWarning)]


def _envelope(result, start, width=0.5):
    t = np.asarray(result.table["time"])
    u = np.abs(np.asarray(result.table["ctrl_diag.u1"]))
    return float(np.max(u[(t >= start) & (t < start + width)]))


def test_the_margin_lies_between_the_two_gains(folder):
    """The linear engine's upper gain margin of the diagonal loop: 2.7 < 2.8 < 2.9."""
    from orchestrator.analysis.scenario import linearize

    lin = linearize(TRUSS, fmu_dir=folder)
    assert 2.7 < lin.gain_margins("ctrl_diag").upper < 2.9


def test_a_loop_beyond_its_margin_ends_unstable_naming_it(folder, tmp_path):
    """Gain 2.9, 1 s closed: status ``unstable``, one line naming ctrl_diag (alone) with
    its growth, in run.json too; the rows kept.  Not the clamp's verdict: less than 10 % of
    the run at a limit (6.4 %; 2 s closed hold the diagonal's current limit, reached at
    any sub-step, for 13 % of the run, the clamp's verdict).  The co-simulation agrees:
    its command has not decayed."""
    result, caught = _run(folder, tmp_path / "o", 2.9, T_ON + 1.0)
    meta = result.metadata
    assert meta["status"] == "unstable" and meta["linear_check"] == "unstable"
    assert max((s["fraction"] for s in meta.get("saturation", [])), default=0.0) < 0.10
    info = meta["unstable"]
    assert info["loop"] == ["ctrl_diag"] and info["pole_abs"] > 1.0
    assert info["message"].startswith("the closed loop through ctrl_diag is unstable in the "
                                      "linear engine: a pole at ")
    assert "\n" not in info["message"] and "ctrl_long" not in info["message"]
    assert len(caught) == 1 and str(caught[0].message) == info["message"]
    saved = json.loads((tmp_path / "o" / "run.json").read_text())
    assert saved["status"] == "unstable" and saved["unstable"]["loop"] == ["ctrl_diag"]
    assert result.table["time"][-1] == pytest.approx(T_ON + 1.0)   # every row kept
    assert _envelope(result, T_ON + 0.5) > 0.8 * _envelope(result, T_ON)


def test_a_loop_within_its_margin_ends_ok(folder, tmp_path):
    """Gain 2.7: ``ok``, the linear check stable, and the command decays after switch-on."""
    result, caught = _run(folder, tmp_path / "o", 2.7, T_ON + 2.0)
    assert result.metadata["status"] == "ok" and result.metadata["linear_check"] == "stable"
    assert caught == []
    assert _envelope(result, T_ON + 1.5) < 0.2 * _envelope(result, T_ON)


def test_a_run_that_ends_before_the_loop_closes_keeps_ok(folder, tmp_path):
    """Gain 3.2 but a run of 3 s: the loop never closed (t_on = 4.5 s); the check says so."""
    result, caught = _run(folder, tmp_path / "o", 3.2, 3.0)
    meta = result.metadata
    assert meta["status"] == "ok" and caught == []
    assert meta["linear_check"] == ("unstable once the loop through ctrl_diag closes at "
                                    "t = 4.5 s, after the run's end at 3 s")


def test_both_loops_unstable_on_their_own_are_both_named(folder):
    """Gains 30 on both: each loop alone is unstable; the verdict names both."""
    from orchestrator.cosim import prepare

    sc = load_scenario(TRUSS).with_overrides({"ctrl_diag.gain": 30.0, "ctrl_long.gain": 30.0})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        verdict, info = linear_verdict(prepare(sc, folder))
    assert verdict == "unstable" and info["loop"] == ["ctrl_diag", "ctrl_long"]
    assert info["message"].startswith("the closed loops through ctrl_diag and ctrl_long, each "
                                      "on its own, are unstable")


def test_feedback_is_a_cycle_of_connections():
    class C:
        def __init__(self, s, t):
            self.source, self.target = s, t

    assert _has_feedback([C("a", "b"), C("b", "c"), C("c", "a")])
    assert not _has_feedback([C("a", "b"), C("b", "c"), C("a", "c")])
    assert not _has_feedback([])


def test_the_command_line_says_it_in_one_line_and_exits_1(folder, tmp_path, capsys):
    from orchestrator.cli import main

    code = main(["run", TRUSS, "--out", str(tmp_path / "o"), "--fmu-dir", str(folder),
                 "--set", "ctrl_diag.gain=2.9", "--stop", str(T_ON + 1.0), "--quiet"])
    err = capsys.readouterr().err
    assert code == 1
    said = [ln for ln in err.splitlines() if "unstable in the linear engine" in ln]
    assert len(said) == 1
    assert said[0].startswith("jitterfmu: unstable: the closed loop through ctrl_diag is ")
    assert (tmp_path / "o" / "results.parquet").exists()


@pytest.mark.filterwarnings("ignore:.*not connected and keep their start values")
def test_a_verdict_is_reused_for_runs_that_change_only_their_sources(folder, monkeypatch):
    """A campaign's events change their sources' parameters, not the loop: the second run
    of the same loop reuses the verdict (no second linearisation) and it is the one a
    fresh linearisation gives; a controller's gain or the run's end is another loop."""
    from orchestrator import linearcheck
    from orchestrator.analysis import scenario as lin_scenario
    from orchestrator.cosim import prepare

    monkeypatch.setattr(linearcheck, "_VERDICTS", {})
    monkeypatch.setattr(linearcheck, "_SOURCES", {})
    calls = []
    real = lin_scenario.linearize
    monkeypatch.setattr(lin_scenario, "linearize",
                        lambda *a, **k: calls.append(1) or real(*a, **k))

    def verdict(**overrides):
        stop = overrides.pop("stop", T_ON + 1.0)
        sc = load_scenario(TRUSS).with_overrides(overrides).with_experiment(stop=stop)
        return linear_verdict(prepare(sc, folder))

    first = verdict(**{"ctrl_diag.gain": 2.9})
    assert first[0] == "unstable" and len(calls) == 1
    again = verdict(**{"ctrl_diag.gain": 2.9, "excitation.amp1": 3.0, "excitation.freq1": 7.0})
    assert again == first and len(calls) == 1          # the sources differ: reused
    again[1]["loop"].append("changed by a caller")     # a copy: the kept one is unchanged
    assert verdict(**{"ctrl_diag.gain": 2.9})[1]["loop"] == ["ctrl_diag"]
    assert verdict(**{"ctrl_diag.gain": 2.7})[0] == "stable" and len(calls) == 2
    short = verdict(**{"ctrl_diag.gain": 2.9}, stop=T_ON - 1.0)   # ends before it closes
    assert short[0].startswith("unstable once the loop") and len(calls) == 3
    monkeypatch.setattr(linearcheck, "_VERDICTS", {})
    assert verdict(**{"ctrl_diag.gain": 2.9, "excitation.amp1": 3.0}) == first
