"""The reduced structural model of Eq. (7): modal block plus a small Ritz block.

Coordinates ``z = [z_e, z_o]``: ``z_e`` are mass-normalised eigenvector coordinates
(``M_ee = I``, ``K_ee = Lambda``), ``z_o`` are Gram-Schmidt static Ritz coordinates,
mass-orthonormalised among themselves (``M_oo = I``) with a small dense ``K_oo``.
The two blocks are uncoupled in mass and stiffness (Eq. 7) and, for proportional or
modal damping, in damping too (Eq. 8).

Equations of motion, with ``u`` the inputs (N)::

    z_e'' + c_e * z_e' + omega**2 * z_e = B_e u
    z_o'' + D_oo z_o'  + K_oo z_o       = B_o u
    y     = C_e z_e + C_o z_o                      (displacement-type outputs)
    y_rate = C_e z_e' + C_o z_o'                   (rate outputs)
    y_acc = C_e z_e'' + C_o z_o''                  (acceleration outputs)
"""

from __future__ import annotations

import difflib
import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from structfmu.errors import DimensionError, ModelError
from structfmu.sensors import SensorLowpass


def _frozen(value) -> np.ndarray:
    """A float array the model may keep: an array a model froze before (its own data,
    not writeable: what ``dataclasses.replace`` passes on) is kept as it is, so that a
    copy of a model with other modes shares its Ritz block (and the discretisation
    kept for it); anything else is copied."""
    if (isinstance(value, np.ndarray) and value.dtype == np.float64
            and not value.flags.writeable and value.flags.owndata):
        return value
    return np.array(value, float)


