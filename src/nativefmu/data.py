"""Model data of the native FMUs: one file per FMU in ``resources/``.

The C kernels read it with ``jf_data_*`` (``csrc/data.c``)::

    jitterfmu-native-data 2\n
    <name> <rows> <cols>\n
    <rows * cols values, row-major, IEEE 754 binary64, little-endian (8 bytes each)>
    ...

A text header per array and the values' own bits: every double exactly, read without a
parser (no locale, no rounding) in a fraction of the time the earlier hexadecimal text
took (3.5 MB of text for the EOS structure, parsed at every instantiation).  The reader
assembles each value from its bytes, so a big-endian host reads the same numbers.
:func:`decode` reads a file back (to inspect one).  One function per kernel turns the
Python FMU's model (reduced model, stack preset, control law) into the arrays its
kernel reads; the step-independent products (output matrices, feedthrough) are computed
here with the Python package's own code, the step-dependent discretisation in C.
"""

from __future__ import annotations

import io
import tempfile
import zipfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ctrlfmu.law import load_law
from distfmu import sources as S
from distfmu.custom import CUSTOM_PRESET, SOURCE_FILE, source_from_json
from distfmu.presets import PRESETS
from distfmu.sources import Sum, Zero
from fmutools.build import FmuSpec
from piezofmu.actuator import actuator_preset
from structfmu.discrete import ZohStepper, discretize
from structfmu.reduced import ReducedModel
from structfmu.statespace import first_order

__all__ = ["KERNELS", "NativeUnsupportedError", "decode", "encode", "kernel_of", "model_data",
           "zip_compression"]

#: slave class -> C kernel (``csrc/<kernel>.c``, data file ``<kernel>.dat``).
KERNELS: dict[str, str] = {
    "structfmu.slave:StructureSlave": "structure",
    "piezofmu.slave:PiezoSlave": "piezo",
    "ctrlfmu.slave:ControllerSlave": "controller",
    "distfmu.excitation:ExcitationSlave": "excitation",
    "acsfmu.slave:AcsSlave": "acs",
    "distfmu.slave:DisturbanceSlave": "disturbance",
}


class NativeUnsupportedError(ValueError):
    """An FMU whose slave has no C kernel yet."""


def kernel_of(spec: FmuSpec) -> str:
    """Name of the C kernel of ``spec``, or :class:`NativeUnsupportedError`."""
    try:
        return KERNELS[spec.slave_class]
    except KeyError:
        raise NativeUnsupportedError(
            f"FMU {spec.model_identifier!r} (slave {spec.slave_class}) has no native kernel; "
            f"native kernels exist for {sorted(KERNELS)}") from None


MAGIC = b"jitterfmu-native-data 2\n"


def zip_compression(name: str) -> int:
    """How an FMU archive holds its resource ``name``: a data file (binary doubles, which
    deflate poorly and are read at every instantiation) stored, anything else deflated."""
    return zipfile.ZIP_STORED if name.endswith(".dat") else zipfile.ZIP_DEFLATED


def encode(arrays: Mapping[str, object]) -> bytes:
    """The data file holding ``arrays`` (scalars, vectors as one row, or matrices).

    Parameters
    ----------
    arrays : mapping of str to array_like
        Name (1-63 printable characters, no spaces) -> finite values; 0-d and 1-d
        arrays are written as one row.

    Returns
    -------
    bytes
        Content of the file (format in the module docstring).
    """
    parts = [MAGIC]
    for name, value in arrays.items():
        if not (0 < len(name) < 64 and name.isascii() and name.isprintable()
                and not any(c.isspace() for c in name)):
            raise ValueError(f"data array name {name!r} must be 1-63 printable ASCII "
                             "characters, no spaces")
        arr = np.asarray(value, dtype=float)
        if arr.ndim > 2:
            raise ValueError(f"data array {name!r} has {arr.ndim} dimensions; expected <= 2")
        arr = arr.reshape(1, -1) if arr.ndim < 2 else arr
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"data array {name!r} has non-finite values")
        parts.append(f"{name} {arr.shape[0]} {arr.shape[1]}\n".encode("ascii"))
        parts.append(np.ascontiguousarray(arr, dtype="<f8").tobytes())
    return b"".join(parts)


