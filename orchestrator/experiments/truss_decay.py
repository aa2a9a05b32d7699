"""Figs. 5-6: ten-bay truss decay, open loop and with 250 Hz strain feedback.

Both runs co-simulate the FMUs of ``scenarios/truss10_closed_loop.toml`` (structure,
two piezo amplifiers, two controllers, excitation): sine voltages on the diagonal
(8.4 Hz) and the longeron (9.5 Hz) for 4.5 s, then free decay (controller gain 0) or
control.  Damping is identified from the free decay by fitting two exponentially
decaying sinusoids to each gauge; "cycles to 90 %" is the time after 4.5 s until the
one-period running peak of the gauge strain stays below 10 % of its value over the last
excitation period, times the mode frequency.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

NAME = "truss-decay"
DESCRIPTION = "Figs. 5-6: ten-bay truss open-loop decay and 250 Hz strain-feedback control"

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "truss10_closed_loop.toml"
FMUS = ("truss10_structure", "piezo_p243_40", "piezo_p243_30",
        "controller_truss10_strain_diag", "controller_truss10_strain_long", "excitation")
T_EXC = 4.5
MODES = {"diagonal": ("structure.strain_diag", 8.4), "longeron": ("structure.strain_long", 9.5)}


def fit_two_modes(t, y, f_guess):
    """Fit ``sum_k a_k exp(-s_k t) cos(2 pi f_k t + p_k)`` to a decay.

    Returns
    -------
    freqs : ndarray, shape (2,)
        Damped frequencies (Hz).
    zetas : ndarray, shape (2,)
        Damping ratios.
    """
    from scipy.optimize import least_squares

    t = t - t[0]
    scale = np.abs(y).max()
    yy = y / scale

    def model(p):
        out = np.zeros_like(t)
        for k in range(2):
            a, s, f, ph = p[4 * k:4 * k + 4]
            out += a * np.exp(-s * t) * np.cos(2 * np.pi * f * t + ph)
        return out

    best = None
    for ph1 in (0.0, np.pi / 2, np.pi, 3 * np.pi / 2):
        for ph2 in (0.0, np.pi):
            p0 = [0.5, 0.1, f_guess[0], ph1, 0.5, 0.2, f_guess[1], ph2]
            res = least_squares(lambda p: model(p) - yy, p0, method="lm", max_nfev=4000)
            if best is None or res.cost < best.cost:
                best = res
    p = best.x
    freqs = np.array([p[2], p[6]])
    sig = np.array([p[1], p[5]])
    wd = 2 * np.pi * np.abs(freqs)
    zetas = sig / np.sqrt(sig**2 + wd**2)
    order = np.argsort(np.abs(freqs))
    return np.abs(freqs)[order], zetas[order]


def cycles_to_fraction(t, y, f_hz, t0=T_EXC, fraction=0.1):
    """Cycles after ``t0`` until the running one-period peak of |y| falls below
    ``fraction`` of its value over the last period before ``t0``; None if never."""
    from scipy.ndimage import maximum_filter1d

    dt = t[1] - t[0]
    n = max(1, int(round(1.0 / (f_hz * dt))))
    a = np.abs(y)
    ref = a[(t > t0 - 1.0 / f_hz) & (t <= t0)].max()
    # forward-looking running max over one period
    peak = maximum_filter1d(a, size=n, origin=-(n // 2))
    after = np.flatnonzero((t >= t0) & (peak < fraction * ref))
    if not after.size:
        return None
    return float((t[after[0]] - t0) * f_hz)


def _run(fmu_dir, stop: float, gain: float):
    from orchestrator.master import run_scenario

    res = run_scenario(SCENARIO, stop_time=stop, fmu_dir=fmu_dir,
                       overrides={"ctrl_diag.gain": gain, "ctrl_long.gain": gain})
    return res.table


def compute(fmu_dir="fmus", quick=False):
    from orchestrator.fmucache import ensure_fmus

    ensure_fmus(FMUS, fmu_dir)
    ol = _run(fmu_dir, 20.0 if quick else 40.0, 0.0)
    cl = _run(fmu_dir, 8.0 if quick else 12.0, 1.0)
    t_ol = ol["time"]
    decay = t_ol > T_EXC + 0.2
    damping, fitted = {}, {}
    for member, (ref, f0) in MODES.items():
        freqs, zetas = fit_two_modes(t_ol[decay], ol[ref][decay], (8.4, 9.5))
        k = int(np.argmin(np.abs(freqs - f0)))
        damping[member] = float(zetas[k])
        fitted[member] = {"freqs_hz": freqs.tolist(), "zetas": zetas.tolist()}
    cycles = {m: cycles_to_fraction(cl["time"], cl[ref], f0) for m, (ref, f0) in MODES.items()}
    cycles_ol = {m: cycles_to_fraction(t_ol, ol[ref], f0) for m, (ref, f0) in MODES.items()}
    volts = max(np.abs(cl["piezo_diag.voltage"]).max(), np.abs(cl["piezo_long.voltage"]).max())
    sat = any(np.any(cl[k] > 0.5) for k in cl if ".sat_" in k)
    return {"ol": ol, "cl": cl, "open_loop_damping": damping, "fits": fitted,
            "closed_loop_cycles_to_90pct": cycles, "open_loop_cycles_to_90pct": cycles_ol,
            "peak_voltage_v": float(volts), "saturated": bool(sat)}


def plot(data, out_dir):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for key, title, fname in (("ol", "open loop (Fig. 5)", "truss-decay-open-loop.png"),
                              ("cl", "250 Hz strain feedback from 4.5 s (Fig. 6)",
                               "truss-decay-closed-loop.png")):
        tab = data[key]
        fig, axes = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
        for ax, (member, (ref, _)) in zip(axes, MODES.items()):
            ax.plot(tab["time"], tab[ref] * 1e6, lw=0.6)
            ax.axvline(T_EXC, color="0.5", lw=0.8, ls="--")
            ax.set_ylabel(f"{member} strain (µε)")
            ax.grid(alpha=0.3)
        axes[0].set_title(f"Ten-bay truss, {title}")
        axes[-1].set_xlabel("time (s)")
        fig.tight_layout()
        fig.savefig(out_dir / fname, dpi=110)
        plt.close(fig)


def run(out_dir, quick: bool = False, fmu_dir="fmus") -> dict:
    data = compute(fmu_dir, quick)
    plot(data, Path(out_dir))
    cycles = data["closed_loop_cycles_to_90pct"]
    reproduced = all(c is not None and c <= 3 for c in cycles.values())
    return {
        "open_loop_damping": data["open_loop_damping"],
        "closed_loop_cycles_to_90pct": cycles,
        "open_loop_cycles_to_90pct": data["open_loop_cycles_to_90pct"],
        "peak_voltage_v": data["peak_voltage_v"],
        "saturated": data["saturated"],
        "fits": data["fits"],
        "paper": {"open_loop_damping": {"diagonal": 0.0018, "longeron": 0.004},
                  "closed_loop_cycles_to_90pct": 2},
        "reproduces_paper_cycles": reproduced,
        "note": ("" if reproduced else
                 "with Eq. 11's one-sample delay at 250 Hz the SISO virtual-absorber "
                 "designs reach only a few percent closed-loop damping on this model's "
                 "gauge-strain plant (a Ritz-captured zero near 5.6 Hz sits below the "
                 "modes), so the slower member takes more cycles than the paper's "
                 "simulation; see docs/controllers.md"),
        "figures": ["truss-decay-open-loop.png", "truss-decay-closed-loop.png"],
    }
