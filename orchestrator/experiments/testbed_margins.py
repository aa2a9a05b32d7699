"""The testbed gains over the testbed's uncertainty: where the shipped factors come from.

``jitterfmu reproduce testbed-robust`` recomputes the numbers behind
``testbed_isolation.GAINS`` and the "what stops the gap" paragraph of
``docs/eos_experiments.md``: the nominal-only gains' stability limit (the largest factor
on them that keeps the sampled closed loop stable,
:func:`~orchestrator.experiments.testbed_robust.stability_limit`) on the nominal plant,
with the modal frequencies alone uncertain, with the damping alone halved, at the nine
common corners and at ``N_RANDOM`` per-mode points drawn with ``SEED``
(:func:`~orchestrator.experiments.testbed_robust.perturbed_plants`); the factor that
keeps 6 dB below the worst of them, against the stored one; and mount #3's linear
reduction at 6 dB below each of those limits.  A sampled check, not a certificate.
"""

from __future__ import annotations

import numpy as np

from ..progress import stage
from .testbed_isolation import (GAINS, MOUNTS, NOMINAL_GAINS, boresight_reduction,
                                ensure_fmus, linear_model, linear_plant, per_mount)
from .testbed_robust import perturbed_plants, stability_limit

NAME = "testbed-robust"
DESCRIPTION = "The testbed isolation gains over the testbed's uncertainty: stability " \
              "limits at its corners and per-mode points, the 6 dB factors"

#: Per-mode points of the stored design (and their seed); a quick run draws 4.
N_RANDOM = 40
SEED = 2026
MARGIN_DB = 6.0


def _ratio(k) -> float:
    """The stored factor of configuration ``k`` over its nominal-only gains."""
    r = np.array(per_mount(GAINS[k])) / np.array(per_mount(NOMINAL_GAINS[k]))
    return float(np.mean(r[np.isfinite(r)]))


def limits(model, n_random=N_RANDOM, seed=SEED) -> dict:
    """The nominal-only gains' stability limits per configuration and plant.

    Parameters
    ----------
    model : ReducedModel
        The nominal reduced testbed.
    n_random : int
        Per-mode points drawn.
    seed : int
        Their seed.

    Returns
    -------
    dict
        Per configuration (``mount3``, ``all_mounts``): plant name to limit (-).
    """
    plants = perturbed_plants(model, n_random=n_random, seed=seed)
    out = {}
    for k, mounts in MOUNTS.items():
        stage(f"testbed-robust: stability limits of the {k} gains on {len(plants)} plants")
        out[k] = {name: stability_limit(p, mounts, NOMINAL_GAINS[k])
                  for name, p in plants.items()}
    return out


def run(out_dir, quick: bool = False, fmu_dir="fmus", fmu_kind="native") -> dict:
    """The stability limits and 6 dB factors of the testbed gains.

    Parameters
    ----------
    out_dir : path-like
        Folder of the experiment's output (the JSON only).
    quick : bool
        4 per-mode points instead of ``N_RANDOM``.
    fmu_dir : path-like
        Folder of the FMUs, built there when missing or stale.
    fmu_kind : str
        The FMU build the model is read beside (``"native"`` or ``"python"``).

    Returns
    -------
    dict
        ``limits`` (per configuration and plant), and per configuration ``nominal``,
        ``frequencies_alone`` (the worse of f x0.95 and x1.05 at nominal damping),
        ``damping_halved`` (nominal frequencies), ``worst_corner``, ``worst`` (its plant
        and limit), ``factor_6db`` (worst limit less 6 dB), ``stored_factor`` (GAINS over
        NOMINAL_GAINS), ``stored_margin_db`` (the stored gains' margin over the set);
        ``reduction_at_6db_pct`` (mount #3, nominal plant, at 6 dB below each limit).
    """
    fdir = ensure_fmus(fmu_dir, "stiff", fmu_kind)
    model = linear_model(fdir)
    n = 4 if quick else N_RANDOM
    lim = limits(model, n, SEED)
    corners = [p for p in lim["mount3"] if not p.startswith("random")]
    out = {"n_random": n, "seed": SEED, "margin_db": MARGIN_DB, "limits": lim}
    for k in MOUNTS:
        L = lim[k]
        worst = min(L, key=L.get)
        stored = _ratio(k)
        out[k] = {"nominal": L["f1 z1"],
                  "frequencies_alone": min(L["f0.95 z1"], L["f1.05 z1"]),
                  "damping_halved": L["f1 z0.5"],
                  "worst_corner": min(L[c] for c in corners),
                  "worst": {"plant": worst, "limit": L[worst]},
                  "factor_6db": L[worst] * 10 ** (-MARGIN_DB / 20),
                  "stored_factor": stored,
                  "stored_margin_db": 20 * np.log10(L[worst] / stored)}
    plant = linear_plant(model)
    m3 = out["mount3"]
    out["reduction_at_6db_pct"] = {
        key: boresight_reduction(plant, (3,), NOMINAL_GAINS["mount3"] * m3[key]
                                 * 10 ** (-MARGIN_DB / 20))
        for key in ("nominal", "frequencies_alone", "damping_halved", "worst_corner")}
    out["reduction_at_6db_pct"]["worst"] = boresight_reduction(
        plant, (3,), NOMINAL_GAINS["mount3"] * m3["factor_6db"])
    return out


def summary(result) -> str:
    """The lines ``jitterfmu reproduce testbed-robust`` prints."""
    lines = [f"stability limits of the nominal-only gains (nine corners and "
             f"{result['n_random']} per-mode points, seed {result['seed']}):"]
    for k in MOUNTS:
        r = result[k]
        lines.append(f"  {k}: nominal {r['nominal']:.3f}, frequencies alone "
                     f"{r['frequencies_alone']:.3f}, damping halved {r['damping_halved']:.3f}, "
                     f"worst corner {r['worst_corner']:.3f}, worst {r['worst']['limit']:.3f} "
                     f"({r['worst']['plant']}); 6 dB factor {r['factor_6db']:.4f}, stored "
                     f"{r['stored_factor']:.4f} ({r['stored_margin_db']:.2f} dB over the set)")
    red = result["reduction_at_6db_pct"]
    lines.append("  mount #3 at 6 dB below each: " + ", ".join(
        f"{k} {v:.1f} %" for k, v in red.items()))
    return "\n".join(lines)
