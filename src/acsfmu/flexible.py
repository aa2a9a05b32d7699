"""ACS design on the flexible plant: bandwidth, notch and low-pass per axis (pure, SI).

:mod:`acsfmu.design` shapes the PID on the rigid body ``1/(J s^2)`` alone.  Here the
loop is the exact sampled one: the plant the ACS sees over its period (structure,
flexible modes, any faster loops closed inside it; :class:`AcsPlant`) with the law the
FMU steps (:func:`acsfmu.law.axis_law`).  Per axis ``i`` the loop is broken at its torque
command with the other axes closed::

    T_i = T_ii + T_ir (I - T_rr)^-1 T_ri,    T = K P,    L_i = -T_i

and the design is accepted when

* **rigid body**: the phase margin at the first gain crossover is at least
  ``phase_margin`` (deg);
* **every flexible mode** (each lightly damped pole of the sampled plant, at its
  frequency folded into the ACS's band) is *gain-stabilised*, its peak of ``|L_i|`` at
  most ``-gain_margin_db``, or *phase-stabilised*: wherever the mode lifts ``|L_i|``
  within ``gain_margin_db`` of 1, the phase of ``L_i`` stays at least ``phase_margin``
  from -180 deg.  Above the crossover the loop avoids the same zone (the Nichols
  exclusion zone ``|dB| < gain_margin_db`` and ``|arg L + 180| < phase_margin``) between
  the modes too;
* the closed loop, all axes closed, is stable (eigenvalues; rigid-body poles at 1 that
  the ACS does not see are allowed).

:func:`design_on_plant` searches, per axis, the bandwidth from high to low and at each
the PID alone, a low-pass a few times the crossover, a notch on the largest flexible
peaks of ``|L|``, and both; it keeps the highest bandwidth that passes (among its
filter options the one with the largest slack), first with the other axes open, then
with them closed at their designs until no axis changes.  The MIMO disk margin of the
three axes, ``1 / max sigma(S - I/2)`` with ``S = (I - T)^-1``, is reported.  A request
that no design of the space meets is refused in one sentence naming the binding axis
and mode and what was tried.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from acsfmu.design import pid_gains_for
from acsfmu.filters import AXES, AcsConfigError, AcsFilters
from acsfmu.law import axis_law
from acsfmu.pid import AcsConfig, PidGains

__all__ = ["AcsPlant", "AxisChoice", "ModeVerdict", "AxisResult", "FlexibleDesign",
           "design_on_plant", "evaluate_on_plant", "check_request", "check_margins"]

_AXIS_NAMES = ("roll", "pitch", "yaw")
_RIGID = 1e-6          # a pole within this of z = 1 is a rigid-body pole
_LIGHT = 0.3           # sampled poles below this damping ratio are modes


@dataclass(frozen=True, eq=False)
class AcsPlant:
    """The plant the ACS sees over its period: ``X+ = Phi X + Gam u``, ``y = R X``.

    ``u`` are the three torques applied over period ``n`` (N m) and ``y`` the six samples
    ``(roll, pitch, yaw, rate_x, rate_y, rate_z)`` the law reads to compute them: taken
    one period earlier, so the law's computational delay is inside the plant and the law
    is :func:`acsfmu.law.law_state_space` (``u = Cc xc + Dc y``).

    Parameters
    ----------
    Phi : ndarray, shape (n, n)
        Map over one ACS period (-).
    Gam : ndarray, shape (n, 3)
        Input of the torques (per N m).
    R : ndarray, shape (6, n)
        The samples (rad, rad/s).
    period : float
        ACS sample time (s).
    """

    Phi: np.ndarray
    Gam: np.ndarray
    R: np.ndarray
    period: float
    _schur: list = field(default_factory=list, repr=False)

    @property
    def nyquist(self) -> float:
        """Nyquist frequency of the ACS (Hz)."""
        return 0.5 / self.period

    def response(self, freqs_hz) -> np.ndarray:
        """``P(e^{j 2 pi f T})`` at each frequency, shape (n_f, 6, 3).

        Parameters
        ----------
        freqs_hz : array_like, shape (n_f,)
            Frequencies (Hz), none where ``e^{j 2 pi f T}`` is a pole.
        """
        import scipy.linalg as la

        if not self._schur:
            with np.errstate(invalid="ignore"):   # scipy casts its unused permutation
                Phi_b, (d, _) = la.matrix_balance(self.Phi, permute=False, separate=True)
            Tm, Q = la.schur(Phi_b, output="complex")
            self._schur.extend([Tm, Q, d])
        Tm, Q, d = self._schur
        z = np.exp(2j * math.pi * np.asarray(freqs_hz, float) * self.period)
        G = Q.conj().T @ (self.Gam / d[:, None])                  # (n, 3)
        n, nf = Tm.shape[0], z.size
        X = np.empty((n, nf, 3), complex)
        diag = np.diag(Tm)
        for i in range(n - 1, -1, -1):                            # (z I - T) X = G
            r = G[i][None, :] + np.einsum("j,jfk->fk", Tm[i, i + 1:], X[i + 1:])
            X[i] = r / (z - diag[i])[:, None]
        Y = np.einsum("rn,nfk->frk", (self.R * d[None, :]) @ Q, X)
        return Y

    def modes(self) -> list:
        """Lightly damped poles of the plant, folded into the ACS band.

        Returns
        -------
        list of (float, float)
            ``(frequency Hz in (0, Nyquist), damping ratio)`` of each pole pair whose
            equivalent damping ``-ln|z| / |ln z|`` is below 0.3, by frequency (a
            repeated pole once).
        """
        ev = np.linalg.eigvals(self.Phi)
        out = []
        for z in ev:
            if abs(z - 1.0) < _RIGID or z.imag <= 1e-12 or abs(z) < 1e-12:
                continue
            s = np.log(z) / self.period
            zeta = -s.real / abs(s)
            if zeta < _LIGHT:
                out.append((float(abs(np.angle(z)) / (2 * math.pi * self.period)),
                            float(zeta)))
        kept = []   # a repeated pole (equal modes of several axes) once
        for m in sorted(out):
            if not kept or abs(m[0] - kept[-1][0]) > 1e-9 * m[0] \
                    or abs(m[1] - kept[-1][1]) > 1e-6 * max(m[1], 1e-9):
                kept.append(m)
        return kept


@dataclass(frozen=True)
class AxisChoice:
    """One axis's design: crossover and filters (0 Hz: filter off).

    Attributes
    ----------
    bandwidth : float
        Design crossover (Hz).
    notch_hz, notch_zeta_num, notch_zeta_den : float
        Notch centre (Hz) and dampings (-).
    lowpass_hz, lowpass_zeta : float
        Low-pass corner (Hz) and damping (-).
    """

    bandwidth: float
    notch_hz: float = 0.0
    notch_zeta_num: float = 0.05
    notch_zeta_den: float = 0.5
    lowpass_hz: float = 0.0
    lowpass_zeta: float = 0.7

    def describe(self) -> str:
        """One line: the crossover and the filters switched on."""
        parts = [f"{self.bandwidth:.4g} Hz"]
        if self.notch_hz:
            parts.append(f"notch {self.notch_hz:.4g} Hz (zeta {self.notch_zeta_num:g}/"
                         f"{self.notch_zeta_den:g})")
        if self.lowpass_hz:
            parts.append(f"low-pass {self.lowpass_hz:.4g} Hz (zeta {self.lowpass_zeta:g})")
        return ", ".join(parts)


@dataclass(frozen=True)
class ModeVerdict:
    """How one flexible mode is stabilised in one axis's loop.

    Attributes
    ----------
    freq_hz, zeta : float
        The mode's sampled pole: frequency in the ACS band (Hz) and damping (-).
    peak_db : float
        Peak of ``|L|`` near the mode (dB).
    how : str
        ``"gain"`` (peak at most ``-gain_margin_db``), ``"phase"`` (the phase keeps its
        margin where ``|L|`` is within ``gain_margin_db`` of 1) or ``"fails"``.
    margin : float
        ``-peak_db`` (dB) when gain-stabilised or when it fails with no phase crossing,
        else the smallest distance of ``arg L`` from -180 deg there (deg).
    unit : str
        ``"dB"`` or ``"deg"``.
    """

    freq_hz: float
    zeta: float
    peak_db: float
    how: str
    margin: float
    unit: str

    def as_dict(self) -> dict:
        """Plain numbers for JSON."""
        return {"freq_hz": self.freq_hz, "zeta": self.zeta, "peak_db": self.peak_db,
                "stabilised": self.how, "margin": self.margin, "unit": self.unit}


@dataclass(frozen=True)
class AxisResult:
    """One axis: its choice, the rigid-body margin and the per-mode verdicts.

    Attributes
    ----------
    axis : str
        ``"roll"``, ``"pitch"`` or ``"yaw"``.
    choice : AxisChoice
    crossover_hz : float
        First gain crossover of ``L_i`` (Hz).
    phase_margin : float
        Rigid-body phase margin there (deg).
    modes : tuple of ModeVerdict
    zone_ok : bool
        Above the crossover, ``L_i`` stays out of the exclusion zone between the modes.
    ok : bool
        Every check met.
    disk_alpha : float
        Balanced disk margin of ``L_i`` (-), ``1 / max |S_i - 1/2|``.
    """

    axis: str
    choice: AxisChoice
    crossover_hz: float
    phase_margin: float
    modes: tuple
    zone_ok: bool
    ok: bool
    disk_alpha: float = math.nan

    def worst_mode(self, gain_margin_db: float = 6.0, phase_margin: float = 30.0):
        """The mode with the least slack over its requirement (None if there is none).

        Parameters
        ----------
        gain_margin_db : float
            The requirement of a mode given in dB (dB).
        phase_margin : float
            The requirement of a mode given in deg (deg).
        """
        def slack(m):
            return (m.margin / max(gain_margin_db, 1e-9) if m.unit == "dB"
                    else m.margin / max(phase_margin, 1e-9))
        return min(self.modes, key=slack) if self.modes else None

    def as_dict(self) -> dict:
        """Plain numbers for JSON."""
        c = self.choice
        return {"axis": self.axis, "bandwidth_hz": c.bandwidth, "notch_hz": c.notch_hz,
                "notch_zeta_num": c.notch_zeta_num, "notch_zeta_den": c.notch_zeta_den,
                "lowpass_hz": c.lowpass_hz, "lowpass_zeta": c.lowpass_zeta,
                "crossover_hz": self.crossover_hz, "phase_margin_deg": self.phase_margin,
                "zone_ok": self.zone_ok, "ok": self.ok, "disk_alpha": self.disk_alpha,
                "disk_db": _alpha_db(self.disk_alpha),
                "modes": [m.as_dict() for m in self.modes]}


@dataclass(frozen=True, eq=False)
class FlexibleDesign:
    """The design: per-axis results, the ACS configuration and its FMU parameters.

    Attributes
    ----------
    axes : tuple of AxisResult, length 3
    config : AcsConfig
        Gains and filters of the design.
    parameters : dict of str to float
        The ACS FMU's parameters that carry it (``bandwidth_x``, ``notch_hz_x``, ...).
    disk_alpha : float
        MIMO disk margin of the three axes (-).
    stable : bool
        The closed loop, all axes closed (eigenvalues).
    searched : dict
        What was searched (bandwidths, filter options, passes, evaluations).
    """

    axes: tuple
    config: AcsConfig
    parameters: dict
    disk_alpha: float
    stable: bool
    searched: dict

    @property
    def disk_db(self) -> float:
        """MIMO disk margin as a gain (dB, either way)."""
        a = self.disk_alpha
        return math.inf if a >= 2 else 20 * math.log10((2 + a) / (2 - a)) if a > 0 else 0.0

    @property
    def disk_deg(self) -> float:
        """MIMO disk margin as a phase (deg)."""
        return math.degrees(2 * math.atan(self.disk_alpha / 2)) if self.disk_alpha > 0 else 0.0


def check_request(sample_time: float, *, phase_margin: float, gain_margin_db: float,
                  bandwidths, lowpass_ratios=(), notch_hz=(), antialias_hz: float = 0.0,
                  disk_margin_db: float = 0.0) -> None:
    """Refuse a request in one sentence, before any computation.

    Parameters
    ----------
    sample_time : float
        ACS sample time (s).
    phase_margin : float
        Requested phase margin (deg), in (0, 90).
    gain_margin_db : float
        Requested gain margin (dB), at least 0.
    bandwidths : sequence of float
        Crossovers searched (Hz), positive and below the Nyquist frequency.
    lowpass_ratios : sequence of float
        Low-pass corners searched, as multiples of the crossover (positive).
    notch_hz : sequence of float
        Notch centres given (Hz), below the Nyquist frequency.
    antialias_hz : float
        Anti-alias corner kept (Hz, 0 for none), below the Nyquist frequency.
    disk_margin_db : float
        Requested MIMO disk margin (dB), at least 0.

    Raises
    ------
    AcsConfigError
    """
    check_margins(phase_margin=phase_margin, gain_margin_db=gain_margin_db,
                  disk_margin_db=disk_margin_db)
    nyq = 0.5 / sample_time
    bw = np.asarray(bandwidths, float)
    if bw.size == 0 or not np.all(np.isfinite(bw) & (bw > 0)):
        raise AcsConfigError(f"ACS design: the bandwidths {bw.tolist()} Hz must be positive "
                             "numbers")
    for what, f in ([("bandwidth", b) for b in bw] + [("notch centre", f) for f in notch_hz]
                    + ([("anti-alias corner", antialias_hz)] if antialias_hz else [])):
        if not (math.isfinite(f) and 0 < f < nyq):
            raise AcsConfigError(f"ACS design: the {what} {f:g} Hz is at or above the ACS's "
                                 f"Nyquist frequency {nyq:g} Hz (sample time {sample_time:g} "
                                 "s) or not positive; expected a frequency below it")
    for r in lowpass_ratios:
        if not (math.isfinite(r) and r > 0):
            raise AcsConfigError(f"ACS design: the low-pass ratio {r:g} must be positive (a "
                                 "corner that many times the crossover)")


def check_margins(*, phase_margin: float, gain_margin_db: float,
                  disk_margin_db: float = 0.0) -> None:
    """Refuse requested margins in one sentence (the part of :func:`check_request`
    that needs no sample time).

    Parameters
    ----------
    phase_margin : float
        Requested phase margin (deg), in (0, 90).
    gain_margin_db : float
        Requested gain margin (dB), at least 0.
    disk_margin_db : float
        Requested MIMO disk margin (dB), at least 0.

    Raises
    ------
    AcsConfigError
    """
    if not (math.isfinite(gain_margin_db) and gain_margin_db >= 0):
        raise AcsConfigError(f"ACS design: the requested gain margin {gain_margin_db:g} dB "
                             "is below 0 dB; a margin is a factor the loop must tolerate, "
                             "expected 0 dB or more (6 dB is usual)")
    if not (math.isfinite(disk_margin_db) and disk_margin_db >= 0):
        raise AcsConfigError(f"ACS design: the requested disk margin {disk_margin_db:g} dB "
                             "is below 0 dB; expected 0 (none) or more")
    if not (math.isfinite(phase_margin) and 0 < phase_margin < 90):
        raise AcsConfigError(f"ACS design: the requested phase margin {phase_margin:g} deg "
                             "is outside (0, 90) deg; expected e.g. 30 deg")


def _grid(plant: AcsPlant, modes, n: int = 600) -> np.ndarray:
    nyq = plant.nyquist
    f = list(np.geomspace(nyq * 1e-4, nyq * 0.999, n))
    for fn, zeta in modes:
        width = max(zeta * fn, 2e-5 * nyq)
        f.extend(fn + width * np.linspace(-8, 8, 33))
    return np.unique(np.clip(f, nyq * 1e-4, nyq * 0.999))


class _Search:
    """Frequency responses of the plant and of candidate axis laws, and the checks."""

    def __init__(self, plant, inertia, design_phase, pm, gm, antialias, integral_ratio,
                 phase_stabilise=True, disk_db=0.0):
        self.plant, self.inertia = plant, np.asarray(inertia, float)
        self.phase_ok = phase_stabilise
        g = 10 ** (disk_db / 20)
        self.disk_req = 2 * (g - 1) / (g + 1)      # the disk alpha of that gain
        self.T = plant.period
        self.design_phase, self.pm, self.gm = design_phase, pm, gm
        self.antialias, self.b = antialias, integral_ratio
        self.modes = plant.modes()
        self.f = _grid(plant, self.modes)
        self.z = np.exp(2j * math.pi * self.f * self.T)
        P = plant.response(self.f)                                  # (n_f, 6, 3)
        self.Pa = [P[:, [i, 3 + i], :] for i in range(3)]          # (n_f, 2, 3)
        self._k = {}
        self.evaluations = 0

    def config(self, choices) -> AcsConfig:
        gains = [pid_gains_for(float(self.inertia[i]), c.bandwidth, self.design_phase,
                               self.T, self.b) for i, c in enumerate(choices)]
        kp, ki, kd = (list(g) for g in zip(*gains))
        fl = AcsFilters(self.T, **{k: [getattr(c, k) for c in choices] for k in (
            "notch_hz", "notch_zeta_num", "notch_zeta_den", "lowpass_hz", "lowpass_zeta")},
            antialias_hz=self.antialias[0], antialias_zeta=self.antialias[1])
        return AcsConfig(PidGains(kp, ki, kd), sample_time=self.T, filters=fl)

    def law(self, i: int, c: AxisChoice) -> np.ndarray:
        """Row ``i`` of ``T = K P`` for axis ``i`` with choice ``c``, shape (n_f, 3)."""
        key = (i, c)
        if key not in self._k:
            Ac, Bc, Cc, Dc = axis_law(self.config([c] * 3), i)
            k = Ac.shape[0]
            X = np.linalg.solve(self.z[:, None, None] * np.eye(k)[None] - Ac[None],
                                np.broadcast_to(Bc, (self.z.size, k, 2)))
            K = (Cc[None] @ X + Dc[None])[:, 0, :]                   # (n_f, 2)
            self._k[key] = np.einsum("fj,fjk->fk", K, self.Pa[i])
        return self._k[key]

    def loop(self, i: int, choices) -> np.ndarray:
        """``L_i = -T_i`` with the other axes closed where they have a choice."""
        T = np.zeros((self.f.size, 3, 3), complex)
        for j, c in enumerate(choices):
            if c is not None or j == i:
                T[:, j, :] = self.law(j, choices[j])
        r = [j for j in range(3) if j != i]
        Trr = T[:, r][:, :, r]
        Ti = T[:, i, i] + np.einsum("fj,fj->f", T[:, i, r], np.linalg.solve(
            np.eye(2)[None] - Trr, T[:, r, i][..., None])[..., 0])
        return -Ti

    def judge(self, i: int, choices) -> AxisResult:
        """The checks of axis ``i`` (see the module docstring)."""
        self.evaluations += 1
        L = self.loop(i, choices)
        f, mag = self.f, np.abs(L)
        dist = 180.0 - np.degrees(np.abs(np.angle(L)))             # from -180 deg
        db = 20 * np.log10(np.maximum(mag, 1e-300))
        down = np.flatnonzero((mag[:-1] >= 1) & (mag[1:] < 1))
        if down.size:
            j = int(down[0])
            w = (0 - db[j]) / (db[j + 1] - db[j])
            fc = float(f[j] * (f[j + 1] / f[j]) ** w)
            ph = np.unwrap(np.angle(L[j:j + 2]))
            pm = 180.0 - abs(math.degrees(math.remainder(ph[0] + w * (ph[1] - ph[0]),
                                                         2 * math.pi)))
        else:
            fc, pm = math.nan, -math.inf
        inzone = (np.abs(db) < self.gm) & (dist < self.pm)
        verdicts, owned = [], np.zeros(f.size, bool)
        fm = [m[0] for m in self.modes]
        for k, (fn, zeta) in enumerate(self.modes):
            lo = math.sqrt(fm[k - 1] * fn) if k > 0 else f[0]
            hi = math.sqrt(fm[k + 1] * fn) if k + 1 < len(fm) else f[-1]
            if math.isfinite(fc):
                lo, hi = (max(lo, fc), hi) if fn > fc else (lo, min(hi, fc))
            seg = (f >= lo) & (f <= hi)
            zw = max(zeta, 1e-3)
            near = seg & (np.abs(f - fn) <= 3 * zw * fn + 1e-12)
            if not near.any():
                near = seg if seg.any() else np.abs(f - fn) == np.abs(f - fn).min()
            peak = float(db[near].max())
            owned |= seg
            if peak <= -self.gm:
                verdicts.append(ModeVerdict(fn, zeta, peak, "gain", -peak, "dB"))
                continue
            band = seg & (np.abs(db) < self.gm)
            d = float(dist[band].min()) if band.any() else 180.0
            above = not math.isfinite(fc) or fn > fc
            if d >= self.pm and (self.phase_ok or not above):
                verdicts.append(ModeVerdict(fn, zeta, peak, "phase", d, "deg"))
            elif peak < 0 or (above and not self.phase_ok):   # a gain margin short
                verdicts.append(ModeVerdict(fn, zeta, peak, "fails", -peak, "dB"))
            else:
                verdicts.append(ModeVerdict(fn, zeta, peak, "fails", d, "deg"))
        above = (f > fc) if math.isfinite(fc) else np.zeros(f.size, bool)
        zone_ok = not np.any(inzone & above & ~owned)
        alpha = float(1.0 / np.max(np.abs(1.0 / (1.0 + L) - 0.5)))
        ok = (math.isfinite(fc) and pm >= self.pm and zone_ok and alpha >= self.disk_req
              and all(v.how != "fails" for v in verdicts))
        return AxisResult(_AXIS_NAMES[i], choices[i], fc, pm, tuple(verdicts), zone_ok, ok,
                          alpha)

    def slack(self, r: AxisResult) -> float:
        """Smallest relative slack of the checks (negative when one fails)."""
        s = [(r.phase_margin - self.pm) / self.pm]
        for m in r.modes:
            if m.unit == "dB":
                s.append((m.margin - self.gm) / max(self.gm, 1.0))
            else:
                s.append((m.margin - self.pm) / self.pm)
        if self.disk_req > 0:
            s.append((r.disk_alpha - self.disk_req) / self.disk_req)
        return min(s) - (0.0 if r.zone_ok else 1.0)

    def rank(self, i: int, r: AxisResult, choices) -> float:
        """:meth:`slack` of axis ``i``'s result, and with a disk margin requested the
        slack of the MIMO disk margin with it in place (the coupling picks filters)."""
        out = self.slack(r)
        if self.disk_req > 0:
            others = list(choices)
            others[i] = r.choice
            out = min(out, (self.disk(others) - self.disk_req) / self.disk_req)
        return out

    def closed(self, choices) -> np.ndarray:
        """Closed-loop map of the plant and the laws of the axes with a choice."""
        p = self.plant
        laws = [(i, axis_law(self.config([c] * 3), i)) for i, c in enumerate(choices)
                if c is not None]
        n = p.Phi.shape[0]
        k = sum(law[0].shape[0] for _, law in laws)
        A = np.zeros((n + k, n + k))
        A[:n, :n] = p.Phi
        off = n
        for i, (Ac, Bc, Cc, Dc) in laws:
            Ri = p.R[[i, 3 + i]]                                     # (2, n)
            g = p.Gam[:, i:i + 1]                                    # (n, 1)
            m = Ac.shape[0]
            A[:n, :n] += g @ Dc @ Ri
            A[:n, off:off + m] = g @ Cc
            A[off:off + m, :n] = Bc @ Ri
            A[off:off + m, off:off + m] = Ac
            off += m
        return A

    def stable(self, choices) -> bool:
        """Every pole of :meth:`closed` inside the unit circle, rigid-body poles aside."""
        import scipy.linalg as la

        with np.errstate(invalid="ignore"):
            Ab = la.matrix_balance(self.closed(choices), permute=False)[0]
        ev = np.linalg.eigvals(Ab)
        ok = np.abs(ev - 1.0) < _RIGID
        return bool(np.all(ok | (np.abs(ev) < 1.0 - 1e-9)))

    def disk(self, choices) -> float:
        """MIMO disk margin of the axes with a choice closed together (the others open)."""
        T = np.stack([self.law(i, c) if c is not None else np.zeros((self.f.size, 3))
                      for i, c in enumerate(choices)], axis=1)
        S = np.linalg.inv(np.eye(3)[None] - T)
        sv = np.linalg.svd(S - 0.5 * np.eye(3)[None], compute_uv=False)[:, 0]
        return float(1.0 / sv.max())


def _options(search: _Search, i: int, bw: float, choices, ratios, lp_zeta, notch_zetas,
             notch_hz) -> list:
    """The filter options at one bandwidth: none, low-pass, notch, both."""
    nyq = search.plant.nyquist
    base = AxisChoice(bw)
    lps = [r * bw for r in ratios if r * bw < 0.95 * nyq]
    centres = list(notch_hz)
    if not centres:   # the largest flexible peaks of |L| above crossover, PID alone
        res = search.judge(i, [base if j == i else c for j, c in enumerate(choices)])
        peaks = sorted((m for m in res.modes
                        if not math.isfinite(res.crossover_hz) or m.freq_hz > res.crossover_hz),
                       key=lambda m: -m.peak_db)
        centres = [m.freq_hz for m in peaks[:2] if m.peak_db > -search.gm - 6.0
                   and m.freq_hz < 0.95 * nyq]
    notches = [(fn, zn, zd) for fn in centres for zn, zd in notch_zetas]
    out = [base]
    out += [AxisChoice(bw, lowpass_hz=fl, lowpass_zeta=lp_zeta) for fl in lps]
    out += [AxisChoice(bw, fn, zn, zd) for fn, zn, zd in notches]
    out += [AxisChoice(bw, fn, zn, zd, fl, lp_zeta) for fn, zn, zd in notches for fl in lps]
    return out


def design_on_plant(plant: AcsPlant, inertia, *, phase_margin: float = 30.0,
                    gain_margin_db: float = 6.0, design_phase: float = 50.0,
                    bandwidths=(0.1, 0.01), steps: int = 21,
                    lowpass_ratios=(4.0, 5.0, 6.25, 8.0), lowpass_zeta: float = 0.7,
                    notch_zetas=((0.02, 0.7), (0.02, 0.3)), notch_hz=(),
                    antialias=(0.0, 0.7), integral_ratio: float = 5.0,
                    phase_stabilise: bool = True, disk_margin_db: float = 0.0,
                    passes: int = 4, progress=None) -> FlexibleDesign:
    """Design the three axes on the flexible plant (see the module docstring).

    Parameters
    ----------
    plant : AcsPlant
        The sampled plant the ACS sees.
    inertia : array_like, shape (3,)
        Inertias the PID gains are computed from (kg m^2), as the FMU does.
    phase_margin : float
        Required rigid-body phase margin, and phase margin of a phase-stabilised mode
        (deg), in (0, 90).
    gain_margin_db : float
        Required gain margin of a gain-stabilised mode (dB), at least 0.
    design_phase : float
        Phase margin the PID is shaped for on the rigid body (deg): the FMU's
        ``phase_margin`` parameter, common to the axes.
    bandwidths : (float, float) or sequence of float
        ``(high, low)``: crossovers searched from high to low, ``steps`` of them, log
        spaced (Hz); a longer sequence is taken as the crossovers themselves.
    steps : int
        Crossovers between ``high`` and ``low``.
    lowpass_ratios : sequence of float
        Low-pass corners tried, as multiples of the crossover (those below 0.95 times the
        Nyquist frequency).
    lowpass_zeta : float
        Their damping (-).
    notch_zetas : sequence of (float, float)
        Notch ``(zeta_num, zeta_den)`` pairs tried.
    notch_hz : sequence of float
        Notch centres tried (Hz); empty: the two largest flexible peaks of ``|L|`` above
        the crossover of the PID alone at each crossover.
    antialias : (float, float)
        Anti-alias corner (Hz, 0 for none) and damping kept on the six inputs.
    integral_ratio : float
        The PID's integral zero at ``w_c / integral_ratio``.
    phase_stabilise : bool
        Accept flexible modes above the crossover that are phase-stabilised; False: every
        one must be gain-stabilised (a mode whose frequency is uncertain).
    disk_margin_db : float
        MIMO disk margin of the three axes required (dB, 0 for none), and so each axis's
        own disk margin (a check of the axis like the others); while it is short,
        a common cap on the crossovers is stepped down the list, then each axis is
        raised again one step at a time while the margin holds.
    passes : int
        Most passes over the axes with the others closed.
    progress : callable, optional
        ``progress(done, total)`` after each crossover searched.

    Returns
    -------
    FlexibleDesign

    Raises
    ------
    AcsConfigError
        A request refused before any computation (a margin below 0 dB, a phase margin
        outside (0, 90) deg, a corner at or above Nyquist), or one sentence naming the
        axis and mode no design of the space stabilises with the requested margins.
    """
    bw = np.asarray(bandwidths, float)
    if bw.size == 2 and not (isinstance(steps, int) and steps >= 1):
        raise AcsConfigError(f"ACS design: steps is {steps!r}; expected a whole number >= 1")
    check_request(plant.period, phase_margin=phase_margin, gain_margin_db=gain_margin_db,
                  bandwidths=bw, lowpass_ratios=lowpass_ratios, notch_hz=notch_hz,
                  antialias_hz=float(antialias[0]), disk_margin_db=disk_margin_db)
    if bw.size == 2:
        hi, lo = max(bw), min(bw)
        bw = np.geomspace(hi, lo, steps) if steps > 1 else np.array([hi])
    else:
        bw = np.sort(bw)[::-1]
    s = _Search(plant, inertia, design_phase, phase_margin, gain_margin_db,
                (float(antialias[0]), float(antialias[1])), integral_ratio, phase_stabilise,
                disk_margin_db)
    done = [0]

    def tick(total):
        done[0] += 1
        if progress:
            progress(done[0], max(total, done[0]))

    def run(caps):
        lists = [bw[bw <= cap * (1 + 1e-12)] for cap in caps]
        return _passes(s, lists, passes, lambda: tick(3 * bw.size * passes),
                       (lowpass_ratios, lowpass_zeta, notch_zetas, notch_hz))

    choices = run([bw[0]] * 3)
    disk = s.disk(choices)
    lowered = 0
    if disk_margin_db and _alpha_db(disk) < disk_margin_db:
        # a common cap on the crossovers, stepped down until the margin holds ...
        top, best = list(choices), (disk, choices)
        for cap in bw[1:]:
            lowered += 1
            try:
                ch = run([min(cap, c.bandwidth) for c in top])
            except AcsConfigError:
                continue
            d = s.disk(ch)
            best = max(best, (d, ch), key=lambda t: t[0])
            if _alpha_db(d) >= disk_margin_db:
                choices, disk = ch, d
                break
        else:
            raise AcsConfigError(
                f"ACS design: the MIMO disk margin of the three axes reaches "
                f"{_alpha_db(best[0]):.2f} dB at best ({_tried(bw, lowpass_ratios)}, a "
                f"common cap on the crossovers lowered step by step; {disk_margin_db:g} dB "
                "requested); lower the requested disk margin")
        # ... then each axis raised again while it holds
        raised = True
        while raised:
            raised = False
            for i in range(3):
                up = bw[(bw > choices[i].bandwidth * (1 + 1e-12))
                        & (bw <= top[i].bandwidth * (1 + 1e-12))]
                if up.size == 0:
                    continue
                caps = [c.bandwidth for c in choices]
                caps[i] = up[-1]
                try:
                    ch = run(caps)
                except AcsConfigError:
                    continue
                d = s.disk(ch)
                if _alpha_db(d) >= disk_margin_db and ch[i].bandwidth > choices[i].bandwidth:
                    choices, disk, raised = ch, d, True
    if progress:
        progress(done[0], done[0])
    out = evaluate_on_plant(plant, inertia, choices, phase_margin=phase_margin,
                            gain_margin_db=gain_margin_db, design_phase=design_phase,
                            antialias=antialias, integral_ratio=integral_ratio,
                            phase_stabilise=phase_stabilise, _search=s)
    bad = [r for r in out.axes if not r.ok]
    if bad or not out.stable:
        what = f"{bad[0].axis} fails its checks" if bad else "the closed loop is unstable"
        raise AcsConfigError(f"ACS design: the axes designed one at a time do not hold "
                             f"together ({what} with the others closed); narrow the "
                             "bandwidth range or add damping")
    searched = {"bandwidths_hz": [float(b) for b in bw],
                "lowpass_ratios": [float(r) for r in lowpass_ratios],
                "lowpass_zeta": lowpass_zeta,
                "notch_zetas": [list(z) for z in notch_zetas],
                "notch_hz": [float(f) for f in notch_hz] or "the two largest flexible peaks "
                            "of |L| above crossover, PID alone",
                "design_phase_deg": design_phase, "phase_stabilise": phase_stabilise,
                "phase_margin_deg": phase_margin, "gain_margin_db": gain_margin_db,
                "disk_margin_db": disk_margin_db, "disk_cap_steps": lowered,
                "evaluations": s.evaluations, "frequencies": int(s.f.size),
                "plant_modes": len(s.modes)}
    return FlexibleDesign(out.axes, out.config, out.parameters, out.disk_alpha, out.stable,
                          searched)


def evaluate_on_plant(plant: AcsPlant, inertia, choices, *, phase_margin: float = 30.0,
                      gain_margin_db: float = 6.0, design_phase: float = 50.0,
                      antialias=(0.0, 0.7), integral_ratio: float = 5.0,
                      phase_stabilise: bool = True, _search=None) -> FlexibleDesign:
    """The checks of a given ACS on the flexible plant (no search).

    Parameters
    ----------
    plant : AcsPlant
        The sampled plant the ACS sees.
    inertia : array_like, shape (3,)
        Inertias the PID gains are computed from (kg m^2).
    choices : sequence of AxisChoice, length 3
        Crossover and filters of roll, pitch and yaw.
    phase_margin, gain_margin_db, design_phase, antialias, integral_ratio, phase_stabilise
        As :func:`design_on_plant`.

    Returns
    -------
    FlexibleDesign
        Its ``searched`` is empty.
    """
    s = _search or _Search(plant, inertia, design_phase, phase_margin, gain_margin_db,
                           (float(antialias[0]), float(antialias[1])), integral_ratio,
                           phase_stabilise)
    choices = list(choices)
    final = tuple(s.judge(i, choices) for i in range(3))
    params = {}
    for a, c in zip(AXES, choices):
        params.update({f"bandwidth_{a}": c.bandwidth, f"notch_hz_{a}": c.notch_hz,
                       f"notch_zeta_num_{a}": c.notch_zeta_num,
                       f"notch_zeta_den_{a}": c.notch_zeta_den,
                       f"lowpass_hz_{a}": c.lowpass_hz, f"lowpass_zeta_{a}": c.lowpass_zeta})
    params["phase_margin"] = math.radians(design_phase)
    return FlexibleDesign(final, s.config(choices), params, s.disk(choices),
                          s.stable(choices), {})


def _alpha_db(alpha: float) -> float:
    return math.inf if alpha >= 2 else 20 * math.log10((2 + alpha) / (2 - alpha)) \
        if alpha > 0 else 0.0


def _tried(bw, ratios) -> str:
    return (f"bandwidth {min(bw):.3g}-{max(bw):.3g} Hz, notch and low-pass "
            f"({', '.join(f'{x:g}' for x in ratios)} x crossover) tried")


def _passes(s: _Search, lists, passes: int, tick, opts) -> list:
    """Per-axis searches, the other axes open then closed at their designs, until no
    axis changes; a refusal names the axis no crossover of its list passes."""
    choices = [None, None, None]
    for p in range(passes):
        changed = False
        for i in range(3):
            found, best = None, None
            for b in lists[i]:
                tick()
                others = list(choices)
                judged = []
                for o in _options(s, i, float(b), choices, *opts):
                    others[i] = o
                    judged.append((s.judge(i, others), o))
                for r, o in judged:
                    if best is None or s.slack(r) > s.slack(best):
                        best = r
                for r, o in sorted((x for x in judged if x[0].ok),
                                   key=lambda x: -s.rank(i, x[0], choices)):
                    others[i] = o
                    if s.stable(others):
                        found = o
                        break
                if found:
                    break
            if found is None:
                raise AcsConfigError(_refusal(s, best, lists[i], opts[0]))
            changed |= choices[i] != found
            choices[i] = found
        if not changed and p > 0:
            break
    return choices


def _refusal(s: _Search, r: AxisResult, bw, ratios) -> str:
    """One sentence: the binding check of the best failing design of an axis."""
    tried = _tried(bw, ratios) if len(bw) else "no crossover below the cap"
    if r is None:
        return f"ACS design: no design was tried ({tried})"
    if not math.isfinite(r.crossover_hz):
        return (f"ACS design: {r.axis}: the loop never crosses 0 dB ({tried}); check the "
                "inertias and the plant")
    worst = None
    for m in r.modes:
        if m.how == "fails":
            short = (s.gm - m.margin) / max(s.gm, 1) if m.unit == "dB" else \
                (s.pm - m.margin) / s.pm
            if worst is None or short > worst[0]:
                worst = (short, m)
    if worst is not None and (r.phase_margin >= s.pm or
                              worst[0] > (s.pm - r.phase_margin) / s.pm):
        m = worst[1]
        if m.unit == "deg":
            got = (f"keeps {m.margin:.1f} deg of phase where |L| is within {s.gm:g} dB "
                   "of 1")
        elif m.margin >= 0:
            got = f"keeps {m.margin:.1f} dB"
        else:
            got = f"rises {-m.margin:.1f} dB above 0 dB"
        asked = f"{s.gm:g} dB or {s.pm:g} deg" if s.phase_ok else f"{s.gm:g} dB"
        return (f"ACS design: {r.axis}: the {m.freq_hz:.3g} Hz mode {got} at best "
                f"({tried}; {asked} requested); lower the requested margin or add damping")
    if r.phase_margin < s.pm:
        return (f"ACS design: {r.axis}: the rigid-body phase margin reaches "
                f"{r.phase_margin:.1f} deg at best ({tried}; {s.pm:g} deg requested); "
                "lower the requested margin or the bandwidth range")
    return (f"ACS design: {r.axis}: above the crossover the loop enters the "
            f"{s.gm:g} dB / {s.pm:g} deg exclusion zone between the modes at best "
            f"({tried}); lower the requested margin")
