"""The paper's ten-bay truss laboratory model (Figs. 1, 4-6).

Geometry (paper): an L shape of cubic bays, side 10 in (0.254 m); two bays cantilevered
horizontally (+x) from a backstop at x = 0, eight bays hanging vertically (-z) below the
second horizontal bay; aluminium struts joined by steel rods to aluminium node balls; six
steel bars of 7 lb on the lower battens.  Two active members in the bay closest to the
support: the lower horizontal longeron (P-243.30) and the adjacent diagonal on the same
side face (P-243.40), each with a strain gauge on the passive strut in series.

Each bay has 4 longerons, 4 battens per batten plane, one diagonal per side face and
one diagonal per batten plane (no mechanisms).  Each active member is the piezo stack
(stiffness ``k_e``, stack mass) from the fixed node to an intermediate fitting node,
then a passive strut to the far node; the gauge reads that strut's strain.

Assumed properties (the paper does not give them):

=========================  ============================================================
strut tube                  aluminium 6061, OD 1.0 in, wall 0.065 in (A = 1.24e-4 m^2)
E, rho                      70 GPa, 2700 kg/m^3
node ball + rods            0.15 kg per node (steel rods and aluminium ball)
joint efficiency            ``eta_tower``, ``eta_arm``: EA knock-down of erectable joints
active-member fitting       0.20 kg at the intermediate node; stack length + fittings
                            0.10 m (longeron) and 0.12 m (diagonal); the fitting node is
                            held on the member's line by the tube's bending stiffness
                            3 EI L / (a^2 b^2) (two transverse springs)
payload bars                6 x 7 lb (3.175 kg), on the four bottom battens and two
                            battens of the next batten plane up, half to each end node
damping                     modal 0.18 % (mode 1), 0.4 % (mode 2), 0.5 % others (test);
                            Ritz block 2 %
=========================  ============================================================

Calibration: the two joint efficiencies are solved so that the first two modes land
on 8.4 Hz and 9.5 Hz (the paper's modes of interest); the ratio f2/f1 depends only on
``eta_arm / eta_tower`` and the level on their product, so a 1-D root find on the
ratio followed by a uniform scaling does it (see :func:`calibrate`, rerun by
``tests/structfmu/test_truss10.py``).  The stored values below come from that function.
Both modes couple tower bending in two planes with torsion, as the paper reports.
"""

from __future__ import annotations

import numpy as np

from fmukit.units import INCH, LB
from piezofmu import preset
from structfmu.fem import ActiveMember, Truss, assemble, transverse_link
from structfmu.reduce import Damping, eigenpairs, reduce
from structfmu.statespace import to_statespace

BAY = 10 * INCH
E_AL = 70e9
RHO_AL = 2700.0
TUBE_AREA = np.pi / 4 * ((1.0 * INCH) ** 2 - (0.87 * INCH) ** 2)
TUBE_I = np.pi / 64 * ((1.0 * INCH) ** 4 - (0.87 * INCH) ** 4)
NODE_MASS = 0.15
FITTING_MASS = 0.20
BAR_MASS = 7 * LB
# calibrated by calibrate(): modes at 8.4 Hz and 9.5 Hz
ETA_TOWER = 0.9410749
ETA_ARM = 0.8612624
TARGET_HZ = (8.4, 9.5)
ZETA = (0.0018, 0.004)
ZETA_OTHERS = 0.005
ZETA_RITZ = 0.02


