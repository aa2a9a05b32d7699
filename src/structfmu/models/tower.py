"""Generated 3-D lattice truss towers of any size, for tests and benchmarks.

A tower stands on the plane ``z = 0`` (all its nodes fixed) and rises ``n_bays``
cubic bays of side ``bay``.  Every plane ``z = k * bay`` holds an ``nx`` x ``ny``
grid of nodes ``(i * bay, j * bay, k * bay)``, numbered ``k * nx * ny + j * nx + i``.

Members (every face of every cubic cell carries exactly one diagonal):

==================  =====================================================  ==========
longerons           ``(i, j, k)`` - ``(i, j, k + 1)``                       nx ny
battens             ``(i, j, k)`` - ``(i + 1, j, k)`` and ``(i, j + 1, k)`` (nx-1) ny +
                    in the planes ``k >= 1``                               nx (ny-1)
plane diagonals     ``(i, j, k)`` - ``(i + 1, j + 1, k)``, planes ``k >= 1``  (nx-1)(ny-1)
face diagonals      ``(i, j, k)`` - ``(i + 1, j, k + 1)`` and                (nx-1) ny +
                    ``(i, j, k)`` - ``(i, j + 1, k + 1)``                   nx (ny-1)
==================  =====================================================  ==========

(counts per bay).  No mechanism: each cubic cell is a convex polyhedron whose faces
are all triangulated, hence rigid (Cauchy-Dehn); neighbouring cells share a face, i.e.
three non-collinear nodes, so the whole lattice is rigid, and the fixed base removes
the rigid-body motion.  ``tests/structfmu/test_tower.py`` checks ``K`` is positive
definite.

Active members: up to four piezo stacks replace the corner longerons of the first bay
(the most effective place for bending).  As in :mod:`structfmu.models.truss10`, each
is the stack (``k_e``, stack mass) from the base node to a fitting node ``stack_length``
up the member, then a passive strut carrying the strain gauge to the first batten
plane; two transverse springs ``3 EI L / (a^2 b^2)`` (the tube's bending stiffness)
hold the fitting node on the member's line.  Hence

    n_free_dof = 3 * (nx * ny * n_bays + n_active).

Euler-Bernoulli equivalent (used by the test of the first bending frequency): the
longerons carry the bending moment, so bending that deflects the tower along x has

    EI_y = EA * sum over longerons of (x_i - x_mean)^2 = EA * bay^2 * ny * nx (nx^2 - 1) / 12

with ``EA`` the longeron's axial stiffness times length, and the mass per unit length
is ``mu = (nx * ny * node_mass + mass of the members of one bay) / bay``.  The
diagonals give the shear stiffness, which only matters for stubby towers (the
Timoshenko correction scales like ``(width / height)^2``).

Inputs: ``f_tip_x``, ``f_tip_y`` (N) at the top corner node ``(0, 0, n_bays)`` and
``fc_<name>`` (N) per active member.  Outputs: ``los_tip_roll/pitch/yaw`` (rad) of the
four top corner nodes, ``strain_<name>`` (gauge strains), ``acc_tip_x``/``acc_tip_y``
(m/s^2).

Everything is built with numpy index arithmetic (no Python loop over members): a
100 000-DOF tower builds in well under a second.
"""

from __future__ import annotations

import numpy as np

from fmukit.units import INCH

from piezofmu import preset
from structfmu.errors import ModelError
from structfmu.fem import ActiveMember, Truss, transverse_link

BAY = 0.5  # m
E_AL = 70e9  # Pa
RHO_AL = 2700.0  # kg/m^3
TUBE_OD, TUBE_ID = 1.0 * INCH, 0.0221  # m: 1.0 in tube, 0.065 in wall
TUBE_AREA = np.pi / 4 * (TUBE_OD**2 - TUBE_ID**2)  # m^2
TUBE_I = np.pi / 64 * (TUBE_OD**4 - TUBE_ID**4)  # m^4
NODE_MASS = 0.15  # kg
FITTING_MASS = 0.20  # kg
STACK = "P-243.30"
STACK_LENGTH = 0.10  # m, stack plus its fittings, from the base node
ACTIVE_NAMES = ("a1", "a2", "a3", "a4")


def n_free_dofs(n_bays: int, nx: int = 4, ny: int = 4, n_active: int = 4) -> int:
    """Number of free DOFs of :func:`build` (3 per non-base node and fitting node).

    Parameters
    ----------
    n_bays : int
        Number of bays.
    nx, ny : int
        Nodes per plane along x and y.
    n_active : int
        Number of active members (0 to 4), each adding one fitting node.

    Returns
    -------
    int
        ``3 * (nx * ny * n_bays + n_active)``.
    """
    return 3 * (nx * ny * n_bays + n_active)