def decode(content: bytes) -> dict:
    """The arrays of a data file (:func:`encode`'s inverse), each of shape (rows, cols).

    Raises
    ------
    ValueError
        When ``content`` is not such a file, in one sentence saying where.
    """
    if not content.startswith(MAGIC):
        raise ValueError("not a jitterfmu native data file of version 2 (its first line "
                         f"must be {MAGIC.decode().strip()!r})")
    out, at = {}, len(MAGIC)
    while at < len(content):
        end = content.find(b"\n", at, at + 128)
        head = content[at:end].decode("ascii", "replace").split(" ") if end > 0 else []
        if len(head) != 3 or not (head[1].isdigit() and head[2].isdigit()):
            raise ValueError(f"malformed array header at byte {at} (array {len(out) + 1})")
        rows, cols = int(head[1]), int(head[2])
        stop = end + 1 + 8 * rows * cols
        if stop > len(content):
            raise ValueError(f"array {head[0]!r} is cut short: {rows} x {cols} values need "
                             f"{8 * rows * cols} bytes, {len(content) - end - 1} are left")
        out[head[0]] = np.frombuffer(content, "<f8", rows * cols, end + 1).reshape(
            rows, cols).astype(float)
        at = stop
    return out


def _resource_bytes(spec: FmuSpec, name: str) -> bytes:
    src = spec.resources[name]
    return src if isinstance(src, bytes) else Path(src).read_bytes()


#: Communication steps (s) whose structure discretisation is shipped precomputed: those of
#: the shipped scenarios and experiments.  Other steps are discretised in C at the first
#: step of that size (see csrc/structure.c).
STRUCTURE_STEPS = (1e-3, 4e-3)


def _structure(spec: FmuSpec, vrs: Mapping[str, int],
               steps: tuple[float, ...] = STRUCTURE_STEPS) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.npz"
        path.write_bytes(_resource_bytes(spec, "model.npz"))
        model = ReducedModel.load(path)
    stepper = ZohStepper(model)
    n_m, n_r, ns = model.n_modes, model.n_ritz, model.n_struct_states
    out = {
        "n_m": n_m, "n_r": n_r, "n_in": model.n_inputs, "n_out": model.n_outputs,
        "n_f": model.n_filter_states,
        "omega": model.omega, "modal_damping": np.broadcast_to(model.modal_damping, (n_m,)),
        "B_e": model.B_e, "K_oo": model.K_oo, "D_oo": model.D_oo,
        "B_o": model.B_o if n_r else np.zeros((0, model.n_inputs)),
        "C_x": stepper.C_x, "D": stepper.D,
        "u_vr": [vrs[name] for name in model.input_names],
        "y_vr": [vrs[name] for name in model.output_names],
    }
    if model.n_filter_states:
        A, B, _, _ = first_order(model)
        n = A.shape[0]
        # first_order's layout [q_e, q_o, v_e, v_o, x_f] -> the stepper's [q_e, v_e, q_o, v_o, x_f]
        perm = np.r_[0:n_m, n_m + n_r:2 * n_m + n_r, n_m:n_m + n_r, 2 * n_m + n_r:ns, ns:n]
        out["A_full"] = A[np.ix_(perm, perm)]
        out["B_full"] = B[perm]
    # the Ritz block is stiff (kHz stack modes): its exponential has round-off of ~1e-10
    # relative, different in every implementation; shipping scipy's keeps both FMUs equal
    steps = tuple(sorted({float(h) for h in (*steps, spec.step_size or steps[0])}))
    out["n_steps"] = len(steps)
    out["steps"] = steps
    for j, h in enumerate(steps):
        dm = discretize(model, h)
        zoh = {"a11": dm.a11, "a12": dm.a12, "a21": dm.a21, "a22": dm.a22, "G1": dm.G1,
               "G2": dm.G2, "Phi_o": dm.Phi_o,
               "G_o": dm.G_o if n_r else np.zeros((0, model.n_inputs))}
        if model.n_filter_states:
            zoh["F_x"], zoh["F_u"] = dm.F_x, dm.F_u
        out.update({f"{name}_{j}": value for name, value in zoh.items()})
    return out


def _piezo(spec: FmuSpec, vrs: Mapping[str, int]) -> dict:
    act = actuator_preset(str(spec.init_kwargs.get("preset_name", "P-243.30")))
    stack = act.stack
    return {"ch": stack.ch, "capacitance": stack.capacitance,
            "stroke_per_volt": act.stroke_per_volt, "rated_voltage": stack.rated_voltage}


def _controller(spec: FmuSpec, vrs: Mapping[str, int]) -> dict:
    law = load_law(io.BytesIO(_resource_bytes(spec, "law.npz")))
    return {"n": law.n_states, "n_in": law.n_inputs, "n_out": law.n_outputs, "dt": law.dt,
            "delayed": float(law.delayed), "A": law.A, "B": law.B, "C": law.C, "D": law.D,
            "aw_gain": law.aw_gain}


