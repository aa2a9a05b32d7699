"""The native FMUs' own transcendental functions (``csrc/jfmath.c``).

Before, the FMUs called the C library's ``sin``, ``cos``, ``exp``, ...: msvcrt's differ from
glibc's by an ulp for a few hundred arguments in 20,000, so the win64 container under
wine differed from linux64 (truss: 1 value in 12,006; EOS: 1490 of 2000 rows).  References:
the exact value (mpmath at 200 bits) for the accuracy; the win64 build run under wine,
bit for bit, for the sameness; glibc's functions (the same FMUs built with a libm shim in
place of jfmath.c) for the FMUs' results.
"""

from __future__ import annotations

import math
import shutil
import subprocess
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest

from nativefmu.build import CFLAGS

REPO = Path(__file__).resolve().parents[2]
CSRC = REPO / "src" / "nativefmu" / "csrc"
FUNCS = ("sin", "cos", "tan", "exp", "expm1", "log", "log1p")
#: glibc's functions, in the order the driver prints them after ours
LIBM = ("sin", "cos", "exp")
TRUSS = ["truss10_structure", "piezo_p243_40", "piezo_p243_30", "controller_truss10_strain_diag",
         "controller_truss10_strain_long", "excitation"]
EOS = ["eos_testbed_structure", "acs", "disturbance", "piezo_p845_37",
       "controller_testbed_isolation", "controller_eos_isolation"]

#: Reads doubles as hex bits, one a line; prints each function of each as hex bits.
DRIVER = r"""
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include "jfmath.h"
static void put(double y) {
    uint64_t b; memcpy(&b, &y, sizeof b);
    printf(" %08lx%08lx", (unsigned long)(b >> 32), (unsigned long)(b & 0xffffffffu));
}
int main(int argc, char **argv) {
    unsigned long hi, lo; FILE *f = fopen(argv[1], "r"); (void)argc;
    while (f && fscanf(f, "%8lx%8lx", &hi, &lo) == 2) {
        uint64_t b = ((uint64_t)hi << 32) | lo; double x; memcpy(&x, &b, sizeof x);
        put(jm_sin(x)); put(jm_cos(x)); put(jm_tan(x)); put(jm_exp(x)); put(jm_expm1(x));
        put(jm_log(x)); put(jm_log1p(x)); put(sin(x)); put(cos(x)); put(exp(x));
        printf("\n");
    }
    return 0;
}
"""

#: jfmath.c replaced by the C library's functions (the FMUs as they were built before).
LIBM_SHIM = """#include <math.h>
#include "jfmath.h"
double jm_sin(double x) { return sin(x); }
double jm_cos(double x) { return cos(x); }
double jm_tan(double x) { return tan(x); }
double jm_exp(double x) { return exp(x); }
double jm_expm1(double x) { return expm1(x); }
double jm_log(double x) { return log(x); }
double jm_log1p(double x) { return log1p(x); }
int jm_ceil_log2(double v) { return (int)ceil(log2(v)); }
"""


def _arguments(n: int, seed: int = 7) -> np.ndarray:
    """Arguments of every kind: the trigonometric range and past it to 1e300, near
    multiples of pi/2, exp's range, tiny ones, logarithms' positive range."""
    rng = np.random.default_rng(seed)
    k = n // 8
    sign = rng.choice([-1.0, 1.0], k)
    near = np.arange(1, k + 1) * (math.pi / 2) * (1 + rng.uniform(-1e-15, 1e-15, k))
    return np.concatenate([
        rng.uniform(-7, 7, k), rng.uniform(-1e5, 1e5, k), sign * 10 ** rng.uniform(5, 300, k),
        near, rng.uniform(-745, 709.7, k), sign * 10 ** rng.uniform(-300, 0, k),
        10 ** rng.uniform(-307, 308, k), rng.uniform(-1, 2, n - 7 * k)])


