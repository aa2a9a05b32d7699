"""Fig. 9: SWIR jitter (1.8 s) due to VNIR pointing, without and with active mounts.

Co-simulation of ``scenarios/eos_budget.toml`` with the ``vnir_pointing`` preset (the
VNIR telescope slews from t = 1 s): SWIR and VNIR active mounts (stack strain and
strain-rate feedback with a low-pass, ``controller_eos_isolation``) off, then on with the
campaign's gain.  Jitter is the windowed peak-to-peak over 1.8 s of the line of sight
(rigid-body motion included, as in the paper) and, to show what isolation can act on,
of the line of sight relative to the bus attitude sensor (``los - att``).

Loads are scaled by 1/10 in the scenario (the testbed's mass and stiffness scale), so
strokes and angles are those of the full-scale spacecraft, and full-scale forces are the
testbed's times 10.
"""

from __future__ import annotations

import numpy as np

from . import eos_budget

NAME = "swir-isolation"
DESCRIPTION = "Fig. 9: SWIR jitter due to VNIR pointing, SWIR/VNIR active mounts off and on"

GAIN = 0.1          # controller_eos_isolation gain (campaigns/eos_budget.toml)
WINDOW = 1.8
SKIP = 0.5
AXES = ("roll", "pitch", "yaw")
RAD_TO_ARCSEC = 206264.80624709636
N_TO_LBF = 0.2248089430997105
FULL_SCALE = 10.0   # force factor testbed -> EOS AM-1 (scenario loads x 0.1)


def _cosim(fmu_dir, gain, stop):
    from orchestrator.master import run_scenario

    ov = {"dist_vnir.preset": "vnir_pointing", "ctrl_swir.gain": gain, "ctrl_vnir.gain": gain}
    return run_scenario(eos_budget.SCENARIO, stop_time=stop, overrides=ov,
                        fmu_dir=fmu_dir).table


def jitter(tab, inst, relative=False) -> dict:
    """Windowed peak-to-peak (arcsec) per axis after ``SKIP`` s."""
    from orchestrator.metrics import peak_to_peak

    t = tab["time"]
    m = t >= SKIP
    dt = float(t[1] - t[0])
    out = {}
    for a in AXES:
        x = tab[f"structure.los_{inst}_{a}"]
        if relative:
            x = x - tab[f"structure.att_{a}"]
        out[a] = float(peak_to_peak(x[m], dt, WINDOW)) * RAD_TO_ARCSEC
    return out


def _pct(off, on):
    return {a: 100.0 * (1.0 - on[a] / off[a]) if off[a] > 0 else None for a in off}


def run(out_dir, quick: bool = False) -> dict:
    fdir = eos_budget.fmu_dir()
    stop = 3.5 if quick else 6.0
    off, on = _cosim(fdir, 0.0, stop), _cosim(fdir, GAIN, stop)
    sw_off, sw_on = jitter(off, "swir"), jitter(on, "swir")
    rel_off, rel_on = jitter(off, "swir", True), jitter(on, "swir", True)
    mi_off, mi_on = jitter(off, "misr"), jitter(on, "misr")
    misr_red = 100.0 * (1.0 - np.linalg.norm(list(mi_on.values()))
                        / np.linalg.norm(list(mi_off.values())))
    stroke = max(np.abs(on[f"structure.elong_{m}_mount"]).max() for m in ("swir", "vnir"))
    force = max(np.abs(on[f"piezo_{m}.force"]).max() for m in ("swir", "vnir"))
    red = _pct(sw_off, sw_on)
    plot(off, on, out_dir)
    reproduced = (red["pitch"] > 50 and red["yaw"] > 50 and 10 <= red["roll"] <= 50
                  and 0 < misr_red <= 30 and stroke * 1e6 < 5
                  and force * FULL_SCALE * N_TO_LBF < 15)
    return {
        "swir_jitter_off_arcsec": sw_off,
        "swir_jitter_on_arcsec": sw_on,
        "reduction_pct": red,
        "swir_relative_jitter_off_arcsec": rel_off,
        "swir_relative_jitter_on_arcsec": rel_on,
        "relative_reduction_pct": _pct(rel_off, rel_on),
        "misr_jitter_off_arcsec": mi_off,
        "misr_jitter_on_arcsec": mi_on,
        "misr_reduction_pct": float(misr_red),
        "max_stroke_um": float(stroke * 1e6),
        "max_force_lbf": float(force * FULL_SCALE * N_TO_LBF),
        "max_force_lbf_testbed_scale": float(force * N_TO_LBF),
        "gain": GAIN,
        "stop_s": stop,
        "paper": {"reduction_pct": {"roll": 30, "pitch": "large", "yaw": "large"},
                  "misr_reduction_pct": 10, "max_stroke_um": "< 5", "max_force_lbf": "< 15",
                  "swir_jitter_off_arcsec": 1.0},
        "reproduced": bool(reproduced),
        "note": ("Reproduced." if reproduced else
                 "Not reproduced: with the assumed VNIR pointing preset (a 4 N m, 0.05 s "
                 "torque pulse about roll, scaled 1/10) the SWIR line of sight is dominated "
                 "by rigid-body motion of the whole model (the same in every instrument), "
                 "which mount isolation cannot remove; the paper's 1 arcsec/1.8 s in all "
                 "axes implies a much smaller rigid-body share. The relative (LOS - "
                 "attitude) jitter shows what the mounts act on."),
    }


def plot(off, on, out_dir):
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for ax, a in zip(axes, AXES):
        for tab, lab in ((off, "mounts passive"), (on, "SWIR/VNIR mounts active")):
            ax.plot(tab["time"], tab[f"structure.los_swir_{a}"] * RAD_TO_ARCSEC, lw=0.6,
                    label=lab)
        ax.set_ylabel(f"SWIR {a} (arcsec)")
        ax.grid(alpha=0.3)
    axes[0].legend()
    axes[0].set_title("SWIR line of sight, VNIR pointing disturbance (paper Fig. 9)")
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(Path(out_dir) / "swir-isolation.png", dpi=110)
    plt.close(fig)
