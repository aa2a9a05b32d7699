"""Figures of the EOS isolation experiments (Figs. 9 and 13-16 style), from their data.

matplotlib is imported when a figure is drawn.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fmukit.units import ARCSEC, ARCSEC_PER_RAD

__all__ = ["swir_figure", "testbed_figure"]


def swir_figure(off, on, out_dir, stem="swir-isolation", label="SWIR/VNIR mounts active"):
    """Draw the SWIR line of sight, mounts off and on (Fig. 9).

    Parameters
    ----------
    off, on : dict of str to ndarray
        Co-simulation tables (``swir_isolation.cosim``) with isolation off and on.
    out_dir : path-like
        Folder for the figure.
    stem : str
        File name without ``.png``.
    label : str
        Legend of the isolation-on curve.
    """
    # deferred: plotting only
    import matplotlib

    matplotlib.use("Agg")
    # deferred: plotting only
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for ax, a in zip(axes, ("roll", "pitch", "yaw")):
        for tab, lab in ((off, "mounts passive"), (on, label)):
            ax.plot(tab["time"], np.asarray(tab[f"structure.los_swir_{a}"]) / ARCSEC, lw=0.6,
                    label=lab)
        ax.set_ylabel(f"SWIR {a} (arcsec)")
        ax.grid(alpha=0.3)
    axes[0].legend()
    axes[0].set_title("SWIR line of sight, VNIR pointing disturbance (paper Fig. 9)")
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(Path(out_dir) / f"{stem}.png", dpi=110)
    plt.close(fig)


def _frequency_axes(ax, ylabel, title):
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)


#: Names the figure gives the testbed's configurations (the experiment's keys).
CONFIGURATION_NAMES = {"mount3": "mount #3", "all_mounts": "all three mounts"}


def testbed_figure(data, out_dir, stem="testbed-isolation", *, freqs, t_on, highpass,
                   record_t_on=None):
    """Figs. 13-16 style figure of the testbed isolation's data, written to ``<stem>.png``.

    Parameters
    ----------
    data : dict
        The result of ``testbed_isolation.compute``.
    out_dir : path-like
        Output folder (must exist).
    stem : str
        File name without ``.png``.
    freqs : ndarray, shape (n_f,)
        Frequencies of ``data["frf"]`` and ``data["ratio"]`` (Hz).
    t_on : float
        Switch-on time of the isolation (s).
    highpass : callable
        ``highpass(t, x)``: the boresight above the band the figure shows.
    record_t_on : float, optional
        Switch-on time the time history shows (s): its time axis is shifted by
        ``record_t_on - t_on`` (the paper's record starts on a settled response);
        default ``t_on`` (no shift).
    """
    # deferred: plotting only
    import matplotlib

    matplotlib.use("Agg")
    # deferred: plotting only
    import matplotlib.pyplot as plt

    FREQS, T_ON, _highpassed = freqs, t_on, highpass   # noqa: N806 (the experiment's names)
    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    ax = axes[0, 0]
    ax.loglog(FREQS, np.abs(data["frf"]["mount3"][0]), label="open loop (baseline)")
    ax.loglog(FREQS, np.abs(data["frf"]["mount3"][1]), label="mount #3 closed")
    ax.loglog(FREQS, np.abs(data["frf"]["all_mounts"][1]), ls="--", label="all mounts closed")
    _frequency_axes(ax, "accel. #6 / SWIR force ((m/s^2)/N)",
                    "Fig. 13 style: accelerometer #6 (payload, mount #3)")
    ax = axes[0, 1]
    # transmissibility: closed over open loop, below 1 where the mount isolates
    ax.loglog(FREQS, 1.0 / data["ratio"], label="mount #3")
    ax.loglog(FREQS, np.abs(data["frf"]["all_mounts"][1]) / np.abs(data["frf"]["all_mounts"][0]),
              ls="--", label="all three mounts")
    ax.axhline(1.0, color="0.5", lw=0.8)
    _frequency_axes(ax, "closed / open accel. #6 (below 1: isolating)",
                    "Fig. 14 style: transmissibility (linear model)")
    ax = axes[1, 0]
    t = data["off"]["time"]
    n = int(round(0.25 / (t[1] - t[0])))
    kernel = np.ones(n) / n

    def moving_rms(tab):
        r = _highpassed(t, tab["structure.los_misr_roll"])
        p = _highpassed(t, tab["structure.los_misr_pitch"])
        ms = np.convolve(r**2 + p**2, kernel, "same")
        ms[: n // 2], ms[-(n // 2):] = np.nan, np.nan  # partial windows at the ends
        return np.sqrt(ms) * ARCSEC_PER_RAD

    pitch3 = _highpassed(t, data["runs"]["mount3"]["structure.los_misr_pitch"]) * ARCSEC_PER_RAD
    shift = (T_ON if record_t_on is None else record_t_on) - T_ON
    shown = t + shift >= 0.0
    ts = t[shown] + shift
    ax.plot(ts, pitch3[shown], lw=0.3, color="C1", alpha=0.5, label="pitch, mount #3")
    ax.plot(ts, moving_rms(data["off"])[shown], color="0.3", label="RMS, isolation off")
    for k, c in (("mount3", "C1"), ("all_mounts", "C2")):
        ba = data["before_after"][k]["before_after_reduction_pct"]
        ax.plot(ts, moving_rms(data["runs"][k])[shown], color=c,
                label=f"RMS, {CONFIGURATION_NAMES[k]} ({ba:.0f} % before/after, "
                      f"{data['reduction'][k]:.0f} % two runs)")
    for edge in (w for win in data.get("windows", {}).values() for w in win):
        ax.axvline(edge + shift, color="0.8", ls=":", lw=0.8)
    ax.axvline(T_ON + shift, color="0.5", ls="--", lw=0.8)
    ax.set_xlabel("time (s)" if shift == 0 else
                  f"time of the record (s; the disturbance began {-shift:g} s before 0)")
    ax.set_ylabel("MISR boresight (arcsec, >5 Hz; RMS over 0.25 s)")
    ax.set_title(f"Fig. 15 style: boresight, isolation on at {T_ON + shift:g} s "
                 "(co-simulation)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax = axes[1, 1]
    a0, a1 = data.get("windows", {}).get("after", (data["stop"] - 1.2, data["stop"]))
    last = (t >= a0) & (t < a1)
    for tab, label in ((data["off"], "without isolation"),
                       (data["runs"]["mount3"], "with isolation (mount #3)")):
        r = _highpassed(t, tab["structure.los_misr_roll"]) * ARCSEC_PER_RAD
        p = _highpassed(t, tab["structure.los_misr_pitch"]) * ARCSEC_PER_RAD
        ax.plot(r[last], p[last], ".", ms=2, label=f"{label}, after-window")
    ax.set_xlabel("roll (arcsec)")
    ax.set_ylabel("pitch (arcsec)")
    ax.xaxis.set_major_locator(plt.MaxNLocator(5))
    ax.set_title("Fig. 16 style: image-plane jitter")
    # no requirement box: the paper states no jitter requirement for the testbed, and
    # the EOS budget's MISR value (campaigns/eos_budget.toml) is an assumption for the
    # flight scale, not this 1/10-load rig
    ax.text(0.98, 0.98, "no jitter requirement stated for the testbed", fontsize=7,
            ha="right", va="top", transform=ax.transAxes, color="0.35")
    ax.set_aspect("equal", "datalim")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower left", markerscale=4)
    fig.tight_layout()
    fig.savefig(Path(out_dir) / f"{stem}.png", dpi=110)
    plt.close(fig)