def _compile(out: Path, sources: list, compiler: str = "gcc") -> Path:
    cmd = [compiler, *CFLAGS, "-O2", "-I", str(CSRC), "-o", str(out), *map(str, sources), "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return out


def _bits(x: np.ndarray) -> list:
    return [f"{int(b):016x}" for b in np.asarray(x, float).view(np.uint64)]


def _run_driver(cmd: list, args_file: Path, env=None) -> np.ndarray:
    """(n, 10) results of the driver: ours (7 functions), then libm's sin, cos, exp."""
    proc = subprocess.run([*cmd, str(args_file) if env is None else "Z:" + str(args_file)],
                          capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows = [[int(v, 16) for v in line.split()] for line in proc.stdout.splitlines()]
    return np.array(rows, dtype=np.uint64)


@pytest.fixture(scope="module")
def linux_results(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("jfmath")
    (tmp / "driver.c").write_text(DRIVER)
    exe = _compile(tmp / "driver", [tmp / "driver.c", CSRC / "jfmath.c"])
    x = _arguments(20000)
    (tmp / "args.txt").write_text("\n".join(_bits(x)) + "\n")
    return tmp, x, _run_driver([str(exe)], tmp / "args.txt")


def _mpmath():
    return pytest.importorskip("mpmath", reason="mpmath (a test dependency: pip install "
                               "'.[test]') gives the exact values")


def _ulps(y: float, exact) -> float:
    """|y - exact| in ulps of the exact value (its double's ulp)."""
    mpmath = _mpmath()
    e = float(exact)
    if math.isinf(e) or math.isnan(e) or e == 0.0:
        return 0.0 if (y == e or (math.isnan(y) and math.isnan(e))) else math.inf
    return float(abs(mpmath.mpf(y) - exact) / math.ulp(e))


@pytest.mark.parametrize("name", FUNCS)
def test_each_function_is_within_one_ulp_of_the_exact_value(linux_results, name):
    """Over 2,000 of the arguments (every kind) the worst error is below 1 ulp; the
    functions are deterministic, so this bounds what the FMUs compute."""
    mpmath = _mpmath()
    _, x, res = linux_results
    col = FUNCS.index(name)
    y = res[:, col].view(np.float64)
    exact = {"sin": mpmath.sin, "cos": mpmath.cos, "tan": mpmath.tan, "exp": mpmath.exp,
             "expm1": mpmath.expm1, "log": mpmath.log, "log1p": mpmath.log1p}[name]
    pick = np.random.default_rng(3).choice(len(x), 2000, replace=False)
    worst, checked = 0.0, 0
    with mpmath.workprec(200):
        for i in pick:
            xi = float(x[i])
            if name in ("log", "log1p") and xi <= (0.0 if name == "log" else -1.0):
                assert math.isnan(y[i]) or y[i] == -math.inf
                continue
            worst = max(worst, _ulps(float(y[i]), exact(mpmath.mpf(xi))))
            checked += 1
    assert checked > 1000
    assert worst < 1.0, f"{name}: {worst:.3f} ulp"


def test_special_values(tmp_path):
    """IEEE's answers at the edges (what the C library returns there)."""
    import ctypes

    lib_path = tmp_path / "jfmath.so"
    proc = subprocess.run(["gcc", *CFLAGS, "-O2", "-fPIC", "-shared", "-o", str(lib_path),
                           str(CSRC / "jfmath.c")], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    lib = ctypes.CDLL(str(lib_path))
    f = {}
    for name in FUNCS:
        f[name] = getattr(lib, f"jm_{name}")
        f[name].restype, f[name].argtypes = ctypes.c_double, [ctypes.c_double]
    inf, nan = math.inf, math.nan
    for name in ("sin", "cos", "tan"):
        assert math.isnan(f[name](inf)) and math.isnan(f[name](-inf)) and math.isnan(f[name](nan))
    assert math.copysign(1, f["sin"](-0.0)) == -1 and f["cos"](0.0) == 1.0
    assert f["exp"](inf) == inf and f["exp"](-inf) == 0.0 and f["exp"](710.0) == inf
    assert f["exp"](0.0) == 1.0 and f["exp"](-745.2) == 0.0 and f["exp"](-745.0) > 0.0
    assert f["expm1"](-inf) == -1.0 and f["expm1"](1e-300) == 1e-300
    assert f["log"](0.0) == -inf and math.isnan(f["log"](-1.0)) and f["log"](1.0) == 0.0
    assert f["log"](5e-324) == pytest.approx(-744.4400719213812, rel=1e-15)
    assert f["log1p"](-1.0) == -inf and math.isnan(f["log1p"](-2.0)) and f["log1p"](inf) == inf
    lib_ceil = lib.jm_ceil_log2
    lib_ceil.restype, lib_ceil.argtypes = ctypes.c_int, [ctypes.c_double]
    assert [lib_ceil(v) for v in (1.0, 2.0, 2.0000000000000004, 3.0, 0.5, 0.3, 5e-324)] == \
        [0, 1, 2, 2, -1, -1, -1074]


# ---------------------------------------------------------------- Windows, under wine

def _wine_env(prefix: Path) -> dict:
    return {"PATH": "/usr/bin:/bin", "LANG": "C.UTF-8", "HOME": str(prefix.parent),
            "WINEPREFIX": str(prefix), "WINEDEBUG": "-all"}


@pytest.fixture(scope="module")
def wine(tmp_path_factory):
    """``(command prefix, environment)`` that runs a win64 executable; skips saying why
    it cannot (no mingw-w64, no wine, or wine failing to start a test program)."""
    if shutil.which("x86_64-w64-mingw32-gcc") is None:
        pytest.skip("mingw-w64 is not installed (make native-deps): no win64 build to run")
    cmd = shutil.which("wine") or shutil.which("wine64")
    if cmd is None:
        pytest.skip("wine is not installed (make native-deps, needs root and apt-get): "
                    "the win64 binaries cannot be run here")
    tmp = tmp_path_factory.mktemp("wine")
    (tmp / "hello.c").write_text('#include <stdio.h>\nint main(void) { printf("%d\\n", 42); '
                                 'return 0; }\n')
    subprocess.run(["x86_64-w64-mingw32-gcc", "-o", str(tmp / "hello.exe"), str(tmp / "hello.c")],
                   check=True)
    env = _wine_env(tmp / "prefix")
    try:
        proc = subprocess.run([cmd, str(tmp / "hello.exe")], capture_output=True, text=True,
                              env=env, timeout=300)
    except subprocess.TimeoutExpired:
        pytest.skip("wine did not run a test program within 300 s")
    if proc.returncode != 0 or proc.stdout.strip() != "42":
        pytest.skip(f"wine cannot run a win64 program here (status {proc.returncode}): "
                    f"{proc.stderr.strip()[-300:]}")
    return [cmd], env


@pytest.mark.long   # make test-full: cross-compiles and starts wine, 10 s
@pytest.mark.slow
def test_windows_build_gives_the_same_bits_as_linux(linux_results, wine):
    """20,000 arguments, seven functions: 0 differing bits between the mingw-w64 build run
    under wine and the Linux build; the C libraries' own sin, cos and exp differ (the
    driver can see a difference)."""
    tmp, x, lin = linux_results
    exe = _compile(tmp / "driver.exe", [tmp / "driver.c", CSRC / "jfmath.c"],
                   "x86_64-w64-mingw32-gcc")
    cmd, env = wine
    win = _run_driver([*cmd, str(exe)], tmp / "args.txt", env=env)
    assert win.shape == lin.shape == (len(x), len(FUNCS) + len(LIBM))
    ours = len(FUNCS)
    assert np.count_nonzero(win[:, :ours] != lin[:, :ours]) == 0
    finite = np.isfinite(lin[:, ours:].view(np.float64))
    differ = np.count_nonzero((win[:, ours:] != lin[:, ours:]) & finite)
    assert differ > 0, "msvcrt and glibc agree everywhere: the comparison cannot fail"


def _container(scenario, out: Path, fmu_dir: Path, **kw) -> Path:
    from nativefmu.container import export_fmu

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return export_fmu(scenario, out, fmu_dir=fmu_dir, **kw)


def _scenarios():
    from orchestrator import load_scenario

    eos_on = ["dist_swir.preset=swir_cryocooler", "dist_rwa.preset=rwa",
              "dist_vnir.preset=vnir_pointing", "dist_ceres.preset=ceres_scan",
              "ctrl_iso1.gain=0.27", "ctrl_iso2.gain=0.27", "ctrl_iso3.gain=0.27",
              "ctrl_swir.gain=0.1", "ctrl_vnir.gain=0.1"]
    return {"truss": (load_scenario(REPO / "scenarios" / "truss10_closed_loop.toml"), 12.0),
            "eos": (load_scenario(REPO / "scenarios" / "eos_budget.toml").with_overrides(eos_on),
                    2.0)}


@pytest.mark.slow
@pytest.mark.long
@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("name", ["truss", "eos"])
def test_windows_container_under_wine_equals_linux_bit_for_bit(suite_fmus, suite_fmu_dir,
                                                               wine, tmp_path, name, fmi):
    """The container's win64 DLL in a Windows C host under wine, the linux64 .so in the
    same host built for Linux (FMI 2.0 and 3.0): every recorded value at every 1 ms step,
    0 differing bits (before: truss 1 value in 12,006, EOS 1490 of 2000 rows)."""
    from tests.support.hosts import compile_c_host, run_c_host

    suite_fmus(*TRUSS, *EOS)
    sc, stop = _scenarios()[name]
    fmu = _container(sc, tmp_path / f"{name}.fmu", suite_fmu_dir, windows=True, fmi=fmi)
    source = CSRC.parents[2] / "tests" / "support" / "c_host" / ("host.c" if fmi == 2
                                                                  else "host3.c")
    kw = dict(outputs=list(sc.record), step_size=1e-3, n_steps=int(round(stop / 1e-3)))
    y_linux = run_c_host(fmu, **kw, host=compile_c_host(tmp_path / "host", source))
    cmd, env = wine
    y_win = run_c_host(fmu, **kw, windows=True, wrapper=cmd, env=env,
                       host=compile_c_host(tmp_path / "host.exe", source, windows=True))
    assert y_linux.shape == y_win.shape and np.count_nonzero(np.abs(y_linux) > 0) > 100
    assert np.count_nonzero(y_linux.view(np.uint64) != y_win.view(np.uint64)) == 0


def _libm_fmus(names, src: Path, out: Path) -> Path:
    """Copies of the native FMUs whose sources/jfmath.c calls the C library instead."""
    out.mkdir(parents=True, exist_ok=True)
    for m in names:
        with zipfile.ZipFile(src / f"{m}.fmu") as zin, \
                zipfile.ZipFile(out / f"{m}.fmu", "w", zipfile.ZIP_DEFLATED) as zout:
            for item in zin.infolist():
                data = zin.read(item.filename)
                if item.filename == "sources/jfmath.c":
                    data = LIBM_SHIM.encode()
                zout.writestr(item, data)
    return out


@pytest.mark.slow
@pytest.mark.long
@pytest.mark.parametrize("name", ["truss", "eos"])
def test_containers_give_what_the_c_library_gave(suite_fmus, suite_fmu_dir, tmp_path, name):
    """The same container built with glibc's functions (as before): every recorded signal
    within 1e-12 of its peak (the container tests' tolerance against the master)."""
    from tests.support.hosts import run_c_host

    suite_fmus(*TRUSS, *EOS)
    sc, stop = _scenarios()[name]
    names = TRUSS if name == "truss" else EOS
    libm_dir = _libm_fmus(names, suite_fmu_dir, tmp_path / "libm")
    kw = dict(outputs=list(sc.record), step_size=1e-3, n_steps=int(round(stop / 1e-3)))
    ours = run_c_host(_container(sc, tmp_path / "ours.fmu", suite_fmu_dir, windows=False), **kw)
    libm_fmu = _container(sc, tmp_path / "libm.fmu", libm_dir, windows=False)
    with zipfile.ZipFile(libm_fmu) as z:
        shims = [n for n in z.namelist() if n.endswith("jfmath.c")
                 and b"return sin(x)" in z.read(n)]
    assert shims, "the container holds no libm shim: the comparison would compare ours twice"
    libm = run_c_host(libm_fmu, **kw)
    peak = np.max(np.abs(libm), axis=0)
    moving = peak > 0
    assert np.count_nonzero(moving) >= len(sc.record) // 2
    assert np.all(ours[:, ~moving] == 0)
    worst = np.max(np.abs(ours - libm)[:, moving] / peak[moving])
    assert worst <= 1e-12, worst