def build(eta_tower: float = None, eta_arm: float = None, mass_type: str = "consistent") -> Truss:
    """Full FEM of the ten-bay truss.

    Parameters
    ----------
    eta_tower, eta_arm : float, optional
        Joint efficiencies (EA knock-down) of the vertical tower and the horizontal arm;
        defaults are the calibrated values.
    mass_type : {"consistent", "lumped"}

    Returns
    -------
    Truss
        With inputs ``fc_long``, ``fc_diag`` (actuator forces, N), ``f_tip_x``,
        ``f_tip_y`` (tip forces, N) and outputs ``strain_long``, ``strain_diag``,
        ``elong_long``, ``elong_diag`` (piezo elongations, m), ``acc_tip_x``,
        ``acc_tip_y`` (m/s^2) and ``los_tip_roll/pitch/yaw`` (rad).
    """
    eta_tower = ETA_TOWER if eta_tower is None else eta_tower
    eta_arm = ETA_ARM if eta_arm is None else eta_arm
    a = BAY
    index: dict = {}
    nodes: list = []

    def node(i, j, k):
        key = (i, j, k)
        if key not in index:
            index[key] = len(nodes)
            nodes.append((i * a, j * a, k * a))
        return index[key]

    elements: list = []  # (n1, n2, region)

    def rod(p, q, region):
        elements.append((node(*p), node(*q), region))

    # horizontal arm: bays along x from the backstop (x=0) to x=2a, z in [0, 1]
    for b in range(2):
        x0, x1 = b, b + 1
        for j in (0, 1):
            for k in (0, 1):
                rod((x0, j, k), (x1, j, k), "arm")  # longerons
        # side-face diagonals (y=0, y=1, z=0, z=1 faces)
        rod((x0, 0, 1), (x1, 0, 0), "arm")
        rod((x0, 1, 1), (x1, 1, 0), "arm")
        rod((x0, 0, 0), (x1, 1, 0), "arm")
        rod((x0, 0, 1), (x1, 1, 1), "arm")
    for x in range(3):  # batten planes x = 0, 1, 2
        if x == 0:
            continue  # backstop face: nodes fixed, no battens needed
        rod((x, 0, 0), (x, 1, 0), "arm")
        rod((x, 0, 1), (x, 1, 1), "arm")
        rod((x, 0, 0), (x, 0, 1), "arm")
        rod((x, 1, 0), (x, 1, 1), "arm")
        rod((x, 0, 0), (x, 1, 1), "arm")
    # vertical tower below the second arm bay: x in [1, 2], z from 0 down to -8
    for b in range(8):
        z0, z1 = -b, -b - 1
        for i in (1, 2):
            for j in (0, 1):
                rod((i, j, z0), (i, j, z1), "tower")
        rod((1, 0, z0), (2, 0, z1), "tower")
        rod((1, 1, z0), (2, 1, z1), "tower")
        rod((1, 0, z0), (1, 1, z1), "tower")
        rod((2, 0, z0), (2, 1, z1), "tower")
        z = z1
        rod((1, 0, z), (2, 0, z), "tower")
        rod((1, 1, z), (2, 1, z), "tower")
        rod((1, 0, z), (1, 1, z), "tower")
        rod((2, 0, z), (2, 1, z), "tower")
        rod((1, 0, z), (2, 1, z), "tower")

    # active members in the bay next to the backstop: lower longeron (0,0,0)-(1,0,0)
    # and the adjacent side-face diagonal (0,0,1)-(1,0,0).  Replace the plain rods.
    long_pair = (node(0, 0, 0), node(1, 0, 0))
    diag_pair = (node(0, 0, 1), node(1, 0, 0))
    plain = [(n1, n2, r) for (n1, n2, r) in elements
             if (n1, n2) not in (long_pair, diag_pair)]
    xyz = np.array(nodes, float)

    conn, k_ax, mass = [], [], []
    eta = {"arm": eta_arm, "tower": eta_tower}
    for n1, n2, region in plain:
        length = np.linalg.norm(xyz[n2] - xyz[n1])
        conn.append((n1, n2))
        k_ax.append(eta[region] * E_AL * TUBE_AREA / length)
        mass.append(RHO_AL * TUBE_AREA * length)

    node_mass = [NODE_MASS] * len(xyz)
    active = []
    extra_nodes = []
    links = []
    for name, (n1, n2), stack_name, lp in (("long", long_pair, "P-243.30", 0.10),
                                           ("diag", diag_pair, "P-243.40", 0.12)):
        stack = preset(stack_name)
        d = xyz[n2] - xyz[n1]
        length = np.linalg.norm(d)
        mid = len(xyz) + len(extra_nodes)
        extra_nodes.append(xyz[n1] + d / length * lp)
        node_mass.append(FITTING_MASS)
        conn.append((n1, mid))
        k_ax.append(stack.k_e)
        mass.append(stack.mass)
        pe = len(conn) - 1
        ls = length - lp
        conn.append((mid, n2))
        k_ax.append(eta_arm * E_AL * TUBE_AREA / ls)
        mass.append(RHO_AL * TUBE_AREA * ls)
        active.append(ActiveMember(name, pe, len(conn) - 1, stack))
        # bending stiffness of the member at the fitting: 3 EI L / (a^2 b^2)
        links.append((n1, n2, mid, 3 * E_AL * TUBE_I * length / (lp**2 * ls**2)))
    xyz = np.vstack([xyz, np.array(extra_nodes)])
    springs = tuple(s for n1, n2, mid, k in links for s in transverse_link(xyz, n1, n2, mid, k))
    node_mass = np.array(node_mass)

    # six 7 lb bars on the lower battens: the 4 bottom battens (z=-8) and the two
    # x-direction battens one plane up (z=-7); half of each bar to each end node
    bars = [((1, 0, -8), (2, 0, -8)), ((1, 1, -8), (2, 1, -8)), ((1, 0, -8), (1, 1, -8)),
            ((2, 0, -8), (2, 1, -8)), ((1, 0, -7), (2, 0, -7)), ((1, 1, -7), (2, 1, -7))]
    for p, q in bars:
        node_mass[index[p]] += BAR_MASS / 2
        node_mass[index[q]] += BAR_MASS / 2

    fixed = np.concatenate([3 * index[(0, j, k)] + np.arange(3)
                            for j in (0, 1) for k in (0, 1)])
    names = {f"n{i}_{j}_{k}": v for (i, j, k), v in index.items()}
    names.update({"fit_long": len(index), "fit_diag": len(index) + 1})
    truss = Truss(nodes=xyz, elements=np.array(conn), axial_stiffness=np.array(k_ax),
                  element_mass=np.array(mass), node_mass=node_mass, fixed_dofs=fixed,
                  active=tuple(active), name="truss10", mass_type=mass_type,
                  node_names=names, springs=springs)
    tip = "n1_0_-8"
    loads = (truss.force_channel("f_tip_x", tip, (1, 0, 0)),
             truss.force_channel("f_tip_y", tip, (0, 1, 0)))
    a_long, a_diag = active
    outputs = (
        truss.strain_channel("strain_long", a_long.gauge_element),
        truss.strain_channel("strain_diag", a_diag.gauge_element),
        truss.elong_channel("elong_long", a_long.element),
        truss.elong_channel("elong_diag", a_diag.element),
        truss.accel_channel("acc_tip_x", tip, (1, 0, 0)),
        truss.accel_channel("acc_tip_y", tip, (0, 1, 0)),
        *truss.angle_channels("los_tip", ["n1_0_-8", "n2_0_-8", "n1_1_-8", "n2_1_-8"]),
    )
    return truss.replace(loads=loads, outputs=outputs)


