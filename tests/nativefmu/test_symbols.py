"""Every native FMU and container exports its FMI functions and nothing else.

Before, a native FMU exported 33 internal symbols (``jf_*``, ``model_*``) and a
container 406 more (``uN_*``, ``fastloop_*``); loaded into one symbol scope
(``RTLD_GLOBAL``, ``LD_PRELOAD``, as some hosts do) a second FMU bound to the first one's
functions and refused its own GUID.  Reference: ``nm -D --defined-only`` of each
binary, and a process that loads one FMU ``RTLD_GLOBAL`` and then runs another.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from .test_fmi3 import dirs  # noqa: F401  (the FMI 3.0 builds of the session)

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[2]
NATIVE = ("truss10_structure", "controller_truss10_strain_diag", "piezo_p243_40",
          "excitation", "acs", "disturbance")


def _binary(fmu: Path, tmp: Path) -> Path:
    with zipfile.ZipFile(fmu) as z:
        name = next(n for n in z.namelist() if n.endswith(".so"))
        out = tmp / fmu.stem / Path(name).name
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_bytes(z.read(name))
    return out


def _exported(lib: Path) -> list:
    out = subprocess.run(["nm", "-D", "--defined-only", str(lib)], capture_output=True,
                         text=True, check=True).stdout
    return [ln.split()[-1] for ln in out.splitlines() if len(ln.split()) == 3]


@pytest.fixture(scope="module")
def binaries(suite_fmus, suite_fmu_dir, dirs, suite_container,  # noqa: F811
             tmp_path_factory):
    """{label: .so} of FMI 2.0 and 3.0 native FMUs and of both containers."""
    suite_fmus(*NATIVE)
    tmp = tmp_path_factory.mktemp("symbols")
    out = {f"{m} (FMI 2.0)": _binary(suite_fmu_dir / f"{m}.fmu", tmp / "2") for m in NATIVE}
    out.update({f"{m} (FMI 3.0)": _binary(dirs[3] / f"{m}.fmu", tmp / "3") for m in NATIVE})
    for fmi in (2, 3):
        fmu = suite_container(REPO / "scenarios" / "truss10_closed_loop.toml", fmi)
        out[f"container (FMI {fmi}.0)"] = _binary(fmu, tmp / f"c{fmi}")
    return out


def test_only_fmi_functions_are_exported(binaries):
    for label, lib in binaries.items():
        names = _exported(lib)
        prefix = "fmi3" if "FMI 3.0" in label else "fmi2"
        assert len(names) >= 30, (label, names)
        assert all(n.startswith(prefix) for n in names), (label, [n for n in names
                                                                  if not n.startswith(prefix)])
        assert f"{prefix}DoStep" in names


_HOST = r"""
import ctypes, sys
from fmpy import simulate_fmu
ctypes.CDLL(sys.argv[1], mode=ctypes.RTLD_GLOBAL)     # one FMU in the global scope
res = simulate_fmu(sys.argv[2], stop_time=0.05, output_interval=1e-3)
print(len(res))
"""


@pytest.mark.parametrize("first, second", [
    ("truss10_structure", "controller_truss10_strain_diag"),
    ("controller_truss10_strain_diag", "piezo_p243_40"),
])
def test_an_fmu_runs_beside_another_loaded_into_the_global_scope(suite_fmu_dir, binaries,
                                                                 tmp_path, first, second):
    fmu = tmp_path / f"{second}.fmu"
    shutil.copy2(suite_fmu_dir / f"{second}.fmu", fmu)
    lib = binaries[f"{first} (FMI 2.0)"]
    proc = subprocess.run([sys.executable, "-c", _HOST, str(lib), str(fmu)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split()[-1] == "51"


def _dll_exports(dll: Path) -> list:
    """Names in a DLL's export table (``objdump -p``)."""
    text = subprocess.run(["x86_64-w64-mingw32-objdump", "-p", str(dll)], capture_output=True,
                          text=True, check=True).stdout
    table = text.split("[Ordinal/Name Pointer] Table", 1)[1]
    return re.findall(r"(?m)^\s*\[\s*\d+\]\s+(\S+)\s*$", table)


@pytest.mark.skipif(shutil.which("x86_64-w64-mingw32-gcc") is None or
                    shutil.which("x86_64-w64-mingw32-objdump") is None,
                    reason="mingw-w64 is not installed (make native-deps): no win64 binary")
@pytest.mark.parametrize("fmi", [2, 3])
def test_a_windows_container_exports_only_its_fmi_functions(suite_container, tmp_path, fmi):
    """A DLL exports what its sources mark dllexport: only the FMI functions (a guard:
    the inner units' renamed ones, u1_fmi2DoStep, are not marked; this held before the
    Linux version script too).  The run's container, written with mingw-w64 installed."""
    fmu = suite_container(REPO / "scenarios" / "truss10_closed_loop.toml", fmi)
    with zipfile.ZipFile(fmu) as z:
        name = next(n for n in z.namelist() if n.endswith(".dll"))
        (tmp_path / "x.dll").write_bytes(z.read(name))
    names = _dll_exports(tmp_path / "x.dll")
    prefix = f"fmi{fmi}"
    assert len(names) >= 30 and f"{prefix}DoStep" in names
    assert [n for n in names if not n.startswith(prefix)] == []
