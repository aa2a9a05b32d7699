"""Run one FMU in fmpy, in a plain C host and in libcosim, step by step.

The three runners share one signature and return the outputs after every step as
an array of shape ``(n_steps, n_outputs)``, so a test compares them directly::

    kw = dict(inputs={"u": u}, outputs=["y"], step_size=1e-3, n_steps=100)
    np.testing.assert_array_equal(run_c_host(fmu, **kw), run_fmpy(fmu, **kw))

Inputs are held constant over each step (value ``inputs[name][k]`` during step
``k``); Real parameters are set before initialisation.  Time is ``k * step_size``
(never accumulated).  These helpers are for tests: they need fmpy, gcc and
libcosimpy, which the FMUs themselves do not.  The C host is ``c_host/host.c`` beside
this module.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

__all__ = ["run_fmpy", "run_c_host", "run_libcosim", "compile_c_host", "clean_env",
           "HostError"]

#: Source of the plain C host (no libpython).
C_HOST_SOURCE = Path(__file__).with_name("c_host") / "host.c"


class HostError(RuntimeError):
    """An FMU run in a host failed."""


def _input_matrix(inputs: Mapping[str, object] | None, n_steps: int) -> tuple[list[str], np.ndarray]:
    names = list(inputs or {})
    cols = []
    for name in names:
        col = np.broadcast_to(np.asarray(inputs[name], dtype=float), (n_steps,))
        cols.append(col)
    matrix = np.column_stack(cols) if cols else np.zeros((n_steps, 0))
    return names, matrix


def _variables(fmu: str | Path):
    md = read_model_description(str(fmu))
    return md, {v.name: v for v in md.modelVariables}


def _vrs(variables, names: Sequence[str], fmu) -> list[int]:
    missing = [n for n in names if n not in variables]
    if missing:
        raise KeyError(f"FMU {Path(fmu).name} has no variables {missing}")
    return [variables[n].valueReference for n in names]


def run_fmpy(fmu: str | Path, *, outputs: Sequence[str], step_size: float, n_steps: int,
             inputs: Mapping[str, object] | None = None,
             parameters: Mapping[str, float] | None = None) -> np.ndarray:
    """Run ``fmu`` in fmpy (this Python process).

    Parameters
    ----------
    fmu : str or Path
        ``.fmu`` file.
    outputs : sequence of str
        Real variables to read after each step.
    step_size : float
        Communication step (s).
    n_steps : int
        Number of steps.
    inputs : mapping of str to float or array, shape (n_steps,)
        Real inputs, held during each step.
    parameters : mapping of str to float
        Real start values set before initialisation.

    Returns
    -------
    numpy.ndarray, shape (n_steps, len(outputs))
    """
    md, variables = _variables(fmu)
    in_names, u = _input_matrix(inputs, n_steps)
    in_vrs, out_vrs = _vrs(variables, in_names, fmu), _vrs(variables, outputs, fmu)
    par = dict(parameters or {})
    par_vrs = _vrs(variables, list(par), fmu)
    unzip = extract(str(fmu))
    try:
        slave = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                          modelIdentifier=md.coSimulation.modelIdentifier, instanceName="fmpy")
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        if par_vrs:
            slave.setReal(par_vrs, list(par.values()))
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        y = np.empty((n_steps, len(out_vrs)))
        for k in range(n_steps):
            if in_vrs:
                slave.setReal(in_vrs, u[k].tolist())
            slave.doStep(currentCommunicationPoint=k * step_size, communicationStepSize=step_size)
            y[k] = slave.getReal(out_vrs)
        slave.terminate()
        slave.freeInstance()
    finally:
        shutil.rmtree(unzip, ignore_errors=True)
    return y


def clean_env() -> dict[str, str]:
    """Environment for a C host: no PYTHONPATH, PYTHONHOME, LD_PRELOAD, VIRTUAL_ENV."""
    return {"PATH": "/usr/bin:/bin", "LANG": "C.UTF-8"}


def compile_c_host(out: str | Path, source: str | Path | None = None, *,
                   windows: bool = False) -> Path:
    """Compile the C host ``tests/support/c_host/host.c`` with gcc.

    Parameters
    ----------
    out : str or Path
        Executable to write.
    source : str or Path, optional
        Host source; default: :data:`C_HOST_SOURCE`.
    windows : bool
        Cross-compile a Windows executable with mingw-w64 (it loads ``binaries/win64``).

    Returns
    -------
    Path
        ``out``.
    """
    source = C_HOST_SOURCE if source is None else Path(source)
    if not source.is_file():
        raise FileNotFoundError(f"C host source {source} not found; pass source=")
    out = Path(out)
    cmd = (["x86_64-w64-mingw32-gcc", "-O2", "-Wall", "-o", str(out), str(source)] if windows
           else ["gcc", "-O2", "-Wall", "-o", str(out), str(source), "-ldl"])
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise HostError(f"compiling the C host failed: {proc.stderr.strip()}")
    return out


def run_c_host(fmu: str | Path, *, outputs: Sequence[str], step_size: float, n_steps: int,
               inputs: Mapping[str, object] | None = None,
               parameters: Mapping[str, float] | None = None,
               host: str | Path | None = None, wrapper: Sequence[str] = (),
               env: Mapping[str, str] | None = None, windows: bool = False) -> np.ndarray:
    """Run ``fmu`` in the plain C host, in a subprocess with :func:`clean_env`.

    Parameters are as in :func:`run_fmpy`; ``host`` is a compiled host executable
    (compiled into a temporary folder when None); ``wrapper`` is a command prefix the
    host runs under (e.g. ``["valgrind", "--log-file=vg.txt"]``); ``env`` adds variables
    to the clean environment.  With ``windows`` the host is a Windows executable that
    runs the FMU's win64 binary under ``wrapper`` (``["wine"]``), given ``Z:`` paths.
    The host prints each output's bits, so the values returned are exactly the FMU's.

    Returns
    -------
    numpy.ndarray, shape (n_steps, len(outputs))

    Raises
    ------
    HostError
        If the host exits with a non-zero status (its stderr is in the message).
    """
    md, variables = _variables(fmu)
    in_names, u = _input_matrix(inputs, n_steps)
    in_vrs, out_vrs = _vrs(variables, in_names, fmu), _vrs(variables, outputs, fmu)
    par = dict(parameters or {})
    par_vrs = _vrs(variables, list(par), fmu)
    with tempfile.TemporaryDirectory(prefix="c_host_") as tmp:
        tmp = Path(tmp)
        exe = Path(host) if host is not None else compile_c_host(
            tmp / ("host.exe" if windows else "host"), windows=windows)
        here = (lambda p: "Z:" + str(p)) if windows else str
        unzip = tmp / "fmu"
        with zipfile.ZipFile(fmu) as zf:
            zf.extractall(unzip)
        input_file = tmp / "inputs.txt"
        np.savetxt(input_file, u.reshape(n_steps, -1), fmt="%.17g")
        cmd = [*wrapper, str(exe), here(unzip), md.coSimulation.modelIdentifier, md.guid,
               repr(step_size), str(n_steps), here(input_file),
               ",".join(map(str, in_vrs)) or "-", ",".join(map(str, out_vrs)),
               ",".join(f"{vr}={float(v)!r}" for vr, v in zip(par_vrs, par.values()))]
        proc = subprocess.run(cmd, capture_output=True, text=True,
                              env={**clean_env(), **(env or {})}, cwd=tmp)
    if proc.returncode != 0:
        raise HostError(f"C host run of {Path(fmu).name} failed with status {proc.returncode}: "
                        f"{proc.stderr.strip()[-2000:]}")
    rows = [line.split() for line in proc.stdout.splitlines() if line.strip()]
    y = np.array([[_value(v) for v in row] for row in rows], dtype=float)
    if y.shape != (n_steps, len(out_vrs)):
        raise HostError(f"C host printed {y.shape} values; expected {(n_steps, len(out_vrs))}")
    return y


def _value(text: str) -> float:
    """A host's printed output: a double's bits (``0x`` and 16 hex digits) or a number."""
    if text.startswith("0x"):
        return float(np.array(int(text, 16), dtype=np.uint64).view(np.float64))
    return float(text)


def run_libcosim(fmu: str | Path, *, outputs: Sequence[str], step_size: float, n_steps: int,
                 inputs: Mapping[str, object] | None = None,
                 parameters: Mapping[str, float] | None = None) -> np.ndarray:
    """Run ``fmu`` alone in libcosim (libcosimpy), with inputs set by an override manipulator.

    Parameters are as in :func:`run_fmpy`.  libcosim counts time in integer
    nanoseconds, so ``step_size`` must be a whole number of nanoseconds.

    libcosim runs in a fresh Python process, like a separate tool would: its slaves
    are destroyed when libcosim's objects are collected, and when that happens during
    interpreter shutdown pythonfmu touches a finalising interpreter.  A child process
    that exits without teardown once its results are written keeps the caller safe.

    Returns
    -------
    numpy.ndarray, shape (n_steps, len(outputs))
    """
    in_names, u = _input_matrix(inputs, n_steps)
    with tempfile.TemporaryDirectory(prefix="libcosim_run_") as tmp:
        job = Path(tmp) / "job.npz"
        out = Path(tmp) / "out.npy"
        np.savez(job, u=u, spec=np.array(json.dumps({
            "fmu": str(Path(fmu).resolve()), "outputs": list(outputs), "step_size": step_size,
            "n_steps": n_steps, "in_names": in_names, "parameters": dict(parameters or {}),
            "out": str(out)})))
        proc = subprocess.run([sys.executable, __file__, str(job)],
                              capture_output=True, text=True, timeout=600)
        if proc.returncode != 0 or not out.is_file():
            raise HostError(f"libcosim run of {Path(fmu).name} failed (exit "
                            f"{proc.returncode}): {proc.stderr.strip()[-2000:]}")
        return np.load(out, allow_pickle=False)


def _run_libcosim_here(fmu, *, outputs, step_size, n_steps, inputs=None, parameters=None):
    """Body of :func:`run_libcosim`, run in the child process."""
    # libcosimpy is an optional test dependency, imported only in the child process
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    step_ns = round(step_size * 1e9)
    if abs(step_ns - step_size * 1e9) > 1e-6 * max(step_ns, 1):
        raise ValueError(f"step_size {step_size} s is not a whole number of nanoseconds")
    _, variables = _variables(fmu)
    in_names, u = _input_matrix(inputs, n_steps)
    in_vrs, out_vrs = _vrs(variables, in_names, fmu), _vrs(variables, outputs, fmu)
    par = dict(parameters or {})
    execution = CosimExecution.from_step_size(step_ns)
    index = execution.add_local_slave(CosimLocalSlave(fmu_path=str(Path(fmu).resolve()),
                                                      instance_name="slave"))
    if index < 0:
        raise HostError(f"libcosim could not load {Path(fmu).name}")
    for name, value in par.items():
        execution.real_initial_value(index, variables[name].valueReference, float(value))
    if in_vrs:
        for vr, value in zip(in_vrs, u[0]):
            execution.real_initial_value(index, vr, float(value))
    observer = CosimObserver.create_last_value()
    manipulator = CosimManipulator.create_override()
    execution.add_observer(observer)
    execution.add_manipulator(manipulator)
    y = np.empty((n_steps, len(out_vrs)))
    for k in range(n_steps):
        if in_vrs:
            manipulator.slave_real_values(index, in_vrs, u[k].tolist())
        if not execution.step(1):
            raise HostError(f"libcosim step {k} of {Path(fmu).name} failed")
        y[k] = observer.last_real_values(index, out_vrs)
    return y


def _child_main(job_path: str) -> None:
    with np.load(job_path, allow_pickle=False) as job:
        spec = json.loads(str(job["spec"]))
        u = job["u"]
    inputs = {name: u[:, i] for i, name in enumerate(spec["in_names"])}
    y = _run_libcosim_here(spec["fmu"], outputs=spec["outputs"], step_size=spec["step_size"],
                           n_steps=spec["n_steps"], inputs=inputs or None,
                           parameters=spec["parameters"] or None)
    np.save(spec["out"], y)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)  # skip interpreter teardown with libcosim slaves still alive


if __name__ == "__main__":
    _child_main(sys.argv[1])
