"""Figs. 13-15: EOS Dynamics Testbed, MISR payload isolation against a 22 Hz disturbance.

Co-simulation of ``scenarios/eos_budget.toml`` with the ``swir_cryocooler`` preset at the
SWIR location (22, 44, 66 Hz) and the MISR strut controllers switched on at t = 2.4 s
(``t_on``), with isolator mount #3 alone and with all three.  The jitter reduction is
computed from the co-simulated MISR boresight roll and pitch: RMS over [1.2, 2.4) s
before and over the last 1.2 s after switch-on (the optical scoring system measures roll
and pitch).  The suspended testbed has no ACS; our scenario keeps its 0.1 Hz ACS, and
the slow rigid-body motion (< 5 Hz) is removed by a zero-phase high-pass before the RMS,
as an optical scoring record of a suspended article would be read.

The transmissibility (Fig. 14) is computed from the linear models: the reduced structure
(the FMU's own ``model.npz``), sampled with a zero-order hold at 1 kHz, the controller's
discrete law and one sample of amplifier delay; it is the ratio of open-loop to closed-
loop payload acceleration at strut #3 (our "accelerometer #6") for a SWIR-location
vertical force.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import eos_budget

NAME = "testbed-isolation"
DESCRIPTION = "Figs. 13-15: MISR active isolator struts against a 22 Hz SWIR-location " \
              "disturbance, switched on at 2.4 s"

T_ON = 2.4
#: Strut controller gain (multiplier of the design's gains) per configuration, chosen on
#: the linear model with the accelerometers' 150 Hz low-pass: half the stability limit
#: (about -1 for mount #3 alone, -0.45 for all three; the loops go unstable at 40, 48 and
#: 158 Hz, and at 31 and 119 Hz).
GAINS = {"mount3": -0.5, "all_mounts": -0.2}
MOUNTS = {"mount3": (3,), "all_mounts": (1, 2, 3)}
CH = 26.8  # N/V: P-845.37 k_e d0 / V0 = 6.70e7 N/m x 0.4 um/V
HP_HZ = 5.0
FREQS = np.geomspace(2.0, 300.0, 300)


def _cosim(fmu_dir, mounts, gain, stop):
    from orchestrator.master import run_scenario

    ov = {"dist_swir.preset": "swir_cryocooler"}
    for i in (1, 2, 3):
        ov[f"ctrl_iso{i}.gain"] = gain if i in mounts else 0.0
        ov[f"ctrl_iso{i}.t_on"] = T_ON
    return run_scenario(eos_budget.SCENARIO, stop_time=stop, overrides=ov,
                        fmu_dir=fmu_dir).table


def boresight_rms(t, roll, pitch, t0, t1):
    """RMS of the high-passed boresight (roll, pitch) over [t0, t1) (rad)."""
    from scipy.signal import butter, sosfiltfilt

    dt = t[1] - t[0]
    sos = butter(2, HP_HZ, "highpass", fs=1.0 / dt, output="sos")
    m = (t >= t0) & (t < t1)
    r, p = sosfiltfilt(sos, roll), sosfiltfilt(sos, pitch)
    return float(np.sqrt(np.mean(r[m] ** 2 + p[m] ** 2)))


def linear_model():
    """The reduced structure packed in the structure FMU (a ReducedModel)."""
    import tempfile
    import zipfile

    from structfmu.reduced import ReducedModel

    fmu = Path(eos_budget.fmu_dir()) / f"{eos_budget.STRUCTURE}.fmu"
    with zipfile.ZipFile(fmu) as z, tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.npz"
        path.write_bytes(z.read("resources/model.npz"))
        return ReducedModel.load(path)


def transmissibility(model, mounts=(3,), gain=GAINS["mount3"], freqs=FREQS):
    """Open-loop / closed-loop payload acceleration at strut #3 for a SWIR vertical force.

    Returns
    -------
    ratio : ndarray, shape (n_freq,)
        |a_open| / |a_closed| (> 1: isolated).
    stable : bool
        All closed-loop poles inside the unit circle (rigid-body poles at 1 excepted).
    """
    import control
    from ctrlfmu.analysis import to_statespace
    from ctrlfmu.designs import design
    from structfmu.statespace import first_order

    A, B, C, D = first_order(model)
    ins, outs = list(model.input_names), list(model.output_names)
    yo = [f"acc_{s}_iso{i}" for i in (1, 2, 3) for s in ("pay", "bus")]
    ii = [ins.index(n) for n in ("fc_iso1", "fc_iso2", "fc_iso3", "swir_fz")]
    oo = [outs.index(n) for n in yo + ["acc_pay_iso3"]]
    G = control.sample_system(control.ss(A, B[:, ii], C[oo], D[np.ix_(oo, ii)]), 1e-3, "zoh")
    law = to_statespace(design("testbed_isolation"))
    delay = control.ss([[0.0]], [[1.0]], [[1.0]], [[0.0]], 1e-3)
    off = control.ss([], [], [], np.zeros((1, 2)), 1e-3)
    K = control.append(*[(gain * CH * delay * law) if i in mounts else off for i in (1, 2, 3)],
                       control.ss([], [], [], np.zeros((1, 1)), 1e-3))
    cl = control.feedback(G, K, sign=+1)
    ev = np.linalg.eigvals(cl.A)
    stable = bool(np.all(np.abs(ev[np.abs(ev - 1) > 1e-6]) < 1.0))
    z = np.exp(2j * np.pi * np.asarray(freqs) * 1e-3)
    ho = np.array([np.asarray(G(zz))[6, 3] for zz in z])
    hc = np.array([np.asarray(cl(zz))[6, 3] for zz in z])
    return np.abs(ho) / np.abs(hc), stable


def compute(quick=False):
    fdir = eos_budget.fmu_dir()
    stop = 4.0 if quick else 4.8
    runs = {k: _cosim(fdir, MOUNTS[k], GAINS[k], stop) for k in MOUNTS}
    red, before_after, sat = {}, {}, {}
    for k, tab in runs.items():
        t = tab["time"]
        r, p = tab["structure.los_misr_roll"], tab["structure.los_misr_pitch"]
        b = boresight_rms(t, r, p, T_ON - 1.2, T_ON)
        a = boresight_rms(t, r, p, stop - 1.2, stop)
        before_after[k] = {"before_arcsec_rms": b * 206264.8, "after_arcsec_rms": a * 206264.8}
        red[k] = 100.0 * (1.0 - a / b)
        sat[k] = float(max(np.abs(tab[f"piezo_iso{i}.voltage"]).max() for i in (1, 2, 3)))
    model = linear_model()
    ratio, stable = transmissibility(model)
    ratio_all, stable_all = transmissibility(model, mounts=(1, 2, 3),
                                             gain=GAINS["all_mounts"])
    iso = ratio > 1.0
    bw = float(FREQS[np.flatnonzero(iso)[-1]]) if iso.any() else None
    above = FREQS > (bw or 0.0)
    return {"runs": runs, "reduction": red, "before_after": before_after,
            "max_voltage": sat, "ratio": ratio, "ratio_all": ratio_all,
            "stable": stable and stable_all, "bandwidth": bw,
            "amplification": float(1.0 / ratio[above].min()) if above.any() else None}


def plot(data, out_dir):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1, figsize=(8, 6.5))
    ax = axes[0]
    ax.loglog(FREQS, data["ratio"], label="mount #3 alone")
    ax.loglog(FREQS, data["ratio_all"], label="all three mounts")
    ax.axhline(1.0, color="0.5", lw=0.8)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("open-loop / closed-loop accel.")
    ax.set_title("Transmissibility at strut #3 (linear model; paper Fig. 14)")
    ax.grid(alpha=0.3, which="both")
    ax.legend()
    ax = axes[1]
    for k, tab in data["runs"].items():
        ax.plot(tab["time"], tab["structure.los_misr_pitch"] * 206264.8, lw=0.5, label=k)
    ax.axvline(T_ON, color="0.5", ls="--", lw=0.8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("MISR pitch (arcsec)")
    ax.set_title("MISR boresight, isolation on at 2.4 s (co-simulation; paper Fig. 15)")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(Path(out_dir) / "testbed-isolation.png", dpi=110)
    plt.close(fig)


def run(out_dir, quick: bool = False) -> dict:
    data = compute(quick)
    plot(data, out_dir)
    red = data["reduction"]
    reproduced = (red["mount3"] >= 60.0 and 50.0 <= red["all_mounts"] <= 90.0
                  and data["bandwidth"] is not None and 30.0 <= data["bandwidth"] <= 60.0)
    note = ("Reproduced within the paper's ranges." if reproduced else
            "Not reproduced: on this structure model the P-845.37 struts are so stiff "
            "(strut-payload mode near 600 Hz) that the payload follows the bus at 22 Hz; the "
            "payload acceleration a strut commands at 22 Hz is small (6e-3 m/s^2 per V), so "
            "at the design's gain the loop gain at 22 Hz is only about 0.14, and the loops "
            "go unstable near that gain through the 31-48 Hz payload and bus modes (and "
            "119-158 Hz). The gains used, half the stability limits "
            f"({GAINS['mount3']} for mount #3, {GAINS['all_mounts']} for all three), give a "
            "stable but small isolation; see docs/eos_experiments.md.")
    return {
        "jitter_reduction_pct": red,
        "boresight_rms": data["before_after"],
        "isolation_bandwidth_hz": data["bandwidth"],
        "amplification_above_bandwidth": data["amplification"],
        "closed_loop_stable_linear": data["stable"],
        "max_strut_voltage_v": data["max_voltage"],
        "gain": GAINS,
        "t_on_s": T_ON,
        "paper": {"jitter_reduction_pct": {"mount3": 80, "all_mounts": [50, 80]},
                  "isolation_bandwidth_hz": 45},
        "reproduced": bool(reproduced),
        "note": note,
        "transmissibility": {"freq_hz": FREQS, "mount3": data["ratio"],
                             "all_mounts": data["ratio_all"]},
    }