@dataclass(frozen=True)
class ReducedModel:
    """Reduced structure: modal block + Ritz block, inputs and named outputs.

    Parameters
    ----------
    omega : ndarray, shape (n_m,)
        Natural frequencies of the retained eigenvectors (rad/s); 0 for rigid modes.
    modal_damping : ndarray, shape (n_m,)
        Modal damping coefficients ``c_e = 2 zeta omega (+ alpha + beta omega^2)`` (1/s).
    B_e : ndarray, shape (n_m, n_in)
        Modal input matrix ``T_e^T E``.
    C_e : ndarray, shape (n_out, n_m)
        Output matrix on modal coordinates ``H T_e``.
    K_oo, D_oo : ndarray, shape (n_r, n_r)
        Ritz-block stiffness (1/s^2) and damping (1/s), with ``M_oo = I``.
    B_o : ndarray, shape (n_r, n_in)
        Ritz-block input matrix ``T_o^T E``.
    C_o : ndarray, shape (n_out, n_r)
        Output matrix on Ritz coordinates ``H T_o``.
    input_names, output_names : tuple of str
        Channel names; inputs are forces (N), outputs carry ``output_kinds``.
    output_kinds : tuple of str
        ``"disp"``, ``"strain"``, ``"elong"``, ``"angle"`` or ``"accel"`` per output.
    name : str
        Model name.
    meta : dict
        Free-form metadata (JSON-serialisable): source model, DOFs, damping spec...
    accel_lowpass : SensorLowpass, optional
        Sensor bandwidth applied to every acceleration output (:mod:`structfmu.sensors`);
        its states follow the structural ones and those outputs lose their feedthrough.
    """

    omega: np.ndarray
    modal_damping: np.ndarray
    B_e: np.ndarray
    C_e: np.ndarray
    K_oo: np.ndarray
    D_oo: np.ndarray
    B_o: np.ndarray
    C_o: np.ndarray
    input_names: tuple
    output_names: tuple
    output_kinds: tuple
    name: str = "reduced"
    meta: dict = field(default_factory=dict)
    accel_lowpass: SensorLowpass | None = None

    def __post_init__(self):
        arrays = {k: _frozen(getattr(self, k)) for k in
                  ("omega", "modal_damping", "B_e", "C_e", "K_oo", "D_oo", "B_o", "C_o")}
        n_m = arrays["omega"].shape[0]
        n_in = len(self.input_names)
        n_out = len(self.output_names)
        n_r = arrays["K_oo"].shape[0] if arrays["K_oo"].ndim == 2 else 0
        expect = {"omega": (n_m,), "modal_damping": (n_m,), "B_e": (n_m, n_in),
                  "C_e": (n_out, n_m), "K_oo": (n_r, n_r), "D_oo": (n_r, n_r),
                  "B_o": (n_r, n_in), "C_o": (n_out, n_r)}
        for k, shape in expect.items():
            a = arrays[k].reshape(shape) if arrays[k].size == 0 else arrays[k]
            if a.shape != shape:
                raise DimensionError(f"reduced model {self.name!r}: {k} has shape {a.shape}; "
                                     f"expected {shape}")
            if not np.isfinite(a).all():
                where = np.argwhere(~np.isfinite(a))[0]
                raise ModelError(f"reduced model {self.name!r}: {k} has a non-finite entry "
                                 f"({float(a[tuple(where)])!r} at index {tuple(int(i) for i in where)}); "
                                 "every matrix entry must be a finite number")
            a.setflags(write=False)
            object.__setattr__(self, k, a)
        self._check_physical(arrays)
        if len(self.output_kinds) != n_out:
            raise DimensionError(f"reduced model {self.name!r}: {len(self.output_kinds)} output "
                                 f"kinds for {n_out} outputs")
        object.__setattr__(self, "input_names", tuple(self.input_names))
        object.__setattr__(self, "output_names", tuple(self.output_names))
        object.__setattr__(self, "output_kinds", tuple(self.output_kinds))
        lp = self.accel_lowpass
        if lp is not None and not isinstance(lp, SensorLowpass):
            object.__setattr__(self, "accel_lowpass", SensorLowpass(*lp))

    def _check_physical(self, arrays: dict) -> None:
        """Frequencies and damping >= 0, the Ritz block not unstable (entries are finite)."""
        for k in ("omega", "modal_damping"):
            neg = np.flatnonzero(arrays[k] < 0)
            if neg.size:
                what = "frequency" if k == "omega" else "damping (it would feed energy in)"
                raise ModelError(f"reduced model {self.name!r}: mode {int(neg[0])} has {k} "
                                 f"{float(arrays[k][neg[0]])!r}; a negative {what} makes an "
                                 "unstable structure; give values >= 0")
        for k in ("K_oo", "D_oo"):
            a = arrays[k]
            if a.size == 0:
                continue
            sym = (a + a.T) / 2
            low = float(np.linalg.eigvalsh(sym).min())
            # eigvalsh of a PSD matrix is good to about eps times its norm
            tol = 1e3 * np.finfo(float).eps * max(float(np.abs(sym).max()), 1e-300)
            if low < -tol:
                what = "stiffness" if k == "K_oo" else "damping"
                raise ModelError(f"reduced model {self.name!r}: the Ritz-block {what} {k} has "
                                 f"an eigenvalue {low!r} < 0; a {what} matrix must be "
                                 "positive semi-definite (an unstable structure otherwise)")

    # -- sizes -------------------------------------------------------------------------
    @property
    def n_modes(self) -> int:
        return self.omega.shape[0]

    @property
    def n_ritz(self) -> int:
        return self.K_oo.shape[0]

    @property
    def n_inputs(self) -> int:
        return len(self.input_names)

    @property
    def n_outputs(self) -> int:
        return len(self.output_names)

    @property
    def n_struct_states(self) -> int:
        """Structural states ``2 (n_modes + n_ritz)``."""
        return 2 * (self.n_modes + self.n_ritz)

    @property
    def n_filter_states(self) -> int:
        """States of the accelerometer low-pass (0 without one)."""
        if self.accel_lowpass is None:
            return 0
        return self.accel_lowpass.order * int(self.is_accel.sum())

    @property
    def n_states(self) -> int:
        """All states: structural, then accelerometer filter."""
        return self.n_struct_states + self.n_filter_states

    @property
    def frequencies_hz(self) -> np.ndarray:
        """Natural frequencies of the modal block (Hz)."""
        return self.omega / (2 * np.pi)

    @property
    def is_rate(self) -> np.ndarray:
        """Boolean mask of velocity-type outputs (angular rates)."""
        return np.array([k == "rate" for k in self.output_kinds], bool)

    @property
    def is_accel(self) -> np.ndarray:
        """Boolean mask of acceleration outputs (direct feedthrough unless filtered)."""
        return np.array([k == "accel" for k in self.output_kinds], bool)

    def input_index(self, name: str) -> int:
        return _index(self.input_names, name, "input", self.name)

    def output_index(self, name: str) -> int:
        return _index(self.output_names, name, "output", self.name)

    # -- variants ----------------------------------------------------------------------
    def without_ritz(self) -> "ReducedModel":
        """The same model with the Ritz block dropped (eigenvectors only)."""
        n_in, n_out = self.n_inputs, self.n_outputs
        return replace(self, K_oo=np.zeros((0, 0)), D_oo=np.zeros((0, 0)),
                       B_o=np.zeros((0, n_in)), C_o=np.zeros((n_out, 0)),
                       meta={**self.meta, "n_ritz": 0})

    def truncate(self, n_modes: int) -> "ReducedModel":
        """Keep only the first ``n_modes`` eigenvectors."""
        if not 0 <= n_modes <= self.n_modes:
            raise ModelError(f"reduced model {self.name!r} has {self.n_modes} modes; cannot "
                             f"keep {n_modes}")
        return replace(self, omega=self.omega[:n_modes],
                       modal_damping=self.modal_damping[:n_modes],
                       B_e=self.B_e[:n_modes], C_e=self.C_e[:, :n_modes])

    def with_modal_damping(self, zeta) -> "ReducedModel":
        """Copy with modal damping ratios ``zeta`` (scalar or shape (n_m,))."""
        z = np.broadcast_to(np.asarray(zeta, float), self.omega.shape)
        return replace(self, modal_damping=2 * z * self.omega)

    def select(self, inputs=None, outputs=None) -> "ReducedModel":
        """Copy restricted to some inputs and outputs (by name, in the given order).

        Parameters
        ----------
        inputs : sequence of str, optional
            Input names to keep; default all.
        outputs : sequence of str, optional
            Output names to keep; default all.

        Returns
        -------
        ReducedModel
        """
        ii = [self.input_index(n) for n in inputs] if inputs is not None else \
            list(range(self.n_inputs))
        oo = [self.output_index(n) for n in outputs] if outputs is not None else \
            list(range(self.n_outputs))
        return replace(self, B_e=self.B_e[:, ii], B_o=self.B_o[:, ii], C_e=self.C_e[oo],
                       C_o=self.C_o[oo], input_names=tuple(self.input_names[i] for i in ii),
                       output_names=tuple(self.output_names[i] for i in oo),
                       output_kinds=tuple(self.output_kinds[i] for i in oo))

    # -- persistence -------------------------------------------------------------------
    def save(self, path) -> Path:
        """Write the model to one ``.npz`` file (atomic)."""
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp.npz")
        np.savez(tmp, omega=self.omega, modal_damping=self.modal_damping, B_e=self.B_e,
                 C_e=self.C_e, K_oo=self.K_oo, D_oo=self.D_oo, B_o=self.B_o, C_o=self.C_o,
                 header=np.array(json.dumps({
                     "format": "jitterfmu-reduced-model", "version": 1, "name": self.name,
                     "input_names": list(self.input_names),
                     "output_names": list(self.output_names),
                     "output_kinds": list(self.output_kinds), "meta": self.meta,
                     "accel_lowpass": (self.accel_lowpass.to_json()
                                       if self.accel_lowpass is not None else None)})))
        tmp.replace(path)
        return path

    @classmethod
    def load(cls, path) -> "ReducedModel":
        """Read a model written by :meth:`save`."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"reduced model file {str(path)!r} does not exist")
        try:
            with np.load(path, allow_pickle=False) as f:
                header = json.loads(str(f["header"]))
                arrays = {k: f[k] for k in ("omega", "modal_damping", "B_e", "C_e", "K_oo",
                                            "D_oo", "B_o", "C_o")}
        except (KeyError, ValueError, OSError) as exc:
            raise ModelError(f"{str(path)!r} is not a reduced-model .npz file ({exc})") from None
        if header.get("format") != "jitterfmu-reduced-model":
            raise ModelError(f"{str(path)!r} is not a reduced-model .npz file")
        try:
            return cls(**arrays, input_names=tuple(header["input_names"]),
                       output_names=tuple(header["output_names"]),
                       output_kinds=tuple(header["output_kinds"]), name=header["name"],
                       meta=header.get("meta", {}),
                       accel_lowpass=(SensorLowpass(*header["accel_lowpass"])
                                      if header.get("accel_lowpass") else None))
        except (ModelError, DimensionError) as exc:
            raise type(exc)(f"{str(path)!r}: {exc}") from None


def _index(names, name, what, model):
    try:
        return names.index(name)
    except ValueError:
        close = difflib.get_close_matches(name, names, 3)
        hint = f"; did you mean {', '.join(close)}?" if close else f"; known: {', '.join(names)}"
        raise ModelError(f"reduced model {model!r} has no {what} {name!r}{hint}") from None
