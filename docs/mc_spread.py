"""Where a Monte Carlo's spread comes from: the amplitudes, the modes, the unstable samples.

Reads the samples a linear-engine ``jitterfmu campaign`` kept (``OUT/uncertainty_parts``)
and their draws (reproduced from the campaign's seed), and prints per line of one
configuration the bootstrap width of its ``P_c`` value (default the first level) in four
ways:

* ``all``: the samples as they are (what ``uncertainty.json`` says);
* ``modes only``: every event's metric divided by its source's amplitude factor (each
  event has one source, and a linear record scales with it exactly), so only the other
  inputs vary;
* ``amplitudes only``: each event's modal part held at its median over the samples, times
  the sample's amplitude factor;
* ``stable only`` against ``random subset``: the samples whose loop is stable, and as many
  samples taken at random (does the instability make the tail?).

Run::

    .venv/bin/python docs/mc_spread.py CAMPAIGN.toml OUT [--uncertainty U.toml]
        [--configuration NAME]

The campaign (with ``--uncertainty`` and ``--samples`` as the run had them) must be the
one that wrote ``OUT`` (the kept samples are found by its
identity), with an ``amplitude`` uncertainty on the source of every event.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np


def split(camp, events, out, runner, configuration=None) -> dict:
    """The widths of one configuration's lines, four ways (the module's text).

    Parameters
    ----------
    camp : Campaign
        The campaign that wrote ``out`` (:func:`orchestrator.campaign.load_campaign`).
    events : sequence of Variant
        Its events (``orchestrator.campaign.spec.read_spec(path).events``).
    out : path
        The campaign's output folder.
    runner : LinearRunner
        On the FMUs the samples were computed with.
    configuration : str, optional
        Default the first.

    Returns
    -------
    dict
        ``configuration``, ``samples``, ``stable`` and ``lines``: label -> ``{all,
        modes, amplitudes, stable, random, log_std}`` (widths relative to the value; NaN
        where the value is infinite).

    Raises
    ------
    ValueError
        One sentence: no uncertainty, no kept samples, an event without exactly one
        amplitude-drawn source, an unknown configuration.
    """
    from orchestrator.analysis.uncertainty import draw, statistics
    from orchestrator.campaign import montecarlo as mcm

    unc = camp.uncertainty
    if not unc:
        raise ValueError("the campaign has no [uncertainty] table")
    source = {}   # event -> (its amplitude draw, its instance)
    for ev in events:
        found = [(it, inst) for it in unc["parameters"] if it.kind == "amplitude"
                 for inst in it.instances
                 if any(k.partition(".")[0] == inst for k in ev.overrides)]
        if len(found) != 1:
            raise ValueError(f"event {ev.name!r} has {len(found)} amplitude-drawn sources; "
                             "the split needs exactly one per event")
        source[ev.name] = found[0]
    ctx = mcm._setup(camp, runner)
    identity = mcm._identity(camp, runner, ctx)
    folder = Path(out) / mcm.PARTS_DIR / identity[:24]
    n = unc.get("max_samples") or unc["samples"]   # the most a run of this file keeps
    v = np.full((n, len(ctx["configs"]), len(ctx["events"]), len(ctx["pairs"]),
                 len(camp.metrics)), np.nan)
    st = np.zeros((n, len(ctx["configs"])), int)
    done = mcm.load_parts(folder, v, st, identity)   # checked as a resumed run does
    if not done.any():
        raise ValueError(f"no kept samples of this campaign under {folder}: run `jitterfmu "
                         "campaign` of the same file into that folder first")
    lin0, structs, _ = ctx["base"][ctx["configs"][0]]
    freqs = lin0.blocks[structs[0]].model.frequencies_hz if structs else None
    inputs = {k: x[done] for k, x in
              draw(unc["parameters"], n, unc["seed"], freqs).scalar_inputs().items()}
    v, st, n = v[done], st[done], int(done.sum())
    amp = {e: inputs[f"{it.name} [{inst}]"] if len(it.instances) > 1 else inputs[it.name]
           for e, (it, inst) in source.items()}   # event -> its amplitude factor (n,)
    cfs = ctx["configs"]
    cf = configuration or cfs[0]
    if cf not in cfs:
        raise ValueError(f"no configuration {cf!r}; the campaign has {cfs}")
    ci, pc = cfs.index(cf), unc["confidence"][0]
    A = np.stack([amp[e] for e in ctx["events"]], axis=1)                 # (n, events)
    stable = (st[:, ci] & mcm.UNSTABLE) == 0
    subset = np.random.default_rng(0).choice(n, int(stable.sum()), replace=False)

    def width(x):
        q = statistics(x, [pc], seed=unc["seed"])["quantiles"][float(pc)]   # as the run
        return q["rel_width"] if np.isfinite(q["value"]) else np.nan

    lines = {}
    for j, (inst, axis, _) in enumerate(ctx["pairs"]):
        for k, (kind, window) in enumerate(camp.metrics):
            x = v[:, ci, :, j, k]                                          # (n, events)
            modal = x / A
            full = np.sqrt((x ** 2).sum(1))
            if not np.all(np.isfinite(full)) or full.max() == 0:
                continue
            lines[f"{inst} {axis} {kind}" + ("" if window is None else f" {window:g}")] = {
                "all": width(full), "modes": width(np.sqrt((modal ** 2).sum(1))),
                "amplitudes": width(np.sqrt(((np.median(modal, 0) * A) ** 2).sum(1))),
                "stable": width(full[stable]) if stable.any() else np.nan,
                "random": width(full[subset]) if stable.any() else np.nan,
                "log_std": float(np.std(np.log(full)))}
    return {"configuration": cf, "confidence": pc, "samples": n,
            "stable": int(stable.sum()), "lines": lines}


def main(argv=None) -> int:
    """Print the table; 1 with one sentence when the inputs do not fit."""
    from orchestrator.campaign import LinearRunner, load_campaign
    from orchestrator.campaign.spec import read_spec

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaign")
    ap.add_argument("out")
    ap.add_argument("--uncertainty", help="the run's [uncertainty] file, if it had one")
    ap.add_argument("--samples", type=int, help="the run's --samples, if it had one")
    ap.add_argument("--configuration", help="default: the first")
    ap.add_argument("--fmu-dir", default="fmus")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    camp = load_campaign(args.campaign, args.uncertainty, args.samples)
    try:
        r = split(camp, read_spec(args.campaign, args.uncertainty, args.samples).events,
                  args.out,
                  LinearRunner(camp.scenario_dir, fmu_dir=args.fmu_dir), args.configuration)
    except ValueError as exc:
        print(f"mc_spread: {exc}", file=sys.stderr)
        return 1
    cols = ("all", "modes", "amplitudes", "stable", "random")
    print(f"{r['configuration']}, {r['samples']} samples ({r['stable']} stable): relative "
          f"width of the {100 * r['confidence']:g} % value's bootstrap interval, and the "
          "spread of the budget (std of its log)")
    print(f"{'line':28s} " + " ".join(f"{c[:7]:>7s}" for c in cols) + "  std(log)")
    for label, w in r["lines"].items():
        print(f"{label:28.28s} " + " ".join(f"{100 * w[c]:6.1f}%" for c in cols)
              + f"  {w['log_std']:.3f}")
    if r["lines"]:
        med = {c: np.nanmedian([w[c] for w in r["lines"].values()]) for c in cols + ("log_std",)}
        print(f"{'median':28s} " + " ".join(f"{100 * med[c]:6.1f}%" for c in cols)
              + f"  {med['log_std']:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