def _term(source) -> list[float]:
    """One source as the parameter list csrc/disturbance.c reads (type code first)."""
    def kind(k):
        return 0.0 if k == "force" else 1.0

    if isinstance(source, S.Harmonic):
        n = len(source.amplitudes)
        h = range(1, n + 1) if source.harmonics is None else source.harmonics
        phi = [0.0] * n if source.phases is None else source.phases
        return [1, source.frequency, kind(source.kind), *S._unit(source.direction, "h"), n,
                *source.amplitudes, *h, *phi]
    if isinstance(source, S.Chopper):
        return [2, source.frequency, source.amplitude, kind(source.kind),
                *S._unit(source.direction, "c"), source.rise_time, source.duty, source.phase]
    if isinstance(source, S.ScanMirror):
        return [3, source.inertia, source.period, source.amplitude, source.retrace_fraction,
                source.turnaround, *S._unit(source.axis, "s", "axis")]
    if isinstance(source, S.Slew):
        return [4, source.angle, source.max_rate, source.max_accel, source.inertia,
                source.start, *S._unit(source.axis, "s", "axis"),
                float(source.repeat is not None), source.repeat or 0.0, float(source.alternate)]
    if isinstance(source, S.Stepper):
        return [5, source.step_rate, source.peak_torque, source.pulse_width,
                *S._unit(source.axis, "s", "axis"), float(source.bipolar)]
    if isinstance(source, S.WheelImbalance) and not isinstance(source.speed, S.SpeedProfile):
        n = len(source.harmonics)
        zeros = [0.0] * n
        return [6, n, *source.harmonics, *source.force_coeffs, *source.torque_coeffs,
                *(source.axial_coeffs or zeros), *(source.phases or zeros),
                *np.asarray(source._frame).ravel(), source.speed]
    if isinstance(source, S.Table):
        n = source.times.size
        return [7, float(source.fill == "hold"), n, *source.times,
                *source.values.T.ravel()]
    if isinstance(source, S.BandLimitedRandom):
        n = source.n_samples
        if n & (n - 1):
            raise NativeUnsupportedError(f"band-limited random source: n_samples {n} is not "
                                         "a power of two, which the native FFT needs")
        if not (isinstance(source.seed, int) and 0 <= source.seed < 2**32):
            raise NativeUnsupportedError(f"band-limited random source: seed {source.seed!r} "
                                         "must be an integer in [0, 2**32) natively")
        m = len(source.psd_freqs)
        return [8, source.seed, source.sample_rate, n, kind(source.kind),
                *S._unit(source.direction, "b"), m, *source.psd_freqs, *source.psd_values]
    raise NativeUnsupportedError(f"disturbance source {type(source).__name__} has no native "
                                 "form (supported: harmonic, chopper, scan mirror, slew, "
                                 "stepper, constant-speed wheel imbalance, table, "
                                 "band-limited random, and their sum)")


def _disturbance(spec: FmuSpec, vrs: Mapping[str, int]) -> dict:
    sources = {name: preset.source for name, preset in PRESETS.items()}
    if SOURCE_FILE in spec.resources:  # the FMU's own source (distfmu.fmuspec.spec_with_source)
        sources[CUSTOM_PRESET] = source_from_json(_resource_bytes(spec, SOURCE_FILE))
    out: dict = {"n_presets": len(sources)}
    for i, (name, source) in enumerate(sources.items()):
        terms = [] if isinstance(source, Zero) else (
            list(source.sources) if isinstance(source, Sum) else [source])
        if any(isinstance(t, (Sum, Zero)) for t in terms):
            raise NativeUnsupportedError(f"preset {name!r} nests sums; the native "
                                         "disturbance FMU takes one level")
        out[f"preset{i}_name_len"] = len(name)
        out[f"preset{i}_name"] = [ord(c) for c in name]
        out[f"preset{i}_sum"] = float(isinstance(source, Sum))
        out[f"preset{i}_n"] = len(terms)
        for j, term in enumerate(terms):
            values = _term(term)
            out[f"preset{i}_term{j}_len"] = len(values)
            out[f"preset{i}_term{j}"] = values
    return out


_WRITERS = {"structure": _structure, "piezo": _piezo, "controller": _controller,
            "disturbance": _disturbance}


def model_data(spec: FmuSpec, vrs: Mapping[str, int]) -> dict[str, bytes]:
    """Resource files of the native FMU of ``spec``.

    Parameters
    ----------
    spec : FmuSpec
        The Python FMU's spec (its resources hold the model).
    vrs : mapping of str to int
        Value reference of every variable name, from the model description.

    Returns
    -------
    dict of str to bytes
        ``{"<kernel>.dat": content}``, empty for a kernel without data.
    """
    kernel = kernel_of(spec)
    writer = _WRITERS.get(kernel)
    if writer is None:
        return {}
    return {f"{kernel}.dat": encode(writer(spec, vrs))}
