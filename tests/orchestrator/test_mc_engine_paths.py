"""What the Monte Carlo says about its engine: which loop a sample runs on (the nominal
one, the structured patch of its modal blocks, or the dense engine) and how its poles are
decided (counted from the structure, or dense eigenvalues), each with its reason.

The reference is what a sample does: spies on the records' loop type, on the winding
count and on the eigenvalue solver while ``montecarlo._evaluate`` runs that sample.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from orchestrator.analysis import structpoles, structured
from orchestrator.analysis.fast import FastResponse
from orchestrator.analysis.uncertainty import draw
from orchestrator.campaign import LinearRunner, campaign_from_dict, load_campaign
from orchestrator.campaign import montecarlo as mcm
from orchestrator.campaign.mcloop import engine_paths, path_lines

ROOT = Path(__file__).resolve().parents[2]


def _draws(camp, ctx, n=1):
    lin0, structs, _ = ctx["base"][ctx["configs"][0]]
    freqs = lin0.blocks[structs[0]].model.frequencies_hz if structs else None
    return draw(camp.uncertainty["parameters"], n, camp.uncertainty["seed"], freqs)


def _spied_sample(camp, runner, ctx, draws, monkeypatch) -> dict:
    """Run sample 0 with spies: per memory state, the loop types whose records ran, the
    winding counts and the sizes of the matrices whose eigenvalues were taken."""
    seen = {"loops": {}, "winding": 0, "eig": []}
    run_many, winding, eigvals = (FastResponse.run_many, structpoles.winding_count,
                                  np.linalg.eigvals)

    def spy_run_many(self, *a, **k):
        seen["loops"].setdefault(self.n_memory, set()).add(type(self).__name__)
        return run_many(self, *a, **k)

    def spy_winding(*a, **k):
        seen["winding"] += 1
        return winding(*a, **k)

    def spy_eigvals(A):
        seen["eig"].append(np.shape(A)[0])
        return eigvals(A)

    monkeypatch.setattr(FastResponse, "run_many", spy_run_many)
    monkeypatch.setattr(structpoles, "winding_count", spy_winding)
    monkeypatch.setattr(np.linalg, "eigvals", spy_eigvals)
    mcm._evaluate(camp, runner, ctx, draws, [0])
    monkeypatch.undo()
    return seen


@pytest.fixture(scope="module")
def eos_mc(eos_loops):
    """The shipped EOS Monte Carlo cut to its RWA event (both configurations)."""
    from orchestrator.experiments import eos

    _, runner, _ = eos_loops
    camp = load_campaign(eos.CAMPAIGN, eos.CAMPAIGN.parent / "eos_uncertainty.toml", 1)
    return dataclasses.replace(camp, cases=tuple(
        c for c in camp.cases if c.event == "RWA" and not c.sweep)), runner


@pytest.mark.slow
def test_eos_paths_are_what_a_sample_does(eos_mc, monkeypatch):
    """Both configurations run structured; isolation off counts its poles from the
    structure (no eigenvalues of its memory state are taken), isolation on takes them
    (and says why); the printed lines say the same."""
    camp, runner = eos_mc
    ctx = mcm._setup(camp, runner)
    draws = _draws(camp, ctx)
    paths = engine_paths(ctx, camp.uncertainty["parameters"], draws)
    ctx = mcm._setup(camp, runner)   # fresh nominal loops: nothing kept from the paths
    seen = _spied_sample(camp, runner, ctx, draws, monkeypatch)
    size = {cf: ctx["base"][cf][2].n_memory for cf in ctx["configs"]}
    off, on = paths["isolation off"], paths["isolation on"]
    for cf in ("isolation off", "isolation on"):
        assert paths[cf]["loop"] == "structured" and paths[cf]["loop_why"] is None
        assert seen["loops"][size[cf]] == {"StructuredResponse"}
    assert off["poles"] == "counted from the structure" and off["poles_why"] is None
    assert seen["winding"] >= 1 and size["isolation off"] not in seen["eig"]
    assert on["poles"] == "eigenvalues" and size["isolation on"] in seen["eig"]
    assert "100 of the super-period's 100 ticks" in on["poles_why"]
    lines = path_lines(paths)
    assert lines[0] == ("  isolation off: structured loop (the nominal modal blocks "
                        "patched); poles counted from the structure")
    assert lines[1].startswith("  isolation on: structured loop") and (
        "poles by dense eigenvalues (the coupling reads" in lines[1])


@pytest.mark.slow
def test_a_form_that_does_not_pay_runs_dense_and_says_why(eos_mc, monkeypatch):
    """With the structured form never paying, every sample runs the dense engine, whose
    poles are eigenvalues; the reason is the loop's own sentence."""
    camp, runner = eos_mc
    monkeypatch.setattr(structured, "_PAYS", 0.0)
    ctx = mcm._setup(camp, runner)
    draws = _draws(camp, ctx)
    paths = engine_paths(ctx, camp.uncertainty["parameters"], draws)
    seen = _spied_sample(camp, runner, dict(ctx), draws, monkeypatch)
    for cf, p in paths.items():
        n = ctx["base"][cf][2].n_memory
        assert p["loop"] == "dense" and p["poles"] == "eigenvalues"
        assert "is not low rank" in p["loop_why"] and "dense engine runs it" in p["loop_why"]
        assert seen["loops"][n] == {"FastResponse"} and n in seen["eig"]
    assert seen["winding"] == 0
    assert all(line.split(": ", 1)[1].startswith("dense loop (the coupling of")
               for line in path_lines(paths))


