"""A structural model like the LaRC EOS Dynamics Testbed (paper, Figs. 10-16).

The testbed emulates the EOS AM-1 spacecraft at 1/10 mass and stiffness with the same
geometry and frequencies: a truss bus of 10 in (0.254 m) cubic bays, a flexible solar
array (first mode 0.5 Hz), a high-gain antenna, dummy instrument and subsystem masses,
a suspension giving six rigid-body modes below 0.3 Hz, and three gimballed payloads at
the CERES (rigid mount), TIR (kinematic mount) and MISR (isolator mounts: three P-845.37
piezo struts and one aluminium tube) locations; first bus mode 23 Hz.  For the EOS AM-1
study the SWIR and VNIR kinematic mounts carry a piezo stack in series.

Body axes (as in :mod:`distfmu.presets`): x roll (along the bus length, flight
direction), y pitch (cross track), z yaw (nadir).  The bus box spans
``0 <= x <= 16 a``, ``0 <= y <= 2 a``, ``0 <= z <= 2 a`` with ``a`` = 0.254 m; z = 2 a is
the nadir (instrument) face, z = 0 the zenith face.  Nodes are named ``bus_i_j_k``
(at ``(i, j, k) a``), ``<inst>_p0..p3`` (payload plate), ``<inst>_cg``,
``<inst>_fit_<member>``, ``sa_<station>_<corner>``, ``hga_<station>_<corner>``,
``hga_dish``.

Assumed properties, the one table (P = paper, A = assumption, C = calibrated here;
docs/eos_testbed.md repeats it with the layout):

=====================  =================================================================  ====
item                   value                                                              src
=====================  =================================================================  ====
bay                    0.254 m (10 in) cubes                                              P
bus lattice            16 x 2 x 2 bays (4.06 x 0.51 x 0.51 m), every cube edge + one      A
                       diagonal per cube face (alternating), 153 nodes, 608 struts
bus strut              aluminium tube OD 0.75 in, wall 0.049 in (A = 6.96e-5 m^2),        A
                       E = 70 GPa, rho = 2700 kg/m^3
bus joint efficiency   ``ETA_BUS`` = 0.772 (EA knock-down of erectable joints) so that    C
                       the first bus mode is 23 Hz
node ball + rods       0.15 kg per bus node                                               A
subsystem masses       propulsion 60, power 70, C&DH 25, comms 20, RWA/ACS 25, harness/   A
                       thermal 60 kg (260 kg), each on the 8 nodes of one bus cube
                       (``SUBSYSTEMS``)
instrument masses      about 1/10 of EOS AM-1: CERES 9, MISR 15, TIR 14, SWIR 11, VNIR 8  A
                       kg (60 % at the CG node 0.15 m above the plate centre, 40 % on the
                       plate corners); MODIS 23 kg and MOPITT 19 kg on the 4 bus nodes of
                       their nadir cell (no station)
total mass             464 kg (EOS AM-1 about 5,190 kg: 1/10 scale as in the paper)       P/A
payload station        plate: 4 nodes on a 0.254 m square 0.127 m above the nadir face    A
                       (``STATIONS`` cell), edges + one diagonal, CG node on 4 rods; rod
                       EA 5 x bus tube (gimbal locked, payload stiff); 0.10 kg per plate
                       node
CERES mount            rigid: 4 posts + 4 side diagonals (bus tube, EA not knocked down)  P/A
TIR mount              kinematic: 3 bipods (6 pinned bus-tube struts; at plate corners    P/A
                       0, 1, 2 one vertical and one inclined leg in a side plane)
MISR mount             isolator: 3 vertical legs, each a P-845.37 stack (ActiveMember     P/A
                       ``iso1..3``, k_e 6.70e7 N/m, 40.6 mm, 0.063 kg) + 0.05 kg fitting
                       + solid aluminium rod d 0.5 in; 4th leg a solid rod d 0.5 in;
                       lateral flexure stiffness of each leg end 2e5 N/m (stack legs) and
                       12 EI/L^3 = 5.2e5 N/m (rod), rotation-invariant (held on the line
                       of the bus post below the foot)
MISR layout            ``MISR_FEET``: iso1, tube, iso2 on the bus line x = 3 a (j = 0, 1,   C
                       2), iso3 alone at (1 a, 1 a), two bays behind: a triangular plate
                       whose pitch only iso3 can change.  Fitted to "mount #3 in the
                       dominant 22 Hz path": the 22 Hz bus bending has its node line at
                       x ~ 3 a, so the SWIR cryocooler pitches MISR through iso3's foot
                       (holding its payload accelerometer at zero removes 81 % of the
                       boresight jitter; on the old square cell with iso3 on the quiet
                       corner, 1.8 %)
MISR gimbal            two-axis gimballed payload (paper: 2 arcsec, about 8 Hz): 60 % of  P/A
                       the mass on a rigid octahedron (r 0.12 m) around a pivot
                       ``misr_cg`` 0.15 m above the plate; roll and pitch springs to the
                       plate J (2 pi 8 Hz)^2 (servo, modes 7.9 Hz, damping 5 %), yaw
                       1000 x stiffer; ``los_misr_*`` read the gimballed body
hybrid mount #3        ``build(iso3="hybrid")`` only (not the default): iso3's rod in     C
                       series with an elastomer stage ``ISO3_SERIES_K`` = 3.0e4 N/m, loss
                       factor ``ISO3_LOSS_FACTOR`` = 0.2 (modal strain energy damping in
                       :func:`damping`; plate pitch mode 15.7 Hz, 9 %), bus and array
                       recalibrated (``ETA_BUS_HYBRID``, ``EA_ARRAY_HYBRID``).  Fitted to
                       "mount #3 alone about 80 %" with the stated law: 78.6 % co-simulated
                       (docs/eos_testbed.md, "Hybrid mount #3")
SWIR, VNIR mounts      kinematic as TIR; the inclined leg of bipod 1 carries a P-845.37   P/A
                       stack in series (``swir_mount``, ``vnir_mount``); with
                       ``active_legs="all"`` every leg does (``swir_mount1..6`` ...);
                       P-845.37 because the paper asks < 5 um and < 15 lb, at < 100 V
strain gauges          on the stack itself (paper: gauge on the internal piezoceramic)    P
solar array            boom 9 bays x 0.508 m (4.57 m) along -y, section 0.508 m (x, in    A
                       plane) x 0.05 m (z, out of plane), on a yoke 0.10 m off the bus
                       -y face (4 root nodes, 3 stiff struts each); panels 30 kg on the
                       36 boom nodes; struts 0.10 kg/m; battens/diagonals EA 2.31e6 N
                       (tube 0.5 x 0.035 in)
array longeron EA      ``EA_ARRAY`` = 2.35e5 N (equivalent) so that the first array      C
                       mode is 0.5 Hz
high-gain antenna      boom 5 bays x 0.254 m along -z from the zenith face (cell 14, 0),  A
                       section 0.254 m, longeron EA 2.0e5 N (equivalent), braces as the
                       array, 0.10 kg/m; dish 4 kg at a node 0.2 m beyond the tip
suspension             off by default; ``suspension=True``: five cables 19.8 m (65 ft),   P/A
                       pendulum springs m g / (5 L) in x and y, vertical springs for a
                       0.2 Hz bounce, on five zenith-face nodes (no geometric stiffness)
damping                modal 0.5 % on flexible modes (0 on rigid ones), Ritz block 2 %   A
accelerometers         150 Hz bandwidth, modelled as a 4th-order Butterworth low-pass on  P/A
                       every acceleration output (``ACCEL_LOWPASS``, structfmu.sensors):
                       the stack-fitting modes near 2-3 kHz otherwise alias into the
                       1 kHz samples
=====================  =================================================================  ====

Active members follow Eq. (1) as in :mod:`structfmu.models.truss10`: each stack is a rod
of stiffness ``k_e`` and the stack mass from its resonance, from the bus-side node to a
fitting node, then a passive rod to the payload; the fitting node is held on the leg's
line by two transverse springs (the leg's bending stiffness, 3 EI L / (a^2 b^2)).

"First bus mode" is the first flexible mode whose strain energy is at least 50 % in the
bus lattice elements; "first array mode" likewise with the array boom
(:func:`strain_energy_fractions`).  :func:`calibrate` solves ``ETA_BUS`` and ``EA_ARRAY``
for 23 Hz and 0.5 Hz (a fixed-point iteration on ``f ~ sqrt(stiffness)``); the stored
constants come from it.

Reduction (:func:`reduced`): 70 eigenvectors (to 162 Hz) and 59 static Ritz vectors,
one per active member and one per disturbance wrench input, shift -100 (rad/s)^2.  The
actuator Ritz vectors make the elongation response statically exact (self-equilibrated
loads); the load Ritz vectors carry the local mount and payload deformation under
instrument loads, which the eigenvectors to 160 Hz miss (at 22 Hz the SWIR-load
response errors drop from up to a third to below 1e-4).  With shift -1 the singularity
test of :func:`structfmu.reduce.ritz_vectors` rejects non-equilibrated loads, because
their shifted static shape is then almost all rigid-body motion.

Loads are 6-component wrench channels ``<loc>_fx .. <loc>_mz`` (N, N m) spread with
least-norm nodal forces over a node set (:func:`wrench_channels`): on the instrument
CG + plate nodes for ceres, misr, swir, tir, vnir (the disturbance comes from the
instrument, so it passes through the mount), on bus nodes for modis, mopitt, rwa, and
on the array root nodes for sad.  The ACS torques ``acs_tx/ty/tz`` (N m) are pure
couples on the RWA node set (the wheels torque the bus).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from fmukit.units import G0, INCH
from piezofmu import preset
from structfmu.errors import ModelError
from structfmu.fem import ActiveMember, Channel, Spring, Truss, assemble, transverse_link
from structfmu.reduce import Damping, eigenpairs, reduce
from structfmu.sensors import SensorLowpass

BAY = 10 * INCH
NX, NY, NZ = 16, 2, 2
E_AL = 70e9
RHO_AL = 2700.0
TUBE_AREA = np.pi / 4 * ((0.75 * INCH) ** 2 - (0.652 * INCH) ** 2)
ROD_D = 0.5 * INCH
ROD_AREA = np.pi / 4 * ROD_D**2
ROD_I = np.pi / 64 * ROD_D**4
NODE_MASS = 0.15
PLATE_NODE_MASS = 0.10
PLATE_EA_FACTOR = 5.0
MOUNT_HEIGHT = BAY / 2
CG_HEIGHT = 0.15
CG_FRACTION = 0.6
FITTING_MASS = 0.05
STACK = "P-845.37"
K_LAT_STACK_LEG = 2e5
# build(iso3="hybrid"): mount #3 (iso3) a hybrid isolator, its stack in series with a
# soft, damped elastomer stage (axial stiffness N/m, loss factor); see _stacked_leg,
# damping() and docs/eos_testbed.md ("Hybrid mount #3")
ISO3_SERIES_K = 3.0e4
ISO3_LOSS_FACTOR = 0.2
ARRAY_BAYS = 9
ARRAY_BAY = 2 * BAY
ARRAY_DEPTH = 0.05
ARRAY_YOKE = 0.10
SMALL_TUBE_AREA = np.pi / 4 * ((0.5 * INCH) ** 2 - (0.43 * INCH) ** 2)
EA_BRACE = E_AL * SMALL_TUBE_AREA
ARRAY_PANEL_MASS = 30.0
APPENDAGE_LINE_DENSITY = 0.10
HGA_BAYS = 5
EA_HGA = 2.0e5
HGA_DISH_MASS = 4.0
HGA_DISH_OFFSET = 0.2
SUSPENSION_LENGTH = 65 * 12 * INCH
SUSPENSION_BOUNCE_HZ = 0.2
ZETA = 0.005
ZETA_RITZ = 0.02
ACCEL_LOWPASS = SensorLowpass(4, 150.0)  # paper: accelerometers 10 ug, 150 Hz
TARGET_BUS_HZ = 23.0
TARGET_ARRAY_HZ = 0.5
SHIFT = -100.0
# calibrated by calibrate(): first bus mode 23 Hz, first array mode 0.5 Hz
ETA_BUS = 0.7720308
EA_ARRAY = 2.349375e5
# the same for build(iso3="hybrid") (calibrate(iso3="hybrid"))
ETA_BUS_HYBRID = 0.7421872
EA_ARRAY_HYBRID = 2.349441e5
N_MODES = 70

INSTRUMENTS = ("ceres", "tir", "misr", "swir", "vnir")
LOCATIONS = ("ceres", "misr", "modis", "mopitt", "swir", "tir", "vnir", "rwa", "sad")
WRENCH = ("fx", "fy", "fz", "mx", "my", "mz")

# MISR isolator feet: nadir-face bus nodes (i, j) of the four legs (a diamond; see
# _misr_station and docs/eos_testbed.md for why this layout and why iso3 is there)
MISR_FEET = {"iso1": (3, 0), "iso2": (3, 2), "iso3": (1, 1), "tube": (3, 1)}
GIMBAL_HZ = 8.0         # paper: the payloads point with about 8 Hz bandwidth
GIMBAL_RADIUS = 0.12    # gimballed-body node radius about the pivot (m)
GIMBAL_YAW_FACTOR = 1000.0  # no yaw axis: yaw mode near 250 Hz
ZETA_GIMBAL = 0.05      # servo damping of the two gimbal modes (see gimbal_modes)
# nadir-face cell (i, j) of each station: the plate sits over bus nodes (i..i+1, j..j+1)
# (MISR: lower corner of the 2 x 2 cells its diamond spans)
STATIONS = {"misr": (1, 0), "ceres": (5, 1), "tir": (8, 0), "swir": (11, 0), "vnir": (13, 1)}
INSTRUMENT_MASS = {"ceres": 9.0, "misr": 15.0, "tir": 14.0, "swir": 11.0, "vnir": 8.0}
MOUNTS = {"ceres": "rigid", "tir": "kinematic", "misr": "isolator", "swir": "kinematic",
          "vnir": "kinematic"}
# instruments without a station: mass on the 4 nodes of a nadir cell
BUS_INSTRUMENTS = {"modis": ((4, 0), 23.0), "mopitt": ((15, 1), 19.0)}
# subsystem masses (kg) on the 8 nodes of the bus cube with lower corner (i, j, k)
SUBSYSTEMS = {"propulsion": ((0, 0, 0), 60.0), "power": ((3, 1, 0), 70.0),
              "cdh": ((7, 0, 1), 25.0), "comms": ((12, 1, 0), 20.0),
              "rwa": ((9, 0, 0), 25.0), "harness": ((14, 0, 1), 60.0)}
ACS_SENSOR_CUBE = (6, 0, 0)  # att_* / rate_*: the 8 nodes of this bus cube
ARRAY_ROOT = (3, 0)   # (i, k): yoke over bus nodes x in {3, 5} a, z in {0, 1} a, y = 0 face
HGA_ROOT = (14, 0)    # (i, j): boom root on bus nodes x in {14, 15} a, y in {0, 1} a, z = 0


def _bus_name(i, j, k):
    return f"bus_{i}_{j}_{k}"


def build(eta_bus: float | None = None, ea_array: float | None = None, *,
          suspension: bool = False, active_legs: str = "one", iso3: str = "stiff",
          mass_type: str = "consistent") -> Truss:
    """Full FEM of the EOS-like testbed (free-free unless ``suspension``).

    Parameters
    ----------
    eta_bus : float, optional
        EA knock-down of the bus struts (default the calibrated ``ETA_BUS``).
    ea_array : float, optional
        Axial stiffness ``EA`` of the solar-array boom struts (N); default ``EA_ARRAY``.
    suspension : bool
        Add the soft suspension (five cables + pneumatic springs to ground, all six
        rigid-body modes below 0.3 Hz).  Default off (free-free).
    active_legs : {"one", "all"}
        SWIR and VNIR mounts: one stack per mount (``swir_mount``, ``vnir_mount``) or one
        in each of the six kinematic legs (``swir_mount1..6``, ``vnir_mount1..6``).
    iso3 : {"stiff", "hybrid"}
        MISR mount #3: the stack + rod leg as the other two (default), or a hybrid
        isolator with an elastomer stage of ``ISO3_SERIES_K`` in series (loss factor
        ``ISO3_LOSS_FACTOR``, applied by :func:`damping`); ``eta_bus``/``ea_array`` then
        default to ``ETA_BUS_HYBRID``/``EA_ARRAY_HYBRID`` (first modes 23 and 0.5 Hz).
    mass_type : {"consistent", "lumped"}

    Returns
    -------
    Truss
        Inputs: ``<loc>_fx .. <loc>_mz`` for ``LOCATIONS`` (N, N m), ``acs_tx/ty/tz``
        (N m) and ``fc_<member>`` (N).  Outputs: ``los_<inst>_roll/pitch/yaw`` (rad),
        ``acc_pay_iso1..3``, ``acc_bus_iso1..3``, ``acc_pay_tube``, ``acc_bus_tube``
        (m/s^2 along the leg), ``strain_<member>``, ``elong_<member>`` (1, m),
        ``att_roll/pitch/yaw`` (rad), ``rate_roll/pitch/yaw`` (rad/s).
    """
    if active_legs not in ("one", "all"):
        raise ModelError(f"active_legs is {active_legs!r}; expected 'one' or 'all'")
    if iso3 not in ("stiff", "hybrid"):
        raise ModelError(f"iso3 is {iso3!r}; expected 'stiff' or 'hybrid'")
    hybrid = iso3 == "hybrid"
    eta_bus = (ETA_BUS_HYBRID if hybrid else ETA_BUS) if eta_bus is None else float(eta_bus)
    ea_array = (EA_ARRAY_HYBRID if hybrid else EA_ARRAY) if ea_array is None \
        else float(ea_array)
    a = BAY
    stack = preset(STACK)
    xyz: list = []
    names: dict = {}
    node_mass: list = []

    def add_node(name, p, mass=0.0):
        names[name] = len(xyz)
        xyz.append(np.asarray(p, float))
        node_mass.append(mass)
        return names[name]

    conn: list = []
    k_ax: list = []
    el_mass: list = []
    springs: list = []

    def rod(n1, n2, ea, line_density):
        length = float(np.linalg.norm(xyz[n2] - xyz[n1]))
        conn.append((n1, n2))
        k_ax.append(ea / length)
        el_mass.append(line_density * length)
        return len(conn) - 1

    # -- bus lattice ---------------------------------------------------------------------
    for i in range(NX + 1):
        for j in range(NY + 1):
            for k in range(NZ + 1):
                add_node(_bus_name(i, j, k), (i * a, j * a, k * a), NODE_MASS)
    B = lambda i, j, k: names[_bus_name(i, j, k)]  # noqa: E731
    ea_bus = eta_bus * E_AL * TUBE_AREA
    rho_tube = RHO_AL * TUBE_AREA
    for i in range(NX + 1):
        for j in range(NY + 1):
            for k in range(NZ + 1):
                if i < NX:
                    rod(B(i, j, k), B(i + 1, j, k), ea_bus, rho_tube)
                if j < NY:
                    rod(B(i, j, k), B(i, j + 1, k), ea_bus, rho_tube)
                if k < NZ:
                    rod(B(i, j, k), B(i, j, k + 1), ea_bus, rho_tube)
                # one diagonal per face, direction alternating with the cell parity
                if i < NX and j < NY:
                    if (i + j + k) % 2:
                        rod(B(i, j, k), B(i + 1, j + 1, k), ea_bus, rho_tube)
                    else:
                        rod(B(i + 1, j, k), B(i, j + 1, k), ea_bus, rho_tube)
                if i < NX and k < NZ:
                    if (i + j + k) % 2:
                        rod(B(i, j, k), B(i + 1, j, k + 1), ea_bus, rho_tube)
                    else:
                        rod(B(i + 1, j, k), B(i, j, k + 1), ea_bus, rho_tube)
                if j < NY and k < NZ:
                    if (i + j + k) % 2:
                        rod(B(i, j, k), B(i, j + 1, k + 1), ea_bus, rho_tube)
                    else:
                        rod(B(i, j + 1, k), B(i, j, k + 1), ea_bus, rho_tube)

    def cube_nodes(i, j, k):
        return [B(i + di, j + dj, k + dk) for di in (0, 1) for dj in (0, 1) for dk in (0, 1)]

    def cell_nodes(i, j, k=NZ):
        return [B(i, j, k), B(i + 1, j, k), B(i + 1, j + 1, k), B(i, j + 1, k)]

    for (i, j, k), m in SUBSYSTEMS.values():
        for n in cube_nodes(i, j, k):
            node_mass[n] += m / 8
    for (i, j), m in BUS_INSTRUMENTS.values():
        for n in cell_nodes(i, j):
            node_mass[n] += m / 4

    # -- instrument stations -------------------------------------------------------------
    active: list = []
    legs: dict = {}  # name -> (bus node, payload node)
    for inst in INSTRUMENTS:
        if MOUNTS[inst] == "isolator":
            _misr_station(inst, stack, B, add_node, rod, springs, xyz, active, legs,
                          ISO3_SERIES_K if hybrid else None)
            continue
        i, j = STATIONS[inst]
        m = INSTRUMENT_MASS[inst]
        bus4 = cell_nodes(i, j)
        plate = [add_node(f"{inst}_p{c}", xyz[b] + (0, 0, MOUNT_HEIGHT),
                          PLATE_NODE_MASS + (1 - CG_FRACTION) * m / 4)
                 for c, b in enumerate(bus4)]
        centre = np.mean([xyz[p] for p in plate], axis=0)
        cg = add_node(f"{inst}_cg", centre + (0, 0, CG_HEIGHT), CG_FRACTION * m)
        ea_plate = PLATE_EA_FACTOR * E_AL * TUBE_AREA
        for c in range(4):
            rod(plate[c], plate[(c + 1) % 4], ea_plate, rho_tube)
            rod(plate[c], cg, ea_plate, rho_tube)
        rod(plate[0], plate[2], ea_plate, rho_tube)
        kind = MOUNTS[inst]
        if kind == "rigid":
            for c in range(4):
                rod(bus4[c], plate[c], E_AL * TUBE_AREA, rho_tube)
                rod(bus4[c], plate[(c + 1) % 4], E_AL * TUBE_AREA, rho_tube)
        elif kind == "kinematic":
            # bipods at plate corners 0, 1, 2: one vertical leg and one inclined leg in
            # the side plane; feet on the bus nodes under the plate
            feet = [(0, 0), (0, 1), (1, 1), (1, 2), (2, 2), (2, 3)]
            active_idx = (range(6) if active_legs == "all" else (1,)) \
                if inst in ("swir", "vnir") else ()
            for leg, (c, f) in enumerate(feet):
                if leg in active_idx:
                    name = f"{inst}_mount" + (f"{leg + 1}" if active_legs == "all" else "")
                    active.append(_stacked_leg(name, bus4[f], plate[c], stack, add_node,
                                               rod, springs, xyz, node_mass, inst))
                else:
                    rod(bus4[f], plate[c], E_AL * TUBE_AREA, rho_tube)
        else:  # isolator: the MISR station, built by _misr_station
            raise ModelError(f"station {inst!r}: mount {kind!r} is built by _misr_station")

    # -- solar array -------------------------------------------------------------------
    # yoke: four root nodes off the bus -y face, each pinned to three bus nodes
    xi, zk = ARRAY_ROOT
    yoke_ea = PLATE_EA_FACTOR * E_AL * TUBE_AREA
    zc = (zk + 0.5) * a
    root = []
    for c, (dx, dz) in enumerate(((0, -1), (2, -1), (2, 1), (0, 1))):
        r = add_node(f"sa_0_{c}", ((xi + dx) * a, -ARRAY_YOKE, zc + dz * ARRAY_DEPTH / 2))
        root.append(r)
        nx = xi + dx + (1 if dx == 0 else -1)
        for foot in (B(xi + dx, 0, zk), B(xi + dx, 0, zk + 1),
                     B(nx, 0, zk if dz < 0 else zk + 1)):
            rod(foot, r, yoke_ea, rho_tube)
    rod(root[0], root[2], yoke_ea, rho_tube)
    array_root = list(root)
    prev = root
    panel = ARRAY_PANEL_MASS / (4 * ARRAY_BAYS)
    for s in range(1, ARRAY_BAYS + 1):
        cur = [add_node(f"sa_{s}_{c}", xyz[r] + (0, -s * ARRAY_BAY, 0), panel)
               for c, r in enumerate(root)]
        _box_bay(prev, cur, ea_array, EA_BRACE, APPENDAGE_LINE_DENSITY, rod)
        prev = cur
    # -- high-gain antenna ---------------------------------------------------------------
    hi, hj = HGA_ROOT
    root = [B(hi, hj, 0), B(hi + 1, hj, 0), B(hi + 1, hj + 1, 0), B(hi, hj + 1, 0)]
    prev = root
    for s in range(1, HGA_BAYS + 1):
        cur = [add_node(f"hga_{s}_{c}", xyz[r] + (0, 0, -s * a), 0.0)
               for c, r in enumerate(root)]
        _box_bay(prev, cur, EA_HGA, EA_BRACE, APPENDAGE_LINE_DENSITY, rod)
        prev = cur
    dish = add_node("hga_dish", np.mean([xyz[p] for p in prev], axis=0)
                    + (0, 0, -HGA_DISH_OFFSET), HGA_DISH_MASS)
    for p in prev:
        rod(p, dish, EA_BRACE, APPENDAGE_LINE_DENSITY)

    nodes = np.array(xyz)
    node_mass = np.array(node_mass)
    springs_t = tuple(springs)
    if suspension:
        springs_t += _suspension(nodes, node_mass, np.array(el_mass), conn, names)
    active_t = tuple(ActiveMember(n, el, gauge, stack) for n, el, gauge in active)
    truss = Truss(nodes=nodes, elements=np.array(conn), axial_stiffness=np.array(k_ax),
                  element_mass=np.array(el_mass), node_mass=node_mass, active=active_t,
                  name="eos_testbed", mass_type=mass_type, node_names=names,
                  springs=springs_t)

    # -- channels ------------------------------------------------------------------------------
    loads = []
    for loc in LOCATIONS:
        if loc in STATIONS:  # through the mount: CG (MISR: gimbal pivot) + plate nodes
            set_ = [f"{loc}_cg"] + [f"{loc}_p{c}" for c in range(4)]
        elif loc in BUS_INSTRUMENTS:
            set_ = cell_nodes(*BUS_INSTRUMENTS[loc][0])
        elif loc == "rwa":
            set_ = cube_nodes(*SUBSYSTEMS["rwa"][0])
        else:  # sad: the array root
            set_ = array_root
        loads.extend(wrench_channels(truss, loc, set_))
    rwa = cube_nodes(*SUBSYSTEMS["rwa"][0])
    loads.extend(wrench_channels(truss, "acs", rwa, names=("tx", "ty", "tz"),
                                 components=(3, 4, 5)))
    outputs = []
    for inst in INSTRUMENTS:
        outputs.extend(truss.angle_channels(f"los_{inst}", payload_nodes(inst)))
    for leg, (b, p) in legs.items():
        d = nodes[p] - nodes[b]
        outputs.append(truss.accel_channel(f"acc_pay_{leg}", p, d))
        outputs.append(truss.accel_channel(f"acc_bus_{leg}", b, d))
    for am in active_t:
        outputs.append(truss.strain_channel(f"strain_{am.name}", am.gauge_element))
        outputs.append(truss.elong_channel(f"elong_{am.name}", am.element))
    acs = cube_nodes(*ACS_SENSOR_CUBE)
    att = truss.angle_channels("att", acs)
    outputs.extend(att)
    outputs.extend(Channel(c.name.replace("att_", "rate_"), "rate", c.dofs, c.weights)
                   for c in att)
    return truss.replace(loads=tuple(loads), outputs=tuple(outputs))


def payload_nodes(inst: str) -> list:
    """Nodes whose rigid rotation is the boresight of ``inst`` (``los_<inst>_*``).

    The MISR payload is gimballed: its boresight is the gimballed body (pivot ``misr_cg``
    and the six body nodes ``misr_g0..g5``), not the interface plate.  The other
    payloads are locked to their plate: CG node and plate nodes ``<inst>_p0..p3``.
    """
    if MOUNTS[inst] == "isolator":
        return [f"{inst}_cg"] + [f"{inst}_g{c}" for c in range(6)]
    return [f"{inst}_cg"] + [f"{inst}_p{c}" for c in range(4)]


def _misr_station(inst, stack, B, add_node, rod, springs, xyz, active, legs,
                  iso3_series_k=None):
    """The MISR isolator station: diamond of four vertical legs, gimballed payload.

    Legs (``MISR_FEET``): three P-845.37 stack legs ``iso1..3`` and one solid aluminium
    rod ``tube``, each from a nadir-face bus node to a plate node ``MOUNT_HEIGHT`` above
    it (``misr_p0..p3`` over iso1, iso2, iso3, tube).  iso1/iso2 sit on the roll axis
    of the plate (+-y), iso3 and the tube on its pitch axis (+-x), so one strut tilts the
    plate about one axis only.  Each leg end is held laterally (flexure) on the line of
    the bus post below its foot.  The plate (edges + the x diagonal) carries a pivot
    ``misr_cg`` ``CG_HEIGHT`` above its centre on four rods; the gimballed body is a rigid
    octahedron ``misr_g0..g5`` (+-x, +-y, +-z at ``GIMBAL_RADIUS``) around the pivot, free to
    rotate about it but for three springs: roll and pitch at ``gimbal_stiffness()`` (the
    8 Hz servo) and yaw at ``GIMBAL_YAW_FACTOR`` times that (no yaw axis).
    ``iso3_series_k`` (N/m): an elastomer stage in series in leg iso3 (hybrid mount #3).
    """
    m = INSTRUMENT_MASS[inst]
    order = ("iso1", "iso2", "iso3", "tube")
    feet = [B(*MISR_FEET[leg], NZ) for leg in order]
    plate = [add_node(f"{inst}_p{c}", xyz[f] + (0, 0, MOUNT_HEIGHT),
                      PLATE_NODE_MASS + (1 - CG_FRACTION) * m / 4)
             for c, f in enumerate(feet)]
    centre = np.mean([xyz[p] for p in plate], axis=0)
    ea_plate = PLATE_EA_FACTOR * E_AL * TUBE_AREA
    rho_tube = RHO_AL * TUBE_AREA
    pivot = add_node(f"{inst}_cg", centre + (0, 0, CG_HEIGHT), 0.0)
    for a_, b_ in ((0, 2), (2, 1), (1, 3), (3, 0), (2, 3)):
        rod(plate[a_], plate[b_], ea_plate, rho_tube)
    for p in plate:
        rod(p, pivot, ea_plate, rho_tube)
    # gimballed body: octahedron around the pivot, 60 % of the instrument mass
    r = GIMBAL_RADIUS
    offs = [(r, 0, 0), (-r, 0, 0), (0, r, 0), (0, -r, 0), (0, 0, r), (0, 0, -r)]
    body = [add_node(f"{inst}_g{c}", xyz[pivot] + np.array(o), CG_FRACTION * m / 6)
            for c, o in enumerate(offs)]
    for g in body:
        rod(pivot, g, ea_plate, rho_tube)
    for a_ in (0, 1):
        for b_ in (2, 3, 4, 5):
            rod(body[a_], body[b_], ea_plate, rho_tube)
    for a_ in (2, 3):
        for b_ in (4, 5):
            rod(body[a_], body[b_], ea_plate, rho_tube)
    # gimbal springs on (body rotation - plate rotation); u_z = th_x y - th_y x,
    # u_y = th_z x.  Plate: p0/p1 at -y/+y, p2/p3 at -x/+x, half-span a_p
    a_p = float(np.linalg.norm(xyz[plate[1]] - xyz[plate[0]])) / 2
    k_g = gimbal_stiffness(m)

    def dof(n, d):
        return 3 * n + d

    for name, k, (bp, bm, pp, pm, d, sgn) in (
            ("roll", k_g, (2, 3, 1, 0, 2, 1.0)),
            ("pitch", k_g, (0, 1, 3, 2, 2, -1.0)),
            ("yaw", GIMBAL_YAW_FACTOR * k_g, (0, 1, 3, 2, 1, 1.0))):
        dofs = np.array([dof(body[bp], d), dof(body[bm], d), dof(plate[pp], d),
                         dof(plate[pm], d)])
        w = sgn * np.array([1 / (2 * r), -1 / (2 * r), -1 / (2 * a_p), 1 / (2 * a_p)])
        springs.append(Spring(dofs, w, k))
    for c, leg in enumerate(order):
        fi, fj = MISR_FEET[leg]
        if leg == "tube":
            rod(feet[c], plate[c], E_AL * ROD_AREA, RHO_AL * ROD_AREA)
            k_lat = 12 * E_AL * ROD_I / MOUNT_HEIGHT**3
        else:
            active.append(_stacked_leg(leg, feet[c], plate[c], stack, add_node, rod,
                                       springs, xyz, None, inst,
                                       iso3_series_k if leg == "iso3" else None))
            k_lat = K_LAT_STACK_LEG
        legs[leg] = (feet[c], plate[c])
        springs.extend(transverse_link(np.array(xyz), B(fi, fj, NZ - 1), feet[c], plate[c],
                                       k_lat))


def gimbal_stiffness(mass: float | None = None) -> float:
    """Roll/pitch stiffness of the MISR gimbal servo (N m/rad): ``J (2 pi f_g)^2``.

    ``J`` is the gimballed body's inertia about the pivot (``CG_FRACTION`` of the
    instrument mass on six nodes at ``GIMBAL_RADIUS``: ``J = 4 (m / 6) r^2``) and
    ``f_g`` = ``GIMBAL_HZ`` (the paper's payloads point with about 8 Hz bandwidth).
    """
    m = INSTRUMENT_MASS["misr"] if mass is None else mass
    J = 4 * (CG_FRACTION * m / 6) * GIMBAL_RADIUS**2
    return J * (2 * np.pi * GIMBAL_HZ) ** 2


def _stacked_leg(name, n_bus, n_pay, stack, add_node, rod, springs, xyz, node_mass, inst,
                 k_series=None):
    """A leg made of a piezo stack (bus side) + fitting node + passive rod (payload side).

    ``k_series`` (N/m): a soft stage (elastomer) in series with the passive rod, lumped
    into the rod element (series stiffness of the two).  Returns ``(name, stack element,
    gauge element)``; the gauge is on the stack.
    """
    d = xyz[n_pay] - xyz[n_bus]
    length = float(np.linalg.norm(d))
    lp = stack.length
    fit = add_node(f"{inst}_fit_{name}", xyz[n_bus] + d / length * lp, FITTING_MASS)
    el = rod(n_bus, fit, stack.k_e * lp, stack.mass / lp)
    ls = length - lp
    ea = E_AL * ROD_AREA
    if k_series is not None:
        ea = ls / (ls / ea + 1.0 / k_series)
    rod(fit, n_pay, ea, RHO_AL * ROD_AREA)
    k = 3 * E_AL * ROD_I * length / (lp**2 * ls**2)
    springs.extend(transverse_link(np.array(xyz), n_bus, n_pay, fit, k))
    return name, el, el


def _box_bay(prev, cur, ea_long, ea_brace, line_density, rod):
    """One bay of a 4-longeron boom: longerons (``ea_long``), battens and face and
    batten-plane diagonals (``ea_brace``)."""
    for c in range(4):
        rod(prev[c], cur[c], ea_long, line_density)
        rod(cur[c], cur[(c + 1) % 4], ea_brace, line_density)
        rod(prev[c], cur[(c + 1) % 4], ea_brace, line_density)
    rod(cur[0], cur[2], ea_brace, line_density)


def _suspension(nodes, node_mass, el_mass, conn, names):
    """Five cables (pendulum springs) and vertical pneumatic springs to ground."""
    total = node_mass.sum() + el_mass.sum()
    points = [_bus_name(i, j, 0) for i, j in ((1, 0), (1, NY), (NX - 1, 0), (NX - 1, NY),
                                              (NX // 2, NY // 2))]
    k_pend = total * G0 / SUSPENSION_LENGTH / len(points)
    k_z = total * (2 * np.pi * SUSPENSION_BOUNCE_HZ) ** 2 / len(points)
    out = []
    for p in points:
        n = names[p]
        for d, k in ((0, k_pend), (1, k_pend), (2, k_z)):
            out.append(Spring(np.array([3 * n + d]), np.array([1.0]), k))
    return tuple(out)


# -- channels ----------------------------------------------------------------------------
def wrench_matrix(truss: Truss, nodes, point=None) -> np.ndarray:
    """Least-norm nodal forces giving a unit wrench at ``point``, shape (3 k, 6).

    Column ``c`` holds the forces (stacked x, y, z per node) whose resultant is the unit
    force (``c`` < 3) or unit moment (``c`` >= 3) about ``point`` (default the centroid)
    with the other five wrench components exactly zero.

    Parameters
    ----------
    truss : Truss
    nodes : sequence of int or str, length k
        Node set (at least three non-collinear nodes).
    point : array_like, shape (3,), optional
        Reference point (m).

    Returns
    -------
    ndarray, shape (3 k, 6)
        Column ``c``: the nodal forces (N) of a unit force (1 N, ``c`` < 3) or unit
        moment (1 N m, ``c`` >= 3).
    """
    idx = np.array([truss.node(n) for n in nodes])
    x = truss.nodes[idx]
    p = x.mean(axis=0) if point is None else np.asarray(point, float)
    r = x - p
    G = np.zeros((6, 3 * len(idx)))
    for i, ri in enumerate(r):
        G[:3, 3 * i:3 * i + 3] = np.eye(3)
        G[3:, 3 * i:3 * i + 3] = np.array([[0, -ri[2], ri[1]], [ri[2], 0, -ri[0]],
                                            [-ri[1], ri[0], 0]])
    if np.linalg.matrix_rank(G) < 6:
        raise ModelError("wrench node set is collinear; need three non-collinear nodes")
    return G.T @ np.linalg.inv(G @ G.T)


def wrench_channels(truss: Truss, prefix, nodes, point=None, names=WRENCH,
                    components=range(6)) -> tuple:
    """Load channels ``<prefix>_<name>`` applying unit wrench components on a node set.

    Forces (``fx, fy, fz``, N) and couples (``mx, my, mz``, N m) are spread over the
    nodes with :func:`wrench_matrix`, so each channel has exactly the one resultant.

    Parameters
    ----------
    truss : Truss
        Model whose nodes carry the loads.
    prefix : str
        Channel name prefix, e.g. the location (``"swir"``).
    nodes : sequence of int or str, length k
        Node set (at least three non-collinear nodes).
    point : array_like, shape (3,), optional
        Reference point of the moments (m); default the centroid of ``nodes``.
    names : sequence of str
        Channel name suffixes, paired in order with ``components``; default ``WRENCH``
        (``fx .. mz``).
    components : sequence of int
        Wrench components, 0-5 for ``fx, fy, fz, mx, my, mz``; default all six.

    Returns
    -------
    tuple of Channel
        One per ``(name, component)`` pair on the ``3 k`` DOFs of ``nodes``: kind
        ``"force"`` (N) for components 0-2, ``"torque"`` (N m) for 3-5.
    """
    W = wrench_matrix(truss, nodes, point)
    idx = np.array([truss.node(n) for n in nodes])
    dofs = (3 * idx[:, None] + np.arange(3)).ravel()
    kinds = ("force",) * 3 + ("torque",) * 3
    return tuple(Channel(f"{prefix}_{n}", kinds[c], dofs, W[:, c])
                 for n, c in zip(names, components))


def torque_channel(truss: Truss, name, nodes, axis) -> Channel:
    """A pure couple of 1 N m about ``axis`` spread over a node set (zero net force).

    Parameters
    ----------
    truss : Truss
        Model whose nodes carry the couple.
    name : str
        Channel name.
    nodes : sequence of int or str, length k
        Node set (at least three non-collinear nodes).
    axis : array_like, shape (3,)
        Axis of the couple (body axes); normalised here, so only its direction counts
        (must be non-zero).

    Returns
    -------
    Channel
        Kind ``"torque"`` (N m) on the ``3 k`` DOFs of ``nodes``.
    """
    W = wrench_matrix(truss, nodes)
    ax = np.asarray(axis, float)
    ax = ax / np.linalg.norm(ax)
    idx = np.array([truss.node(n) for n in nodes])
    return Channel(name, "torque", (3 * idx[:, None] + np.arange(3)).ravel(), W[:, 3:] @ ax)


# -- analysis helpers ------------------------------------------------------------------------
def _node_region(name: str) -> str:
    if name.startswith("bus_"):
        return "bus"
    if name.startswith("sa_"):
        return "array"
    if name.startswith("hga"):
        return "hga"
    inst = name.split("_")[0]
    if "_fit_" in name:
        return f"mount_{inst}"
    return f"payload_{inst}"


def element_regions(truss: Truss) -> np.ndarray:
    """Region of each element: ``bus``, ``array``, ``hga``, ``mount_<inst>``, ``payload_<inst>``.

    Returns
    -------
    ndarray of str, shape (n_el,)
    """
    node_reg = _node_regions(truss)
    out = []
    for n1, n2 in truss.elements:
        r1, r2 = node_reg[n1], node_reg[n2]
        if r1 == r2:
            out.append(r1)
        elif "array" in (r1, r2) or "hga" in (r1, r2):
            out.append("array" if "array" in (r1, r2) else "hga")
        else:  # bus to payload, fitting to either
            inst = (r1 if r1 != "bus" else r2).split("_", 1)[1]
            out.append(f"mount_{inst}")
    return np.array(out)


def _node_regions(truss):
    reg = np.empty(len(truss.nodes), object)
    for name, i in truss.node_names.items():
        reg[i] = _node_region(name)
    return reg


def strain_energy_fractions(truss: Truss, phi_full: np.ndarray) -> dict:
    """Fraction of each mode's strain energy per region.

    Parameters
    ----------
    truss : Truss
    phi_full : ndarray, shape (n_dof, n_modes)
        Mode shapes on all DOFs (free-free: the free DOFs are all DOFs).

    Returns
    -------
    dict of str to ndarray, shape (n_modes,)
        Keys: element regions (:func:`element_regions`); springs count with the mount
        they belong to, ground springs as ``suspension``.  The fractions of one mode sum
        to 1 (rigid-body modes give NaN).
    """
    e, _ = truss.element_geometry()
    el = truss.elements
    du = phi_full.reshape(len(truss.nodes), 3, -1)
    delta = np.einsum("ek,ekm->em", e, du[el[:, 1]] - du[el[:, 0]])
    U = 0.5 * truss.axial_stiffness[:, None] * delta**2
    regions = element_regions(truss)
    out = {r: U[regions == r].sum(axis=0) for r in np.unique(regions)}
    node_reg = _node_regions(truss)
    for s in truss.springs:
        regs = {node_reg[d // 3] for d in np.asarray(s.dofs)}
        if regs == {"bus"}:
            key = "bus" if len({d // 3 for d in s.dofs}) > 1 else "suspension"
        else:
            key = next(r for r in sorted(regs) if r != "bus")
            key = "mount_" + key.split("_", 1)[1] if "_" in key else key
        u = 0.5 * s.k * (np.asarray(s.weights) @ phi_full[np.asarray(s.dofs)]) ** 2
        out[key] = out.get(key, 0.0) + u
    total = sum(out.values())
    with np.errstate(invalid="ignore", divide="ignore"):
        return {k: v / total for k, v in out.items()}


def modes(truss: Truss, n: int = 40):
    """First ``n`` natural frequencies (Hz) and mode shapes on all DOFs.

    Parameters
    ----------
    truss : Truss
        Full model (e.g. :func:`build`).
    n : int
        Number of modes, lowest first, rigid-body modes included.

    Returns
    -------
    f : ndarray, shape (n,)
        Natural frequencies (Hz); 0 for rigid-body modes.
    phi : ndarray, shape (n_dof, n)
        Mass-normalised, zero on fixed DOFs.
    """
    K, M = assemble(truss)
    lam, phi, _ = eigenpairs(K, M, n, SHIFT, truss)
    full = np.zeros((truss.n_dof, n))
    full[truss.free_dofs] = phi
    return np.sqrt(lam) / (2 * np.pi), full


def frequencies_hz(truss: Truss | None = None, n: int = 12) -> np.ndarray:
    """First ``n`` natural frequencies of the full FEM (Hz), rigid-body modes included.

    Parameters
    ----------
    truss : Truss, optional
        Full model; default :func:`build` (built on each call).
    n : int
        Number of frequencies, lowest first.

    Returns
    -------
    ndarray, shape (n,)
        Natural frequencies (Hz); 0 for rigid-body modes.
    """
    return modes(truss or build(), n)[0]


def first_mode_of(region: str, truss: Truss | None = None, n: int = 60, threshold=0.5):
    """Index and frequency (Hz) of the first flexible mode with >= ``threshold`` of its
    strain energy in ``region`` (``"bus"`` or ``"array"``).

    Parameters
    ----------
    region : str
        A region key of :func:`strain_energy_fractions`: ``"bus"``, ``"array"``, ``"hga"``,
        ``"mount_<inst>"`` ...
    truss : Truss, optional
        Full model; default :func:`build`.
    n : int
        Number of lowest modes searched, rigid-body modes included.
    threshold : float
        Minimum fraction (0 to 1) of the mode's strain energy in ``region``.

    Returns
    -------
    index : int
        Index of the mode among the first ``n`` (0-based, rigid-body modes counted).
    f : float
        Its natural frequency (Hz).

    Raises
    ------
    ModelError
        If no flexible mode (above 1 mHz) among the first ``n`` qualifies.
    """
    f, phi = modes(truss or build(), n)
    frac = strain_energy_fractions(truss or build(), phi)[region]
    flexible = f > 1e-3
    hit = np.flatnonzero(flexible & (np.nan_to_num(frac) >= threshold))
    if not hit.size:
        raise ModelError(f"no mode among the first {n} has {threshold:.0%} of its strain "
                         f"energy in {region!r}")
    return int(hit[0]), float(f[hit[0]])


def describe_modes(truss: Truss | None = None, n: int = 12) -> list:
    """One line per mode: frequency and where the strain energy is.

    Parameters
    ----------
    truss : Truss, optional
        Full model; default :func:`build`.
    n : int
        Number of lowest modes described, rigid-body modes included.

    Returns
    -------
    list of str, length n
        ``"<mode number from 1> <f> Hz  <region> <share>, ..."``: the up to three regions
        with at least 5 % of the strain energy, largest first; ``rigid body`` below 1 mHz.
    """
    truss = truss or build()
    f, phi = modes(truss, n)
    frac = strain_energy_fractions(truss, phi)
    lines = []
    for m in range(n):
        if f[m] < 1e-3:
            lines.append(f"{m + 1:3d} {f[m]:9.4f} Hz  rigid body")
            continue
        parts = sorted(((v[m], k) for k, v in frac.items()), reverse=True)
        lines.append(f"{m + 1:3d} {f[m]:9.4f} Hz  " + ", ".join(
            f"{k} {v:.0%}" for v, k in parts[:3] if v >= 0.05))
    return lines


def damping(n_modes: int, truss: Truss | None = None) -> Damping:
    """Modal 0.5 % (0 on rigid modes since ``c = 2 zeta omega``), Ritz 2 %; with
    ``truss``, ``ZETA_GIMBAL`` on its MISR gimbal modes (:func:`gimbal_modes`) and, on
    every flexible mode, the elastomer's share by the modal strain energy method:
    ``ISO3_LOSS_FACTOR / 2`` times the mode's strain-energy fraction in the elastomer
    stage of a hybrid mount #3 (:func:`elastomer_fractions`; none in the default
    stiff build).

    Parameters
    ----------
    n_modes : int
        Number of eigenvectors of the reduced model, rigid-body modes included.
    truss : Truss, optional
        Full model the reduction is made from; without it, no gimbal or elastomer damping.

    Returns
    -------
    Damping
        ``zeta``, shape (n_modes,), the modal damping ratios; ``zeta_ritz`` = ``ZETA_RITZ``.
    """
    zeta = np.full(n_modes, ZETA)
    if truss is not None:
        zeta[gimbal_modes(truss, n_modes)] = ZETA_GIMBAL
        if _elastomer_elements(truss):
            f, phi = modes(truss, n_modes)
            flexible = f > 1e-3
            zeta[flexible] += (0.5 * ISO3_LOSS_FACTOR
                               * elastomer_fractions(truss, phi)[flexible])
    return Damping(zeta=zeta, zeta_ritz=ZETA_RITZ)


def _elastomer_elements(truss: Truss) -> list:
    """``(element, elastomer share of its strain energy)`` of the MISR stack legs whose
    passive part carries an elastomer stage (softer than the bare rod)."""
    _, length = truss.element_geometry()
    out = []
    for c, leg in enumerate(("iso1", "iso2", "iso3")):
        name = f"misr_fit_{leg}"
        if name not in truss.node_names:
            continue
        ends = {truss.node(name), truss.node(f"misr_p{c}")}
        for i, (n1, n2) in enumerate(truss.elements):
            if {int(n1), int(n2)} == ends:
                k_rod = E_AL * ROD_AREA / length[i]
                share = 1.0 - truss.axial_stiffness[i] / k_rod  # 1/k = 1/k_rod + 1/k_s
                if share > 1e-9:
                    out.append((i, float(share)))
    return out


def elastomer_fractions(truss: Truss, phi_full: np.ndarray) -> np.ndarray:
    """Fraction of each mode's strain energy in the elastomer stages of the MISR legs.

    The elastomer is lumped with its passive rod in one element (fitting to plate); its
    share of that element's energy is ``1 - k / k_rod`` (series springs carry one
    force).  Shape (n_modes,); zeros without a hybrid mount or without strain energy.

    Parameters
    ----------
    truss : Truss
        Full model (:func:`build`; only ``iso3="hybrid"`` has an elastomer stage).
    phi_full : ndarray, shape (n_dof, n_modes)
        Mode shapes on all DOFs (:func:`modes`).

    Returns
    -------
    ndarray, shape (n_modes,)
        Fraction of each mode's strain energy in the elastomer stages.
    """
    e, _ = truss.element_geometry()
    du = phi_full.reshape(len(truss.nodes), 3, -1)
    out = np.zeros(phi_full.shape[1])
    total = 0.5 * np.einsum("im,im->m", phi_full, _stiffness(truss) @ phi_full)
    for i, share in _elastomer_elements(truss):
        n1, n2 = truss.elements[i]
        d = e[i] @ (du[n2] - du[n1])
        out += share * 0.5 * truss.axial_stiffness[i] * d**2
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.nan_to_num(np.where(total > 0, out / total, 0.0))


def gimbal_modes(truss: Truss, n_modes: int = N_MODES, threshold: float = 0.5) -> np.ndarray:
    """Indices of the modes with >= ``threshold`` of their strain energy in the MISR gimbal.

    The gimbal servo is modelled as springs between the gimballed body and its plate
    (:func:`_misr_station`); its two modes (roll, pitch, near ``GIMBAL_HZ``) get the
    servo's damping ``ZETA_GIMBAL`` instead of the structural 0.5 %.

    Parameters
    ----------
    truss : Truss
        Full model with the MISR gimbal (nodes ``misr_g0..g5``, as :func:`build`).
    n_modes : int
        Number of lowest modes examined, rigid-body modes included.
    threshold : float
        Minimum fraction (0 to 1) of a mode's strain energy in the springs attached to
        the gimballed body.

    Returns
    -------
    ndarray of int
        Indices (0-based, among the first ``n_modes``) of the gimbal modes; only flexible
        modes below ``2 GIMBAL_HZ`` (16 Hz) qualify.
    """
    f, phi = modes(truss, n_modes)
    body = {truss.node(f"misr_g{c}") for c in range(6)}
    u_gim = np.zeros(n_modes)
    u_all = 0.5 * np.einsum("im,im->m", phi, _stiffness(truss) @ phi)
    for s in truss.springs:
        if {int(d) // 3 for d in s.dofs} & body:
            u_gim += 0.5 * s.k * (np.asarray(s.weights) @ phi[np.asarray(s.dofs)]) ** 2
    servo = (f > 1e-3) & (f < 2 * GIMBAL_HZ)  # the stiff yaw spring is not the servo
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.where(servo, u_gim / u_all, 0.0)
    return np.flatnonzero(frac >= threshold)


def _stiffness(truss: Truss):
    return assemble(truss)[0]


def load_inputs() -> tuple:
    """Names of the disturbance wrench inputs ``<loc>_fx .. <loc>_mz``, shape (54,)."""
    return tuple(f"{loc}_{c}" for loc in LOCATIONS for c in WRENCH)


def reduced(n_modes: int = N_MODES, ritz: bool = True, truss: Truss | None = None,
            ritz_loads=None, shift: float = SHIFT):
    """Reduced model: eigenvectors to about 150 Hz plus static Ritz vectors.

    Parameters
    ----------
    n_modes : int
        Eigenvectors kept, rigid-body modes included (default ``N_MODES`` = 70, to
        158 Hz).
    ritz : bool
        Append static Ritz vectors (Eq. 3-7): one per active member and one per input in
        ``ritz_loads``.
    truss : Truss, optional
        Full model (default :func:`build`).
    ritz_loads : sequence of str, optional
        Load inputs that also get a Ritz vector; default all 54 disturbance wrench
        inputs (:func:`load_inputs`), ``()`` for the actuators only.  The ACS torques
        are the ``rwa_m*`` couples, so they are covered too.
    shift : float
        Shift of the free-free eigen and static solves ((rad/s)^2), default -100.

    Returns
    -------
    ReducedModel
        70 modes + 59 Ritz vectors by default; inputs and outputs as :func:`build`;
        accelerometer outputs through ``ACCEL_LOWPASS``.
    """
    truss = truss or build()
    loads = load_inputs() if ritz_loads is None else tuple(ritz_loads)
    sel = [c.name for c in truss.input_channels if c.name.startswith("fc_")] + list(loads)
    model = reduce(truss, n_modes, ritz=ritz, ritz_inputs=sel if ritz else None,
                   shift=shift, damping=damping(n_modes, truss))
    return replace(model, accel_lowpass=ACCEL_LOWPASS)


def calibrate(target_bus=TARGET_BUS_HZ, target_array=TARGET_ARRAY_HZ, tol=1e-4,
              max_iter=20, iso3: str = "stiff"):
    """Solve ``(eta_bus, ea_array)`` for the first bus and array modes (Hz).

    A fixed-point iteration on ``f ~ sqrt(stiffness)`` for each subsystem.

    Parameters
    ----------
    target_bus : float
        First bus mode to reach (Hz); default ``TARGET_BUS_HZ`` = 23.
    target_array : float
        First array mode to reach (Hz); default ``TARGET_ARRAY_HZ`` = 0.5.
    tol : float
        Relative tolerance on both frequencies.
    max_iter : int
        Maximum number of iterations; the last values are returned, without an error,
        if they have not converged by then.
    iso3 : {"stiff", "hybrid"}
        MISR mount #3 as in :func:`build`; the iteration starts from that build's stored
        constants (``ETA_BUS``, ``EA_ARRAY`` or their ``_HYBRID`` versions).

    Returns
    -------
    (eta_bus, ea_array) : tuple of float
        Bus EA knock-down (dimensionless) and array longeron ``EA`` (N), for :func:`build`.
    """
    eta, ea = (ETA_BUS_HYBRID, EA_ARRAY_HYBRID) if iso3 == "hybrid" else (ETA_BUS, EA_ARRAY)
    for _ in range(max_iter):
        t = build(eta, ea, iso3=iso3)
        _, fb = first_mode_of("bus", t)
        _, fa = first_mode_of("array", t)
        eta *= (target_bus / fb) ** 2
        ea *= (target_array / fa) ** 2
        if abs(fb / target_bus - 1) < tol and abs(fa / target_array - 1) < tol:
            break
    return float(eta), float(ea)