def bays_for(n_dof: int, nx: int = 4, ny: int = 4, n_active: int = 4) -> int:
    """Smallest number of bays whose tower has at least ``n_dof`` free DOFs.

    Parameters
    ----------
    n_dof : int
        Wanted number of free DOFs.
    nx, ny : int
        Nodes per plane along x and y.
    n_active : int
        Number of active members (0 to 4), each adding one fitting node.

    Returns
    -------
    int
        Number of bays, at least 1.
    """
    per_bay = 3 * nx * ny
    return max(1, -(-(n_dof - 3 * n_active) // per_bay))


def members(nx: int, ny: int, n_bays: int) -> dict:
    """Member end nodes of the lattice by family, each an int array of shape (n, 2).

    Parameters
    ----------
    nx, ny : int
        Nodes per plane along x and y (at least 2 each).
    n_bays : int
        Number of bays (at least 1).

    Returns
    -------
    dict of str to ndarray of int, shape (n_members, 2)
        ``"longeron"``, ``"batten"``, ``"plane_diagonal"``, ``"face_diagonal"``.
        Longerons come first in bay order, the first bay's row-major ``(j, i)``.
    """
    per_plane = nx * ny
    grid = np.arange(per_plane).reshape(ny, nx)  # grid[j, i]
    base_planes = per_plane * np.arange(n_bays)[:, None]  # bays 0..n-1 (lower plane)
    top_planes = base_planes + per_plane  # planes 1..n

    def pairs(a, b, offset_a, offset_b):
        a, b = a.ravel(), b.ravel()
        return np.stack([(offset_a + a).ravel(), (offset_b + b).ravel()], axis=-1)

    long_ = pairs(grid, grid, base_planes, top_planes)
    batten = np.concatenate([pairs(grid[:, :-1], grid[:, 1:], top_planes, top_planes),
                             pairs(grid[:-1, :], grid[1:, :], top_planes, top_planes)])
    plane_diag = pairs(grid[:-1, :-1], grid[1:, 1:], top_planes, top_planes)
    face_diag = np.concatenate([pairs(grid[:, :-1], grid[:, 1:], base_planes, top_planes),
                                pairs(grid[:-1, :], grid[1:, :], base_planes, top_planes)])
    return {"longeron": long_, "batten": batten, "plane_diagonal": plane_diag,
            "face_diagonal": face_diag}


def build(n_bays: int, nx: int = 4, ny: int = 4, *, n_active: int = 4, bay: float = BAY,
          stack: str = STACK, mass_type: str = "consistent") -> Truss:
    """A lattice truss tower with piezo active members in its first bay.

    Parameters
    ----------
    n_bays : int
        Number of cubic bays above the fixed base plane (at least 1).
    nx, ny : int
        Nodes per plane along x and y (at least 2 each).
    n_active : int
        Number of corner longerons of the first bay replaced by piezo active members
        (0 to 4), named ``a1`` ... ``a4``.
    bay : float
        Bay side (m).
    stack : str
        Piezo stack preset of the active members (see :func:`piezofmu.preset`).
    mass_type : {"consistent", "lumped"}
        Member mass matrix.

    Returns
    -------
    Truss
        ``3 * (nx * ny * n_bays + n_active)`` free DOFs; inputs ``f_tip_x``,
        ``f_tip_y``, ``fc_a1`` ...; outputs ``strain_a1`` ..., ``acc_tip_x``,
        ``acc_tip_y``, ``los_tip_roll/pitch/yaw``.

    Raises
    ------
    ModelError
        If a size is out of range.
    """
    n_bays, nx, ny, n_active = int(n_bays), int(nx), int(ny), int(n_active)
    if n_bays < 1 or nx < 2 or ny < 2:
        raise ModelError(f"tower of {n_bays} bays with {nx} x {ny} nodes per plane; expected "
                         "at least 1 bay and 2 x 2 nodes per plane")
    if not 0 <= n_active <= 4:
        raise ModelError(f"tower: n_active = {n_active}; expected 0 to 4 (the corner "
                         "longerons of the first bay)")
    per_plane = nx * ny
    n_grid = per_plane * (n_bays + 1)
    k, in_plane = np.divmod(np.arange(n_grid), per_plane)
    j, i = np.divmod(in_plane, nx)
    xyz = bay * np.column_stack([i, j, k]).astype(float)

    fam = members(nx, ny, n_bays)
    conn = np.concatenate(list(fam.values()))
    length = np.linalg.norm(xyz[conn[:, 1]] - xyz[conn[:, 0]], axis=1)
    k_ax = E_AL * TUBE_AREA / length
    mass = RHO_AL * TUBE_AREA * length
    node_mass = np.full(n_grid, NODE_MASS)

    # active members: corner longerons of bay 0 (longeron index = grid index there)
    corners = [0, nx - 1, per_plane - nx, per_plane - 1][:n_active]
    st = preset(stack)
    lp = STACK_LENGTH
    if n_active and lp >= bay:
        raise ModelError(f"tower: bay {bay} m is shorter than the active member's stack "
                         f"({lp} m)")
    fit = n_grid + np.arange(n_active)
    xyz = np.vstack([xyz, xyz[corners] + [0.0, 0.0, lp]])
    node_mass = np.r_[node_mass, np.full(n_active, FITTING_MASS)]
    strut = np.column_stack([fit, np.asarray(corners, int) + per_plane]).reshape(-1, 2)
    conn = conn.copy()
    conn[corners, 1] = fit  # the longeron becomes the stack: base node -> fitting
    k_ax[corners] = st.k_e
    mass[corners] = st.mass
    ls = bay - lp
    gauge = len(conn) + np.arange(n_active)
    conn = np.vstack([conn, strut])
    k_ax = np.r_[k_ax, np.full(n_active, E_AL * TUBE_AREA / ls)]
    mass = np.r_[mass, np.full(n_active, RHO_AL * TUBE_AREA * ls)]
    k_link = 3 * E_AL * TUBE_I * bay / (lp**2 * ls**2)
    springs = tuple(s for c, f in zip(corners, fit)
                    for s in transverse_link(xyz, c, c + per_plane, f, k_link))
    active = tuple(ActiveMember(ACTIVE_NAMES[m], int(corners[m]), int(gauge[m]), st)
                   for m in range(n_active))

    top = per_plane * n_bays
    top_corners = [top, top + nx - 1, top + per_plane - nx, top + per_plane - 1]
    names = {"tip": top, **{f"fit_{a.name}": int(f) for a, f in zip(active, fit)}}
    truss = Truss(nodes=xyz, elements=conn, axial_stiffness=k_ax, element_mass=mass,
                  node_mass=node_mass, fixed_dofs=np.arange(3 * per_plane), active=active,
                  name=f"tower_{nx}x{ny}x{n_bays}", mass_type=mass_type, node_names=names,
                  springs=springs)
    loads = (truss.force_channel("f_tip_x", "tip", (1, 0, 0)),
             truss.force_channel("f_tip_y", "tip", (0, 1, 0)))
    outputs = (*(truss.strain_channel(f"strain_{a.name}", a.gauge_element) for a in active),
               truss.accel_channel("acc_tip_x", "tip", (1, 0, 0)),
               truss.accel_channel("acc_tip_y", "tip", (0, 1, 0)),
               *truss.angle_channels("los_tip", top_corners))
    return truss.replace(loads=loads, outputs=outputs)


def equivalent_beam(nx: int, ny: int, n_bays: int, bay: float = BAY) -> dict:
    """Euler-Bernoulli beam equivalent to the passive lattice (see the module docstring).

    Parameters
    ----------
    nx, ny, n_bays : int
        Tower size as in :func:`build`.
    bay : float
        Bay side (m).

    Returns
    -------
    dict
        ``EI_y`` (N m^2, bending that deflects along x), ``EI_x`` (N m^2, along y),
        ``mu`` (kg/m, mass per unit length) and ``length`` (m).
    """
    EA = E_AL * TUBE_AREA
    col = bay * (np.arange(nx) - (nx - 1) / 2)
    row = bay * (np.arange(ny) - (ny - 1) / 2)
    fam = members(nx, ny, 1)
    n_diag = len(fam["face_diagonal"]) + len(fam["plane_diagonal"])
    n_straight = len(fam["longeron"]) + len(fam["batten"])
    bay_member_length = bay * (n_straight + np.sqrt(2) * n_diag)
    mu = (nx * ny * NODE_MASS + RHO_AL * TUBE_AREA * bay_member_length) / bay
    return {"EI_y": EA * ny * float(np.sum(col**2)), "EI_x": EA * nx * float(np.sum(row**2)),
            "mu": mu, "length": n_bays * bay}