@pytest.mark.slow
def test_a_gain_draw_runs_dense_and_says_why(eos_mc, monkeypatch):
    """A controller's gain drawn beside the modes: the structured form patches the
    modes only, so the sample runs the dense engine, and the reason says so."""
    from orchestrator.analysis.uncertainty import Distribution, Uncertain

    camp, runner = eos_mc
    ctx = mcm._setup(camp, runner)
    ctrl = ctx["base"]["isolation off"][0].controllers()[0]
    gain = Uncertain("g", "gain", Distribution("uniform", 0.9, 1.1), instances=(ctrl,))
    camp = dataclasses.replace(camp, uncertainty={
        **camp.uncertainty, "parameters": (*camp.uncertainty["parameters"], gain)})
    draws = _draws(camp, ctx)
    paths = engine_paths(ctx, camp.uncertainty["parameters"], draws)
    seen = _spied_sample(camp, runner, mcm._setup(camp, runner), draws, monkeypatch)
    for cf, p in paths.items():
        n = ctx["base"][cf][2].n_memory
        assert p["loop"] == "dense" and p["poles"] == "eigenvalues"
        assert "(a controller's gain)" in p["loop_why"]
        assert seen["loops"][n] == {"FastResponse"} and n in seen["eig"]
    assert seen["winding"] == 0


@pytest.mark.slow
def test_a_sample_the_form_refuses_runs_dense_with_the_refusal(eos_mc, monkeypatch):
    """A sample whose structure the nominal form does not cover (here every sample's
    static Ritz block, with the tolerance below zero) runs dense; the reason is the
    form's own refusal, not a guess."""
    camp, runner = eos_mc
    ctx = mcm._setup(camp, runner)
    for cf in ctx["configs"]:   # the nominal forms, built at the shipped tolerance
        assert structured.modal_loop(ctx["base"][cf][2]) is not None
    monkeypatch.setattr(structured, "_FORM_TOL", -1.0)
    draws = _draws(camp, ctx)
    paths = engine_paths(ctx, camp.uncertainty["parameters"], draws)
    seen = _spied_sample(camp, runner, ctx, draws, monkeypatch)
    for cf, p in paths.items():
        assert p["loop"] == "dense" and p["poles"] == "eigenvalues"
        assert p["loop_why"] == ("the sample's structure 'structure' changes its static "
                                 "Ritz block: the dense engine runs it")
        assert seen["loops"][ctx["base"][cf][2].n_memory] == {"FastResponse"}


