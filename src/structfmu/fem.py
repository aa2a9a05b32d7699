"""3-D pin-jointed truss finite elements with embedded piezo active members.

A :class:`Truss` holds nodes, rod elements, lumped node masses, fixed DOFs, the
embedded active members of the paper's Eq. (1), and the named load channels and
output sensors (Eq. 2b).  :func:`assemble` builds sparse stiffness and mass matrices
on the free DOFs; no dense ``n x n`` matrix is formed.

Active members follow Eq. (1): the piezo stack is a rod of axial stiffness
``k_e = k^d - c h^2`` whose structural mass ``m`` is kept in the structure (lumped or
consistent like any rod; the paper's ``m_e = m/6`` is the consistent-mass coupling
term), driven by ``f_c = c h v`` applied as equal and opposite forces at its end nodes.
A strain gauge in series with the stack is modelled as a separate passive strut element
(the rest of the member) so that the gauge strain is a pure displacement output.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp

from structfmu.errors import DimensionError, ModelError

OUTPUT_KINDS = ("disp", "strain", "elong", "angle", "rate", "accel")
UNITS = {"disp": "m", "strain": "1", "elong": "m", "angle": "rad", "rate": "rad/s",
         "accel": "m/s2",
         "force": "N", "torque": "N.m"}


@dataclass(frozen=True)
class ActiveMember:
    """An embedded piezo active member (Eq. 1).

    Parameters
    ----------
    name : str
        Channel name, e.g. ``"diag"``; the input is ``fc_<name>`` (N).
    element : int
        Index of the rod element that represents the piezo stack.
    gauge_element : int or None
        Index of the passive strut element in series carrying the strain gauge.
    stack : object
        The :class:`piezofmu.PiezoStack` datasheet.
    """

    name: str
    element: int
    gauge_element: int | None
    stack: object


@dataclass(frozen=True)
class Channel:
    """A named load channel or sensor: a sparse row over all DOFs.

    Parameters
    ----------
    name : str
        Variable name in the FMU (e.g. ``"strain_diag"``, ``"los_tip_roll"``).
    kind : str
        ``"force"``/``"torque"`` for loads; one of ``OUTPUT_KINDS`` for outputs.
    dofs : ndarray of int, shape (k,)
        Global DOF indices (node * 3 + direction).
    weights : ndarray of float, shape (k,)
        Weights on those DOFs.
    """

    name: str
    kind: str
    dofs: np.ndarray
    weights: np.ndarray

    @property
    def unit(self) -> str:
        return UNITS[self.kind]


@dataclass(frozen=True)
class Spring:
    """A scalar spring of stiffness ``k`` on the DOF combination ``w^T u``.

    Parameters
    ----------
    dofs : ndarray of int, shape (k,)
        Global DOF indices.
    weights : ndarray, shape (k,)
        Weights ``w``.
    k : float
        Stiffness (N/m).
    """

    dofs: np.ndarray
    weights: np.ndarray
    k: float


def transverse_link(truss_nodes, n1, n2, mid, k) -> tuple:
    """Two springs holding node ``mid`` on the line ``n1``-``n2`` transversally.

    The springs act on the transverse part of ``u_mid - (1-s) u_1 - s u_2`` (``s`` the
    position of ``mid`` on the line), like the bending stiffness of the member.

    Parameters
    ----------
    truss_nodes : array_like, shape (n_nodes, 3)
        Node coordinates (m).
    n1, n2 : int
        Indices of the nodes that define the line.
    mid : int
        Index of the node held on the line.
    k : float
        Stiffness of each spring (N/m).

    Returns
    -------
    tuple of two Spring
        One spring per transverse direction.
    """
    p1, p2, pm = (np.asarray(truss_nodes[i], float) for i in (n1, n2, mid))
    d = p2 - p1
    length = np.linalg.norm(d)
    e = d / length
    s = float(np.dot(pm - p1, e) / length)
    helper = np.eye(3)[np.argmin(np.abs(e))]
    t1 = np.cross(e, helper)
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(e, t1)
    dofs = np.r_[3 * mid + np.arange(3), 3 * n1 + np.arange(3), 3 * n2 + np.arange(3)]
    return tuple(Spring(dofs, np.r_[t, -(1 - s) * t, -s * t], k) for t in (t1, t2))


@dataclass(frozen=True)
class Truss:
    """A pin-jointed truss.

    Parameters
    ----------
    nodes : ndarray, shape (n_nodes, 3)
        Node coordinates (m).
    elements : ndarray of int, shape (n_el, 2)
        End node indices of each rod.
    axial_stiffness : ndarray, shape (n_el,)
        ``EA / L`` of each rod (N/m).
    element_mass : ndarray, shape (n_el,)
        Structural mass of each rod (kg).
    node_mass : ndarray, shape (n_nodes,)
        Lumped non-structural mass at each node (kg): node balls, payload bars.
    fixed_dofs : ndarray of int
        Global DOF indices held at zero.
    active : tuple of ActiveMember
        Embedded piezo members.
    loads : tuple of Channel
        Named external load channels (inputs besides the actuators).
    outputs : tuple of Channel
        Named sensors (LOS angles, strains, elongations, accelerations).
    springs : tuple of Spring
        Scalar springs ``k (w^T u)^2`` on combinations of DOFs (suspension springs,
        transverse stiffness of inline fittings).
    name : str
        Model name.
    mass_type : {"consistent", "lumped"}
        Rod mass matrix.
    """

    nodes: np.ndarray
    elements: np.ndarray
    axial_stiffness: np.ndarray
    element_mass: np.ndarray
    node_mass: np.ndarray
    fixed_dofs: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    active: tuple = ()
    loads: tuple = ()
    outputs: tuple = ()
    name: str = "truss"
    mass_type: str = "consistent"
    node_names: dict = field(default_factory=dict)
    springs: tuple = ()

    def __post_init__(self):
        nodes = np.asarray(self.nodes, float)
        if nodes.ndim != 2 or nodes.shape[1] != 3:
            raise DimensionError(f"truss {self.name!r}: nodes has shape {nodes.shape}; "
                                 "expected (n_nodes, 3)")
        n_nodes = len(nodes)
        el = np.asarray(self.elements, int).reshape(-1, 2)
        n_el = len(el)
        if n_el and (el.min() < 0 or el.max() >= n_nodes):
            bad = int(el[(el < 0) | (el >= n_nodes)][0])
            raise ModelError(f"truss {self.name!r}: element refers to unknown node {bad}; "
                             f"nodes are 0..{n_nodes - 1}")
        if n_el and np.any(el[:, 0] == el[:, 1]):
            raise ModelError(f"truss {self.name!r}: element "
                             f"{int(np.flatnonzero(el[:, 0] == el[:, 1])[0])} joins a node to "
                             "itself")
        for attr, n in (("axial_stiffness", n_el), ("element_mass", n_el),
                        ("node_mass", n_nodes)):
            arr = np.asarray(getattr(self, attr), float)
            if arr.shape != (n,):
                raise DimensionError(f"truss {self.name!r}: {attr} has shape {arr.shape}; "
                                     f"expected ({n},)")
            if not np.all(np.isfinite(arr)):
                raise ModelError(f"truss {self.name!r}: {attr} has non-finite values")
            object.__setattr__(self, attr, arr)
        if np.any(self.axial_stiffness <= 0):
            raise ModelError(f"truss {self.name!r}: axial stiffness must be positive "
                             f"(element {int(np.argmin(self.axial_stiffness))})")
        if np.any(self.element_mass < 0) or np.any(self.node_mass < 0):
            raise ModelError(f"truss {self.name!r}: masses must be non-negative")
        if self.mass_type not in ("consistent", "lumped"):
            raise ModelError(f"truss {self.name!r}: mass_type {self.mass_type!r}; expected "
                             "'consistent' or 'lumped'")
        fixed = np.unique(np.asarray(self.fixed_dofs, int))
        if fixed.size and (fixed.min() < 0 or fixed.max() >= 3 * n_nodes):
            raise ModelError(f"truss {self.name!r}: fixed DOF out of range 0..{3 * n_nodes - 1}")
        lengths = np.linalg.norm(nodes[el[:, 1]] - nodes[el[:, 0]], axis=1) if n_el else []
        if n_el and np.any(np.asarray(lengths) <= 0):
            raise ModelError(f"truss {self.name!r}: element with zero length")
        for a in self.active:
            for idx in (a.element, a.gauge_element):
                if idx is not None and not 0 <= idx < n_el:
                    raise ModelError(f"active member {a.name!r}: unknown element {idx}; "
                                     f"elements are 0..{n_el - 1}")
        names = [c.name for c in self.loads] + [f"fc_{a.name}" for a in self.active]
        onames = [c.name for c in self.outputs]
        for group in (names, onames):
            dup = {n for n in group if group.count(n) > 1}
            if dup:
                raise ModelError(f"truss {self.name!r}: duplicate channel names {sorted(dup)}")
        for c in (*self.loads, *self.outputs):
            if np.any(np.asarray(c.dofs) >= 3 * n_nodes) or np.any(np.asarray(c.dofs) < 0):
                raise ModelError(f"channel {c.name!r}: DOF out of range")
        object.__setattr__(self, "nodes", nodes)
        object.__setattr__(self, "elements", el)
        object.__setattr__(self, "fixed_dofs", fixed)

    # -- bookkeeping -------------------------------------------------------------------
    @property
    def n_dof(self) -> int:
        """Number of DOFs before constraints."""
        return 3 * len(self.nodes)

    @property
    def free_dofs(self) -> np.ndarray:
        """Indices of the unconstrained DOFs."""
        mask = np.ones(self.n_dof, bool)
        mask[self.fixed_dofs] = False
        return np.flatnonzero(mask)

    def node(self, name_or_index) -> int:
        """Index of a node given its name or index."""
        if isinstance(name_or_index, (int, np.integer)):
            if not 0 <= name_or_index < len(self.nodes):
                raise ModelError(f"truss {self.name!r}: unknown node {name_or_index}; "
                                 f"nodes are 0..{len(self.nodes) - 1}")
            return int(name_or_index)
        if name_or_index not in self.node_names:
            close = difflib.get_close_matches(str(name_or_index), self.node_names, 3)
            hint = f"; did you mean {', '.join(close)}?" if close else ""
            raise ModelError(f"truss {self.name!r}: unknown node {name_or_index!r}{hint}")
        return self.node_names[name_or_index]

    def element_geometry(self):
        """Unit direction vectors (n_el, 3) and lengths (n_el,) of the elements."""
        d = self.nodes[self.elements[:, 1]] - self.nodes[self.elements[:, 0]]
        length = np.linalg.norm(d, axis=1)
        return d / length[:, None], length

    def element_row(self, element: int) -> Channel:
        """Elongation of one element as a DOF row (m per m of DOF)."""
        e, _ = self.element_geometry()
        n1, n2 = self.elements[element]
        dofs = np.r_[3 * n1 + np.arange(3), 3 * n2 + np.arange(3)]
        return Channel(f"elong_{element}", "elong", dofs, np.r_[-e[element], e[element]])

    @property
    def input_channels(self) -> tuple:
        """Load channels followed by one ``fc_<name>`` channel per active member."""
        acts = []
        for a in self.active:
            row = self.element_row(a.element)
            acts.append(Channel(f"fc_{a.name}", "force", row.dofs, row.weights))
        return tuple(self.loads) + tuple(acts)

    def replace(self, **changes) -> "Truss":
        """Copy with some fields changed."""
        return replace(self, **changes)

    # -- channel constructors (return Channel; add them with replace) --------------------
    def force_channel(self, name, node, direction) -> Channel:
        """A point force at a node along a direction vector (N).

        Parameters
        ----------
        name : str
            Channel name.
        node : int or str
            Node index or name.
        direction : array_like, shape (3,)
            Direction vector in model axes; normalised here.

        Returns
        -------
        Channel
            Load channel of kind ``"force"``.
        """
        n = self.node(node)
        d = np.asarray(direction, float)
        d = d / np.linalg.norm(d)
        return Channel(name, "force", 3 * n + np.arange(3), d)

    def accel_channel(self, name, node, direction) -> Channel:
        """Translational acceleration of a node along a direction (m/s^2).

        Parameters
        ----------
        name : str
            Channel name.
        node : int or str
            Node index or name.
        direction : array_like, shape (3,)
            Direction vector in model axes; normalised here.

        Returns
        -------
        Channel
            Output channel of kind ``"accel"``.
        """
        c = self.force_channel(name, node, direction)
        return Channel(name, "accel", c.dofs, c.weights)

    def disp_channel(self, name, node, direction) -> Channel:
        """Translation of a node along a direction (m).

        Parameters
        ----------
        name : str
            Channel name.
        node : int or str
            Node index or name.
        direction : array_like, shape (3,)
            Direction vector in model axes; normalised here.

        Returns
        -------
        Channel
            Output channel of kind ``"disp"``.
        """
        c = self.force_channel(name, node, direction)
        return Channel(name, "disp", c.dofs, c.weights)

    def strain_channel(self, name, element) -> Channel:
        """Axial strain of an element (elongation / length).

        Parameters
        ----------
        name : str
            Channel name.
        element : int
            Element index.

        Returns
        -------
        Channel
            Output channel of kind ``"strain"`` (dimensionless).
        """
        row = self.element_row(element)
        _, length = self.element_geometry()
        return Channel(name, "strain", row.dofs, row.weights / length[element])

    def elong_channel(self, name, element) -> Channel:
        """Elongation of an element (m).

        Parameters
        ----------
        name : str
            Channel name.
        element : int
            Element index.

        Returns
        -------
        Channel
            Output channel of kind ``"elong"``.
        """
        row = self.element_row(element)
        return Channel(name, "elong", row.dofs, row.weights)

    def angle_channels(self, prefix, nodes, axes=("roll", "pitch", "yaw")) -> tuple:
        """Least-squares rigid rotation of a node set, one channel per axis (rad).

        The translations ``u_i`` of the nodes are fitted by ``t + theta x r_i`` with
        ``r_i`` measured from the centroid; roll, pitch and yaw are ``theta`` about x, y
        and z.  Needs three non-collinear nodes.

        Parameters
        ----------
        prefix : str
            Channel names are ``<prefix>_<axis>``.
        nodes : sequence of int or str
            Node indices or names, at least three non-collinear.
        axes : tuple of str
            Names of the rotations about x, y and z, in that order; only the first
            ``len(axes)`` channels are made.

        Returns
        -------
        tuple of Channel
            Output channels of kind ``"angle"``, one per entry of ``axes``.
        """
        idx = np.array([self.node(n) for n in nodes])
        r = self.nodes[idx] - self.nodes[idx].mean(axis=0)
        rows = []
        for ri in r:
            # u_i = t + theta x r_i = t - [r_i]x theta
            skew = np.array([[0, -ri[2], ri[1]], [ri[2], 0, -ri[0]], [-ri[1], ri[0], 0]])
            rows.append(np.hstack([np.eye(3), -skew]))
        G = np.vstack(rows)  # (3k, 6)
        if np.linalg.matrix_rank(G) < 6:
            raise ModelError(f"angle sensor {prefix!r}: nodes are collinear; need three "
                             "non-collinear nodes")
        P = np.linalg.pinv(G)[3:]  # (3, 3k): theta = P u
        dofs = (3 * idx[:, None] + np.arange(3)).ravel()
        return tuple(Channel(f"{prefix}_{ax}", "angle", dofs, P[i]) for i, ax in enumerate(axes))

    def rate_channels(self, prefix, nodes, axes=("roll", "pitch", "yaw")) -> tuple:
        """Angular rate of a node set (rad/s), the time derivative of :meth:`angle_channels`.

        Parameters
        ----------
        prefix : str
            Channel names are ``<prefix>_<axis>``.
        nodes : sequence of int or str
            Node indices or names, at least three non-collinear.
        axes : tuple of str
            Names of the rotations about x, y and z, in that order.

        Returns
        -------
        tuple of Channel
            Output channels of kind ``"rate"``, one per entry of ``axes``.
        """
        return tuple(Channel(c.name, "rate", c.dofs, c.weights)
                     for c in self.angle_channels(prefix, nodes, axes))


def channel_matrix(channels, n_dof: int) -> sp.csr_matrix:
    """Stack channels as rows of a sparse matrix, shape (n_channels, n_dof).

    Parameters
    ----------
    channels : sequence of Channel
        Rows, in order.
    n_dof : int
        Number of columns: all DOFs of the truss (``3 n_nodes``).

    Returns
    -------
    scipy.sparse.csr_matrix, shape (n_channels, n_dof)
        Channel weights on the DOFs.
    """
    rows, cols, vals = [], [], []
    for i, c in enumerate(channels):
        rows.append(np.full(len(c.dofs), i))
        cols.append(np.asarray(c.dofs))
        vals.append(np.asarray(c.weights, float))
    if not channels:
        return sp.csr_matrix((0, n_dof))
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(len(channels), n_dof))


def assemble(truss: Truss, free_only: bool = True):
    """Sparse stiffness and mass matrices of a truss.

    Parameters
    ----------
    truss : Truss
        The model.
    free_only : bool
        Return matrices on the free DOFs only (default) or on all DOFs.

    Returns
    -------
    K : scipy.sparse.csc_matrix, shape (n, n)
        Stiffness (N/m).
    M : scipy.sparse.csc_matrix, shape (n, n)
        Mass (kg).
    """
    e, length = truss.element_geometry()
    el = truss.elements
    n_el = len(el)
    ndof = truss.n_dof
    # element DOF indices (n_el, 6)
    edofs = np.hstack([3 * el[:, [0]] + np.arange(3), 3 * el[:, [1]] + np.arange(3)])
    ee = np.einsum("ni,nj->nij", e, e)  # (n_el, 3, 3)
    block = np.block([[ee, -ee], [-ee, ee]]) if n_el else np.zeros((0, 6, 6))
    ke = truss.axial_stiffness[:, None, None] * block
    rows = np.repeat(edofs, 6, axis=1).ravel()
    cols = np.tile(edofs, (1, 6)).ravel()
    K = sp.coo_matrix((ke.ravel(), (rows, cols)), shape=(ndof, ndof)).tocsc()
    if truss.springs:
        r, c, v = [], [], []
        for spr in truss.springs:
            d = np.asarray(spr.dofs)
            w = np.asarray(spr.weights, float)
            r.append(np.repeat(d, len(d)))
            c.append(np.tile(d, len(d)))
            v.append(spr.k * np.outer(w, w).ravel())
        K = K + sp.coo_matrix((np.concatenate(v), (np.concatenate(r), np.concatenate(c))),
                              shape=(ndof, ndof)).tocsc()

    m = truss.element_mass
    if truss.mass_type == "lumped":
        me_diag = np.repeat(m / 2.0, 6).reshape(n_el, 6)
        diag = np.bincount(edofs.ravel(), weights=me_diag.ravel(), minlength=ndof)
        M = sp.diags(diag).tocsc()
    else:
        I3 = np.eye(3)
        cm = np.block([[2 * I3, I3], [I3, 2 * I3]]) / 6.0
        me = m[:, None, None] * cm[None]
        M = sp.coo_matrix((me.ravel(), (rows, cols)), shape=(ndof, ndof)).tocsc()
    M = M + sp.diags(np.repeat(truss.node_mass, 3))
    M = M.tocsc()
    if free_only:
        f = truss.free_dofs
        K = K[f][:, f].tocsc()
        M = M[f][:, f].tocsc()
    return K, M


def input_matrix(truss: Truss) -> sp.csc_matrix:
    """Influence matrix ``E`` on the free DOFs, shape (n_free, n_inputs)."""
    E = channel_matrix(truss.input_channels, truss.n_dof).T.tocsr()
    return E[truss.free_dofs].tocsc()


def output_matrix(truss: Truss) -> sp.csr_matrix:
    """Sensor matrix ``H`` on the free DOFs, shape (n_outputs, n_free)."""
    H = channel_matrix(truss.outputs, truss.n_dof).tocsc()
    return H[:, truss.free_dofs].tocsr()


def member_strain_energy(truss: Truss, phi) -> np.ndarray:
    """Share of each mode's strain energy stored in each member.

    Member ``e`` of axial stiffness ``k_e`` stretched by ``delta_e = b_e^T u`` (``b_e``
    its elongation row, :meth:`Truss.element_row`) stores ``k_e delta_e^2 / 2``; the
    mode stores ``u^T K u / 2`` in all (members and springs).  The share is their ratio,
    so it does not depend on how the mode shape is scaled.

    Parameters
    ----------
    truss : Truss
        The model whose free DOFs the shapes live on.
    phi : array_like, shape (n_free,) or (n_free, n_modes)
        Mode shapes (or any displacement shapes) on the free DOFs, as returned by
        :func:`structfmu.reduce.eigenpairs` (m, any scale).

    Returns
    -------
    ndarray, shape (n_el, n_modes)
        Fraction of each shape's strain energy in each member (-).  Each column sums to
        1 minus the share of the truss's scalar springs (exactly 1 without springs).

    Raises
    ------
    DimensionError
        If ``phi`` has not one row per free DOF.
    ModelError
        If a shape stores no strain energy (a rigid-body mode or a zero column).
    """
    phi = np.asarray(phi, float)
    vector = phi.ndim == 1
    shapes = phi[:, None] if vector else phi
    free = truss.free_dofs
    if shapes.ndim != 2 or shapes.shape[0] != len(free):
        raise DimensionError(f"truss {truss.name!r}: mode shapes have shape {phi.shape}; "
                             f"expected ({len(free)}, n_modes), one row per free DOF")
    u = np.zeros((truss.n_dof, shapes.shape[1]))
    u[free] = shapes
    e, _ = truss.element_geometry()
    el = truss.elements
    # elongation of every member in every shape: (u_2 - u_1) . e
    du = u.reshape(len(truss.nodes), 3, -1)
    delta = np.einsum("nim,ni->nm", du[el[:, 1]] - du[el[:, 0]], e)
    members = 0.5 * truss.axial_stiffness[:, None] * delta**2
    K, _ = assemble(truss)
    total = 0.5 * np.einsum("im,im->m", shapes, K @ shapes)
    scale = max(float(np.max(np.abs(total), initial=0.0)), 1e-300)
    weak = np.flatnonzero(total <= 1e-12 * scale) if total.size else []
    if len(weak) or not np.all(total > 0):
        raise ModelError(f"truss {truss.name!r}: shape {int(weak[0]) if len(weak) else 0} "
                         "stores no strain energy (a rigid-body mode?); its shares are "
                         "undefined")
    return members / total
