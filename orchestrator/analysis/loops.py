"""Margins of every loop of a scenario, broken at its actuator on the exact sampled plant.

A loop is broken where a controller's (or the ACS's) command leaves it: the consumers of
the command read a free input ``e`` instead, held as the command would be, and the
command itself becomes an output ``y``.  Over one period ``P`` of the loop (the
hyperperiod of the loops still closed) the master's Gauss-Seidel ticks give the exact
sampled broken loop::

    X[n+1] = Phi X[n] + Gam e[n],     y[n] = R X[n] + Dl e[n]

and closing it again (``e = y``) gives back the closed loop.  Every other loop stays
closed inside ``Phi``.  ``T(z) = R (z I - Phi)^-1 Gam + Dl`` is the loop's return ratio
(positive feedback); ``L = -T`` in the usual negative-feedback convention.

From it, per loop (:class:`LoopMargins`):

* gain margins up and down: the real factors on the command at which a closed-loop pole
  reaches the unit circle, found on the closed loop's eigenvalues (exact, conditionally
  stable loops included);
* phase margin: the smallest phase lag ``e^{-j phi}`` on the command that destabilises
  the loop, found the same way (a complex factor on a real loop: its poles are those of
  ``e^{+j phi}`` conjugated);
* disk margin (balanced, skew 0): ``alpha = 1 / max |S - 1/2|`` with ``S = 1/(1 - T)``,
  the loop stable for every gain-and-phase factor in the disk through
  ``(2 - alpha)/(2 + alpha)`` and ``(2 + alpha)/(2 - alpha)``; for a group of loops the
  MIMO disk margin ``1 / max sigma_max(S - I/2)`` (simultaneous, independent
  perturbations of every channel of the group);
* gain crossovers, and the frequencies above the first crossover where ``|T| > 1``:
  such a loop is phase-stabilised there, and says so.

A loop faster than the loop period of a slower instance (a 1 kHz isolation law beside
the 10 Hz ACS) is periodic, not time-invariant, at its own rate: its margins are taken
with the slower instances opened (their crossover far below its band), and the result
says which were opened; the closed loop's own poles (everything closed) tell whether it
is stable as it is.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from .blocks import AnalysisError, _source_block

__all__ = ["BrokenLoop", "LoopMargins", "GroupMargins", "broken_loop", "group_margins",
           "scenario_margins", "loop_groups", "disk_to_gain_phase", "margins_of"]

_BREAK = "__loop_break"


@dataclass(frozen=True, eq=False)
class BrokenLoop:
    """A loop broken at its commands: ``X+ = Phi X + Gam e``, ``y = R X + Dl e``.

    Parameters
    ----------
    Phi : ndarray, shape (n, n)
        Map over one loop period with the commands free (-).
    Gam : ndarray, shape (n, m)
        Their input (per unit command).
    R : ndarray, shape (m, n)
        The commands the loop computes.
    Dl : ndarray, shape (m, m)
        Same-tick path from the free commands to the computed ones (zero for a delayed
        law).
    period : float
        Loop period (s).
    channels : tuple of str
        ``instance.output`` of each command.
    """

    Phi: np.ndarray
    Gam: np.ndarray
    R: np.ndarray
    Dl: np.ndarray
    period: float
    channels: tuple

    def closed(self, factors) -> np.ndarray:
        """The closed-loop map with command ``i`` multiplied by ``factors[i]``.

        Parameters
        ----------
        factors : array_like, shape (m,)
            Real or complex factors (-).

        Returns
        -------
        ndarray, shape (n, n)
        """
        F = np.diag(np.asarray(factors, dtype=complex if np.iscomplexobj(factors)
                               else float) * np.ones(len(self.channels)))
        inner = np.linalg.solve(np.eye(F.shape[0]) - F @ self.Dl, F @ self.R)
        return self.Phi + self.Gam @ inner

    def stable(self, factors, tol: float = 1e-9) -> bool:
        """Every pole of :meth:`closed` inside the unit circle (rigid-body poles at 1
        allowed).

        Parameters
        ----------
        factors : array_like, shape (m,)
            Real or complex factors on the commands (-).
        tol : float
            Margin inside the unit circle (-).

        Returns
        -------
        bool
        """
        ev = np.linalg.eigvals(self.closed(factors))
        rigid = np.abs(ev - 1.0) < 1e-6
        return bool(np.all(rigid | (np.abs(ev) < 1.0 - tol)))

    def return_ratio(self, freqs_hz) -> np.ndarray:
        """``T(e^{j 2 pi f P})`` at each frequency, shape (n_f, m, m) (positive feedback)."""
        n = self.Phi.shape[0]
        out = np.empty((len(freqs_hz), len(self.channels), len(self.channels)), complex)
        for i, f in enumerate(freqs_hz):
            z = np.exp(2j * math.pi * f * self.period)
            out[i] = self.R @ np.linalg.solve(z * np.eye(n) - self.Phi, self.Gam) + self.Dl
        return out


@dataclass(frozen=True)
class LoopMargins:
    """Margins of one loop broken at its command, the others closed.

    Attributes
    ----------
    loop : str
        ``instance.output`` of the command.
    gain_up_db, gain_down_db : float
        Gain margins (dB): the command may grow by ``gain_up_db`` and shrink by
        ``gain_down_db`` (positive number; ``inf`` when the loop stays stable down to
        zero and through a sign change within the search) before a pole reaches the
        unit circle; ``-inf`` both when the loop is unstable as it is.
    phase_deg : float
        Phase margin (deg), ``inf`` if no phase lag up to 180 deg destabilises it.
    disk_alpha : float
        Balanced disk margin ``alpha`` (-); :func:`disk_to_gain_phase` gives its gain
        (dB) and phase (deg).
    crossovers_hz : tuple of float
        Frequencies where ``|T| = 1`` (Hz).
    phase_stabilised : tuple of (float, float)
        Above the first crossover, peaks of ``|T| > 1``: (frequency Hz, peak dB).
    stable : bool
        The closed loop as it is.
    opened : tuple of str
        Slower instances opened for the phase and disk margins.
    """

    loop: str
    gain_up_db: float
    gain_down_db: float
    phase_deg: float
    disk_alpha: float
    crossovers_hz: tuple
    phase_stabilised: tuple
    stable: bool
    opened: tuple = ()

    @property
    def disk_db(self) -> float:
        return disk_to_gain_phase(self.disk_alpha)[0]

    @property
    def disk_deg(self) -> float:
        return disk_to_gain_phase(self.disk_alpha)[1]

    def as_dict(self) -> dict:
        """Plain numbers for JSON (infinite values as strings ``"inf"``)."""
        def num(v):
            return v if math.isfinite(v) else ("inf" if v > 0 else "-inf")
        return {"loop": self.loop, "stable": self.stable,
                "gain_up_db": num(self.gain_up_db), "gain_down_db": num(self.gain_down_db),
                "phase_deg": num(self.phase_deg), "disk_alpha": num(self.disk_alpha),
                "disk_db": num(self.disk_db), "disk_deg": num(self.disk_deg),
                "crossovers_hz": list(self.crossovers_hz),
                "phase_stabilised": [{"freq_hz": f, "peak_db": p}
                                     for f, p in self.phase_stabilised],
                "opened": list(self.opened)}


@dataclass(frozen=True)
class GroupMargins:
    """The loops of one group (the ACS's axes, one instrument's struts).

    Attributes
    ----------
    name : str
        Group name.
    loops : tuple of LoopMargins
        Each loop broken alone, the others closed.
    disk_alpha : float
        MIMO disk margin of the group broken together (-).
    common_up_db, common_down_db : float
        Gain margins of a factor on every command of the group at once (dB).
    """

    name: str
    loops: tuple
    disk_alpha: float
    common_up_db: float
    common_down_db: float
    opened: tuple = field(default=())

    def as_dict(self) -> dict:
        g, p = disk_to_gain_phase(self.disk_alpha)
        return {"group": self.name, "mimo_disk_alpha": self.disk_alpha,
                "mimo_disk_db": g, "mimo_disk_deg": p,
                "common_gain_up_db": self.common_up_db,
                "common_gain_down_db": self.common_down_db,
                "opened": list(self.opened),
                "loops": [m.as_dict() for m in self.loops]}


def disk_to_gain_phase(alpha: float) -> tuple:
    """Gain (dB, either way) and phase (deg) of a balanced disk margin ``alpha``.

    Parameters
    ----------
    alpha : float
        Disk margin (-), ``>= 2`` meaning every gain.

    Returns
    -------
    (float, float)
        ``20 log10((2 + alpha)/(2 - alpha))`` and ``2 atan(alpha/2)`` in degrees.
    """
    if not alpha > 0:
        return 0.0, 0.0
    gain = math.inf if alpha >= 2 else 20 * math.log10((2 + alpha) / (2 - alpha))
    return gain, math.degrees(2 * math.atan(alpha / 2))


def _factor_boundary(stable, kind: str, tol: float = 1e-3) -> float:
    """Smallest factor (``kind`` "up": gain > 1, "down": gain < 1 then negative, "phase":
    lag in degrees) at which ``stable`` fails; inf when none within the search."""
    if kind == "phase":
        grid = np.linspace(0.0, 180.0, 91)[1:]
        f = lambda x: np.exp(-1j * math.radians(x))   # noqa: E731
    elif kind == "up":
        grid = np.geomspace(1.0, 1e4, 41)[1:]
        f = lambda x: x                                 # noqa: E731
    else:
        grid = np.r_[np.geomspace(1.0, 1e-3, 31)[1:], 0.0, -np.geomspace(1e-3, 1e3, 25)]
        f = lambda x: x                                 # noqa: E731
    prev = 0.0 if kind == "phase" else 1.0
    for g in grid:
        if not stable(f(g)):
            a, b = prev, g
            while abs(b - a) > tol * max(abs(a), abs(b), 1e-3):
                mid = 0.5 * (a + b) if (kind != "up" or a <= 0) else math.sqrt(a * b)
                a, b = (mid, b) if stable(f(mid)) else (a, mid)
            return 0.5 * (a + b)
        prev = g
    return math.inf


def _grid(loop: BrokenLoop, n: int = 500) -> np.ndarray:
    """Log grid to Nyquist, refined around the lightly damped open-loop poles."""
    nyq = 0.5 / loop.period
    f = list(np.geomspace(nyq * 1e-4, nyq * 0.999, n))
    ev = np.linalg.eigvals(loop.Phi)
    ev = ev[(np.abs(ev) > 1e-6) & (ev.imag > 0)]
    s = np.log(ev) / loop.period
    for p in s:
        wn = abs(p)
        fn, zeta = wn / (2 * math.pi), -p.real / wn
        if zeta < 0.2 and nyq * 1e-4 < fn < nyq:
            width = max(zeta, 1e-4) * fn
            f.extend(fn + width * np.linspace(-4, 4, 17))
    f = np.unique(np.clip(f, nyq * 1e-4, nyq * 0.999))
    return f


def group_margins(lin, channels, name: str, opened=()) -> GroupMargins:
    """Margins of each loop of a group and of the group together.

    Parameters
    ----------
    lin : LinearScenario
        The loop at the group's own rate (slower instances opened, named in
        ``opened``).
    channels : sequence of str
        The group's commands ``instance.output`` (one or several instances).
    name : str
        Group name.
    opened : sequence of str
        Instances opened in ``lin`` (reported).

    Returns
    -------
    GroupMargins
    """
    return margins_of(broken_loop(lin, channels), name, opened)


def margins_of(joint: BrokenLoop, name: str, opened=()) -> GroupMargins:
    """Margins of each loop of a broken loop and of all its loops together.

    Parameters
    ----------
    joint : BrokenLoop
        The loops broken at their commands (from :func:`broken_loop`, or assembled from
        matrices).
    name : str
        Group name.
    opened : sequence of str
        Instances opened before breaking (reported).

    Returns
    -------
    GroupMargins
    """
    channels = list(joint.channels)
    m = len(channels)
    f = _grid(joint)
    T = joint.return_ratio(f)
    nominal = joint.stable(np.ones(m))
    out = []
    for i, ch in enumerate(channels):
        def stable_i(c, i=i):
            fac = np.ones(m, dtype=complex if isinstance(c, complex) else float)
            fac[i] = c
            return joint.stable(fac)

        # loop i alone, the others closed: T_ii + T_ir (I - T_rr)^-1 T_ri
        r = [j for j in range(m) if j != i]
        Ti = T[:, i, i].copy()
        if r:
            Trr = T[:, r][:, :, r]
            Ti = Ti + np.einsum("fj,fj->f", T[:, i, r], np.linalg.solve(
                np.eye(len(r))[None] - Trr, T[:, r, i][..., None])[..., 0])
        out.append(_loop(ch, Ti, f, nominal, stable_i, opened))
    if nominal:
        S = np.linalg.inv(np.eye(m)[None] - T)
        sv = np.linalg.svd(S - 0.5 * np.eye(m)[None], compute_uv=False)[:, 0]
        alpha = float(1.0 / sv.max())

        def common(c):
            return joint.stable(np.full(m, c))
        up, down = _factor_boundary(common, "up"), _factor_boundary(common, "down")
    else:
        alpha, up, down = 0.0, 0.0, 0.0
    return GroupMargins(name, tuple(out), alpha, _db_up(up), _db_down(down), tuple(opened))


def _db_up(k: float) -> float:
    return math.inf if math.isinf(k) else (20 * math.log10(k) if k > 0 else -math.inf)


def _db_down(k: float) -> float:
    return math.inf if (math.isinf(k) or k <= 0) else -20 * math.log10(k)


def _loop(ch, Ti, f, nominal, stable_i, opened) -> LoopMargins:
    mag = np.abs(Ti)
    cross = np.flatnonzero((mag[1:] - 1) * (mag[:-1] - 1) < 0)
    fc = tuple(float(np.interp(0.0, [math.log(mag[j]), math.log(mag[j + 1])][::1]
                               if mag[j] < mag[j + 1] else
                               [math.log(mag[j + 1]), math.log(mag[j])],
                               [f[j], f[j + 1]] if mag[j] < mag[j + 1] else [f[j + 1], f[j]]))
               for j in cross)
    peaks = []
    if fc:
        above = f > fc[0]
        fa, ma = f[above], mag[above]
        for j in range(1, len(ma) - 1):
            if ma[j] > 1 and ma[j] >= ma[j - 1] and ma[j] >= ma[j + 1]:
                peaks.append((float(fa[j]), float(20 * math.log10(ma[j]))))
    if not nominal:
        return LoopMargins(ch, -math.inf, -math.inf, -math.inf, 0.0, fc, tuple(peaks),
                           False, tuple(opened))
    up = _factor_boundary(stable_i, "up")
    down = _factor_boundary(stable_i, "down")
    ph = _factor_boundary(stable_i, "phase")
    S = 1.0 / (1.0 - Ti)
    alpha = float(1.0 / np.max(np.abs(S - 0.5)))
    return LoopMargins(ch, _db_up(up), _db_down(down), float(ph), alpha, fc, tuple(peaks),
                       True, tuple(opened))


def broken_loop(lin, channels, *, faster: bool = False) -> BrokenLoop:
    """The loop of ``lin`` broken at the given commands, over one loop period.

    Parameters
    ----------
    lin : LinearScenario
        The closed loop; the commands' instances must run at its hyperperiod (open
        slower instances first).
    channels : sequence of str
        Commands ``instance.output`` (of one or several instances).
    faster : bool
        Also break outputs of instances that run faster than the hyperperiod (a period
        dividing it): their consumers then read the value at the loop's tick 0, held
        over the loop period (exact when every consumer runs at the loop period).

    Returns
    -------
    BrokenLoop
    """
    from .scenario import LinearScenario

    per_inst = {}
    for c in channels:
        inst, var = c.split(".", 1)
        if inst not in lin.blocks or var not in lin.blocks[inst].outputs:
            raise AnalysisError(f"{c} is not an output of the scenario's instances")
        per_inst.setdefault(inst, []).append(var)
    blocks, order, srcs = dict(lin.blocks), list(lin.order), {}
    for k, (inst, outs) in enumerate(per_inst.items()):
        p = lin.blocks[inst].period
        if p != lin.hyper and not (faster and lin.hyper % p == 0):
            raise AnalysisError(f"{inst!r} runs every {lin.blocks[inst].period} ticks but "
                                f"the loop's period is {lin.hyper}; open the slower "
                                "instances first")
        srcs[inst] = (f"{_BREAK}{k}", tuple(outs))
        blocks[f"{_BREAK}{k}"] = _source_block(f"{_BREAK}{k}", lin.hyper, tuple(outs))
        order.insert(0, f"{_BREAK}{k}")
    cut = LinearScenario(lin.plan, blocks, order)
    cut._conns = []
    for t, j, s, i, g in lin._conns:
        var = lin.blocks[s].outputs[i]
        if s in srcs and var in srcs[s][1]:
            cut._conns.append((t, j, srcs[s][0], srcs[s][1].index(var), g))
        else:
            cut._conns.append((t, j, s, i, g))
    cut._conns_to = {}
    for t, j, s, i, g in cut._conns:
        cut._conns_to.setdefault(t, []).append((j, s, i, g))
    chans = [f"{inst}.{v}" for inst, outs in per_inst.items() for v in outs]
    n, m = cut.n, len(chans)
    rows = [cut.index(c) for c in chans]
    X = np.hstack([np.eye(n), np.zeros((n, m))])
    E, off = {}, 0
    for inst, outs in per_inst.items():
        e = np.zeros((len(outs), n + m))
        e[:, n + off:n + off + len(outs)] = np.eye(len(outs))
        E[srcs[inst][0]] = e
        off += len(outs)

    def w_next(name):
        return E[name] if name in E else np.zeros((len(cut.blocks[name].outputs), n + m))

    X = cut._tick(X, 0, w_next)     # tick 0: the free commands published, y computed
    RD = X[rows].copy()
    for name in E:
        E[name] = np.zeros_like(E[name])
    for k in range(1, cut.hyper):
        X = cut._tick(X, k, w_next)
    Phi, Gam, R = X[:, :n], X[:, n:], RD[:, :n]
    # states nothing reads (a source's published slot, overwritten every period): their
    # columns in Phi and R are zero, and they carry the closed loop's poles at 0 only
    k = np.arange(n)
    while True:
        live = np.any(Phi[np.ix_(k, k)] != 0, axis=0) | np.any(R[:, k] != 0, axis=0)
        if live.all():
            break
        k = k[live]
    return BrokenLoop(Phi[np.ix_(k, k)], Gam[k], R[:, k], RD[:, n:], cut.T, tuple(chans))


def loop_groups(lin) -> dict:
    """The scenario's loops by group: the ACS's axes, and each family of controllers
    (instance names equal but for a trailing number: ``ctrl_iso1..3``).

    Returns
    -------
    dict of str to list of str
        Group name -> commands ``instance.output`` (active loops only).
    """
    groups = {}
    for name, b in lin.blocks.items():
        if b.kind == "acs":
            groups[name] = [f"{name}.{o}" for o in b.outputs[:3]]
        elif b.kind == "controller" and b.active:
            fam = re.sub(r"\d+$", "", name) or name
            groups.setdefault(fam, []).extend(f"{name}.{o}" for o in b.outputs)
    return groups


def scenario_margins(lin, known=()) -> list:
    """Margins of every active loop group of a scenario (see the module docstring).

    Parameters
    ----------
    lin : LinearScenario
    known : sequence of GroupMargins
        Groups already measured on this loop (e.g. by the ACS design): kept, not
        measured again.

    Returns
    -------
    list of GroupMargins
    """
    done = {g.name: g for g in known}
    out = []
    for name, chans in loop_groups(lin).items():
        if name in done:
            out.append(done[name])
            continue
        insts = {c.split(".", 1)[0] for c in chans}
        period = max(lin.blocks[i].period for i in insts)
        slow = [n for n, b in lin.blocks.items()
                if b.kind != "source" and b.period > period and n not in insts]
        view = lin.opened(slow) if slow else lin
        out.append(group_margins(view, chans, name, opened=slow))
    return out
