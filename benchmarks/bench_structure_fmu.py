"""Per-step cost of the structure FMU vs the bare numpy update vs dense dlsim.

Run::

    .venv/bin/python benchmarks/bench_structure_fmu.py [--modes 1000] [--ritz 4]
        [--inputs 40] [--outputs 40] [--steps 2000] [--repeat 3]

One synthetic :class:`structfmu.reduced.ReducedModel` (seeded random modal data:
frequencies 1 Hz - 2 kHz log-spaced, 0.5 % damping, a dense Ritz block at 3-5 kHz;
32 angle, 4 rate and 4 acceleration outputs, so that inputs feed through) is stepped
``--steps`` times with ``h = 1 ms`` and seeded random inputs by:

* ``numpy ZohStepper``: the work the FMU slave does per step, in a Python loop:
  :meth:`~structfmu.discrete.ZohStepper.outputs` after the new inputs (feedthrough),
  :meth:`~structfmu.discrete.ZohStepper.step`,
  :meth:`~structfmu.discrete.ZohStepper.update_state_outputs`, ``outputs``;
* ``FMU (fmpy FMU2Slave)``: the FMU built by :func:`fmutools.build.build_fmu`, loaded in
  this process by fmpy; per step ``setReal`` of all inputs, ``doStep``, ``getReal`` of
  all outputs (what :func:`tests.support.hosts.run_fmpy` does);
* ``FMU (raw ctypes)``: the same FMU and calls, but through fmpy's bound C functions with
  ctypes arrays allocated once (host-side overhead removed);
* ``scipy dlsim (dense)``: :func:`scipy.signal.dlsim` on the same discrete model as a
  dense ``(A, B, C, D)`` with ``2 (modes + ritz)`` states.

Best of ``--repeat`` runs (dlsim: one run).  The header prints ``OPENBLAS_NUM_THREADS``:
the matrix-vector products here are too small to gain from BLAS threads, and on a
busy machine the thread hand-offs double the cost of every path, so run it both ways.
All outputs are checked against each other before the table is printed.  A second table
splits the FMU step into its three calls, each through fmpy and called directly on the
Python slave object (no C layer), which shows where the time goes.
"""

from __future__ import annotations

import argparse
import ctypes
import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from structfmu.discrete import ZohStepper
from structfmu.reduced import ReducedModel

H = 1e-3


def synthetic_model(n_modes=1000, n_ritz=4, n_in=40, n_out=40, seed=0) -> ReducedModel:
    """A seeded random reduced model with modal and Ritz blocks.

    Parameters
    ----------
    n_modes, n_ritz, n_in, n_out : int
        Sizes.
    seed : int
        Seed of :func:`numpy.random.default_rng`.

    Returns
    -------
    ReducedModel
        Outputs: ``n_out - 8`` angles, 4 rates, 4 accelerations.
    """
    rng = np.random.default_rng(seed)
    omega = 2 * np.pi * np.logspace(0, np.log10(2000.0), n_modes)
    Q, _ = np.linalg.qr(rng.normal(size=(n_ritz, n_ritz)))
    w_r = 2 * np.pi * np.linspace(3000.0, 5000.0, n_ritz)
    K_oo = (Q * w_r**2) @ Q.T
    D_oo = (Q * (2 * 0.02 * w_r)) @ Q.T
    kinds = ["angle"] * (n_out - 8) + ["rate"] * 4 + ["accel"] * 4
    return ReducedModel(
        omega=omega, modal_damping=2 * 0.005 * omega,
        B_e=rng.normal(size=(n_modes, n_in)), C_e=1e-3 * rng.normal(size=(n_out, n_modes)),
        K_oo=K_oo, D_oo=D_oo, B_o=rng.normal(size=(n_ritz, n_in)),
        C_o=1e-3 * rng.normal(size=(n_out, n_ritz)),
        input_names=tuple(f"f_{i:02d}" for i in range(n_in)),
        output_names=tuple(f"y_{i:02d}" for i in range(n_out)),
        output_kinds=tuple(kinds), name="synthetic")


def run_numpy(model, U):
    """The slave's per-step numerics in a Python loop; outputs after each step."""
    st = ZohStepper(model)
    u = np.zeros(model.n_inputs)
    y = np.zeros(model.n_outputs)
    Y = np.empty((len(U), model.n_outputs))
    t0 = time.perf_counter()
    for k in range(len(U)):
        u[:] = U[k]
        if st.has_feedthrough:
            st.outputs(u, y)
        st.step(u, H)
        st.update_state_outputs()
        st.outputs(u, y)
        Y[k] = y
    return time.perf_counter() - t0, Y