@pytest.mark.slow
@pytest.mark.parametrize("certain", [True, False])
def test_the_run_counts_how_each_sample_was_taken(eos_mc, tmp_path, monkeypatch, certain):
    """``uncertainty.json`` counts, per configuration, the samples run on the dense loop
    and those whose poles the eigenvalues decided: none and none isolation off, none and
    all isolation on; with the winding never certain, isolation off's poles fall back to
    the eigenvalues in every sample, and the count and the printed line say so."""
    import json

    from orchestrator.campaign import run_uncertainty

    camp, runner = eos_mc
    camp = dataclasses.replace(camp, uncertainty={**camp.uncertainty, "samples": 3,
                                                  "max_samples": None})
    if not certain:
        monkeypatch.setattr(structpoles, "winding_count", lambda *a, **k: (None, 0))
    path = run_uncertainty(camp, tmp_path, runner, progress=False, workers=0)
    got = json.loads(path.read_text())["linear_engine"]
    off, on = got["isolation off"], got["isolation on"]
    assert off["samples"] == on["samples"] == 3 and off["dense_loop"] == on["dense_loop"] == 0
    assert on["poles_by_eigenvalues"] == 3
    assert off["poles_by_eigenvalues"] == (0 if certain else 3)
    assert off["poles"] == "counted from the structure"   # what it tries first
    lines = path_lines(got)
    assert lines[0].endswith("3 of 3 samples; poles counted from the structure, " + (
        "3 of 3" if certain else
        "0 of 3 (3 by dense eigenvalues: the count was not certain)"))


def _truss(parameters):
    return campaign_from_dict({
        "campaign": {"name": "mc", "scenario": str(ROOT / "scenarios/truss10_campaign.toml"),
                     "unit": "arcsec", "skip": 0.0, "stop": 0.5, "output_interval": 1e-3,
                     "engine": "linear", "verify": 0},
        "events": [{"name": "diagonal", "overrides": {"excitation.amp1": 10.0}}],
        "configurations": [{"name": "on", "overrides": {"ctrl_diag.gain": 1.0,
                                                        "ctrl_long.gain": 1.0}}],
        "instruments": [{"name": "tip", "axes": {"roll": "structure.los_tip_roll"}}],
        "metrics": [{"kind": "rms"}],
        "uncertainty": {"samples": 1, "seed": 3, "confidence": [0.5],
                        "parameters": parameters}})


@pytest.fixture(scope="module")
def truss_fmus(suite_fmus, suite_fmu_dir):
    from tests.orchestrator.test_truss10_campaign import FMUS
    suite_fmus(*FMUS)
    return suite_fmu_dir


_UNIFORM = {"distribution": "uniform", "low": 0.9, "high": 1.1}


@pytest.mark.slow
@pytest.mark.parametrize("parameters, loop, words, kind", [
    ([{"name": "a", "kind": "amplitude", "instances": ["excitation"], **_UNIFORM}],
     "nominal", "no draw changes the loop", "FastResponse"),
    ([{"name": "f", "kind": "modal_frequency", **_UNIFORM}],
     "dense", "is not low rank", "FastResponse"),
])
def test_truss_paths_are_what_a_sample_does(truss_fmus, monkeypatch, parameters, loop,
                                            words, kind):
    """Amplitudes alone: every sample shares the nominal loop and takes no poles.  The
    truss's modes: its coupling does not pay, so dense, with the loop's own reason."""
    camp = _truss(parameters)
    runner = LinearRunner(camp.scenario_dir, fmu_dir=truss_fmus)
    ctx = mcm._setup(camp, runner)
    draws = _draws(camp, ctx)
    p = engine_paths(ctx, camp.uncertainty["parameters"], draws)["on"]
    assert p["loop"] == loop and words in p["loop_why"]
    seen = _spied_sample(camp, runner, mcm._setup(camp, runner), draws, monkeypatch)
    n = ctx["base"]["on"][2].n_memory
    assert seen["loops"][n] == {kind} and seen["winding"] == 0
    assert (n in seen["eig"]) == (loop != "nominal")
    assert p["poles"] == ("none" if loop == "nominal" else "eigenvalues")
    assert words in path_lines({"on": p})[0]