def damping(n_modes: int) -> Damping:
    """The model's damping: paper's 0.18 % and 0.4 % on modes 1-2, 0.5 % on others."""
    zeta = np.full(n_modes, ZETA_OTHERS)
    zeta[: min(2, n_modes)] = ZETA[: min(2, n_modes)]
    return Damping(zeta=zeta, zeta_ritz=ZETA_RITZ)


def reduced(n_modes: int = 6, ritz: bool = True, truss: Truss | None = None):
    """The paper's reduced model: 6 eigenvectors + 2 static Ritz vectors by default.

    Parameters
    ----------
    n_modes : int
        Number of eigenvectors; damping from :func:`damping`.
    ritz : bool
        Append one static Ritz vector per active member (two).
    truss : Truss, optional
        Full model to reduce; default :func:`build` with the calibrated values.

    Returns
    -------
    ReducedModel
    """
    truss = truss or build()
    return reduce(truss, n_modes, ritz=ritz, damping=damping(n_modes))


def frequencies_hz(truss: Truss, n: int = 6) -> np.ndarray:
    """First ``n`` natural frequencies of the full FEM (Hz).

    Parameters
    ----------
    truss : Truss
        The full model (constrained: no rigid-body modes expected).
    n : int
        Number of frequencies.

    Returns
    -------
    ndarray, shape (n,)
        Natural frequencies (Hz), ascending.
    """
    K, M = assemble(truss)
    lam, _, _ = eigenpairs(K, M, n, 0.0, truss)
    return np.sqrt(lam) / (2 * np.pi)


def calibrate(target=TARGET_HZ):
    """Solve the joint efficiencies that put modes 1-2 on ``target`` (Hz).

    Returns
    -------
    (eta_tower, eta_arm) : tuple of float
    """
    # deferred: scipy takes about 1 s to load
    from scipy.optimize import brentq

    f_ratio = target[1] / target[0]

    def ratio(log_r):
        f = frequencies_hz(build(1.0, float(np.exp(log_r))), 2)
        return f[1] / f[0] - f_ratio

    log_r = brentq(ratio, np.log(0.02), np.log(50.0), xtol=1e-6)
    r = float(np.exp(log_r))
    f1 = frequencies_hz(build(1.0, r), 2)[0]
    s = (target[0] / f1) ** 2
    return s, s * r


def plant(actuator: str, model=None):
    """SISO plant from an actuator's voltage (V) to its own gauge strain, continuous.

    Parameters
    ----------
    actuator : {"diag", "long"}
        Active member.
    model : ReducedModel, optional
        Default :func:`reduced`.

    Returns
    -------
    control.StateSpace
        Includes ``f_c = c h v`` of the member's stack; no amplifier dynamics.
    """
    model = model or reduced()
    if actuator not in ("diag", "long"):
        raise KeyError(f"unknown active member {actuator!r}; expected 'diag' or 'long'")
    ch = model.meta["actuators"][actuator]["ch"]
    sub = model.select([f"fc_{actuator}"], [f"strain_{actuator}"])
    return to_statespace(sub) * ch