def dense_system(model):
    """The discrete model as dense ``(A, B, C, D)`` (state layout of the ZohStepper)."""
    st = ZohStepper(model)
    dm = st.discrete(H)
    n_m, n_x = model.n_modes, model.n_states
    A = np.zeros((n_x, n_x))
    i = np.arange(n_m)
    A[i, i], A[i, n_m + i] = dm.a11, dm.a12
    A[n_m + i, i], A[n_m + i, n_m + i] = dm.a21, dm.a22
    A[2 * n_m:, 2 * n_m:] = dm.Phi_o
    B = np.vstack([dm.G1, dm.G2, dm.G_o])
    return A, B, st.C_x, st.D


def run_dlsim(model, U):
    """:func:`scipy.signal.dlsim`; returns outputs aligned like the FMU's."""
    from scipy.signal import dlsim

    A, B, C, D = dense_system(model)
    t0 = time.perf_counter()
    _, _, X = dlsim((A, B, C, D, H), U)
    dt = time.perf_counter() - t0
    # FMU convention: output after step k = C x_{k+1} + D u_k
    n = len(U)
    X1 = np.vstack([X[1:], (A @ X[-1] + B @ U[-1])[None]])
    return dt, X1 @ C.T + U[:n] @ D.T


def open_fmu(fmu):
    """Extract and instantiate an FMU in fmpy; returns (slave, vrs by name, folder)."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(fmu))
    folder = extract(str(fmu))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=folder,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    return slave, {v.name: v.valueReference for v in md.modelVariables}, folder


def run_fmu(fmu, model, U, raw=False):
    """Step the FMU through fmpy; ``raw`` uses preallocated ctypes arrays."""
    from fmpy.fmi2 import fmi2Real, fmi2ValueReference

    slave, vr, folder = open_fmu(fmu)
    try:
        in_vrs = [vr[n] for n in model.input_names]
        out_vrs = [vr[n] for n in model.output_names]
        Y = np.empty((len(U), model.n_outputs))
        if raw:
            n_in, n_out = len(in_vrs), len(out_vrs)
            c_in = (fmi2ValueReference * n_in)(*in_vrs)
            c_out = (fmi2ValueReference * n_out)(*out_vrs)
            u_buf = np.zeros(n_in)
            y_buf = np.zeros(n_out)
            c_u = u_buf.ctypes.data_as(ctypes.POINTER(fmi2Real))
            c_y = y_buf.ctypes.data_as(ctypes.POINTER(fmi2Real))
            set_real, get_real, do_step = slave.fmi2SetReal, slave.fmi2GetReal, slave.fmi2DoStep
            comp = slave.component
            t0 = time.perf_counter()
            for k in range(len(U)):
                u_buf[:] = U[k]
                set_real(comp, c_in, n_in, c_u)
                do_step(comp, k * H, H, 1)
                get_real(comp, c_out, n_out, c_y)
                Y[k] = y_buf
            dt = time.perf_counter() - t0
        else:
            t0 = time.perf_counter()
            for k in range(len(U)):
                slave.setReal(in_vrs, U[k].tolist())
                slave.doStep(currentCommunicationPoint=k * H, communicationStepSize=H)
                Y[k] = slave.getReal(out_vrs)
            dt = time.perf_counter() - t0
        slave.terminate()
        slave.freeInstance()
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return dt, Y


def breakdown(fmu, model, U):
    """Mean time (s) of setReal, doStep and getReal: through fmpy and on the Python slave."""
    from structfmu.slave import StructureSlave

    n = len(U)
    slave, vr, folder = open_fmu(fmu)
    in_vrs = [vr[n_] for n_ in model.input_names]
    out_vrs = [vr[n_] for n_ in model.output_names]
    rows = {}
    try:
        t = np.zeros(4)
        for k in range(n):
            t0 = time.perf_counter()
            vals = U[k].tolist()
            t1 = time.perf_counter()
            slave.setReal(in_vrs, vals)
            t2 = time.perf_counter()
            slave.doStep(currentCommunicationPoint=k * H, communicationStepSize=H)
            t3 = time.perf_counter()
            slave.getReal(out_vrs)
            t4 = time.perf_counter()
            t += (t1 - t0, t2 - t1, t3 - t2, t4 - t3)
        rows["fmpy"] = t / n
        slave.terminate()
        slave.freeInstance()
        # the same slave class, called directly (what the C++ layer ends up calling)
        py = StructureSlave(instance_name="direct", resources=str(Path(folder) / "resources"))
        py.exit_initialization_mode()
        t = np.zeros(4)
        for k in range(n):
            t0 = time.perf_counter()
            vals = U[k].tolist()
            t1 = time.perf_counter()
            py.set_real(in_vrs, vals)
            t2 = time.perf_counter()
            py.do_step(k * H, H)
            t3 = time.perf_counter()
            py.get_real(out_vrs)
            t4 = time.perf_counter()
            t += (t1 - t0, t2 - t1, t3 - t2, t4 - t3)
        rows["python slave"] = t / n
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return rows


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--modes", type=int, default=1000)
    p.add_argument("--ritz", type=int, default=4)
    p.add_argument("--inputs", type=int, default=40)
    p.add_argument("--outputs", type=int, default=40)
    p.add_argument("--steps", type=int, default=2000)
    p.add_argument("--repeat", type=int, default=3)
    a = p.parse_args(argv)

    from fmutools.build import build_fmu
    from structfmu.fmuspec import spec_from_model

    model = synthetic_model(a.modes, a.ritz, a.inputs, a.outputs)
    U = np.random.default_rng(1).normal(size=(a.steps, a.inputs))
    with tempfile.TemporaryDirectory(prefix="bench_structure_fmu_") as tmp:
        fmu = build_fmu(spec_from_model(model, "bench_structure"), tmp)

        def best(fn):
            runs = [fn() for _ in range(a.repeat)]
            return min(r[0] for r in runs), runs[0][1]

        t_np, y_np = best(lambda: run_numpy(model, U))
        t_fmu, y_fmu = best(lambda: run_fmu(fmu, model, U))
        t_raw, y_raw = best(lambda: run_fmu(fmu, model, U, raw=True))
        t_dl, y_dl = run_dlsim(model, U)
        parts = breakdown(fmu, model, U)

    scale = np.abs(y_np).max(axis=0)
    np.testing.assert_array_equal(y_fmu, y_np)
    np.testing.assert_array_equal(y_raw, y_np)
    np.testing.assert_allclose(y_dl / scale, y_np / scale, rtol=0, atol=1e-9)

    n = a.steps
    print(f"model: {model.n_modes} modes + {model.n_ritz} Ritz coordinates = "
          f"{model.n_states} states, {model.n_inputs} inputs, {model.n_outputs} outputs "
          f"(4 with feedthrough); {n} steps of {H * 1e3:g} ms; best of {a.repeat} "
          f"(dlsim: 1 run); OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}")
    print("outputs agree: FMU == numpy bit for bit; dlsim within 1e-9 of each output's peak")
    head = f"{'path':<26} {'us/step':>9} {'vs numpy':>9} {'dlsim / path':>13}"
    print(head)
    print("-" * len(head))
    for name, t in (("numpy ZohStepper", t_np), ("FMU (fmpy FMU2Slave)", t_fmu),
                    ("FMU (raw ctypes)", t_raw), ("scipy dlsim (dense)", t_dl)):
        print(f"{name:<26} {t / n * 1e6:9.1f} {t / t_np:8.2f}x {t_dl / t:12.1f}x")
    print(f"goal FMU <= 2x numpy: {'met' if t_fmu <= 2 * t_np else 'NOT met'} "
          f"({t_fmu / t_np:.2f}x); goal FMU >= 10x faster than dlsim: "
          f"{'met' if t_dl >= 10 * t_fmu else 'NOT met'} ({t_dl / t_fmu:.1f}x)")
    print()
    print("where the FMU step goes (mean us per call):")
    head = f"{'caller':<16} {'tolist':>7} {'setReal':>8} {'doStep':>8} {'getReal':>8} {'sum':>8}"
    print(head)
    print("-" * len(head))
    for name, t in parts.items():
        us = t * 1e6
        print(f"{name:<16} {us[0]:7.1f} {us[1]:8.1f} {us[2]:8.1f} {us[3]:8.1f} {us.sum():8.1f}")


if __name__ == "__main__":
    main()
