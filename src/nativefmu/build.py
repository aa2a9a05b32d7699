"""Build native (C99) FMUs that swap in place for the project's Python FMUs.

:func:`build_native` builds the Python FMU of a spec (with :func:`fmutools.build.build_fmu`)
only to read its ``modelDescription.xml``, then writes an FMU with the same file name,
modelIdentifier, variables, value references, units, causality, variability and
ModelStructure, whose model code is the C of ``nativefmu/csrc`` plus a generated
``model_config.h`` (the variable table):

- ``sources/``: every ``.c`` and ``.h`` needed, listed in ``<SourceFiles>``; compiles
  with libc and libm only, ``-std=c99 -Wall -Wextra -Werror -pedantic``;
- ``binaries/linux64/<id>.so`` built here with gcc, and ``binaries/win64/<id>.dll``
  when ``x86_64-w64-mingw32-gcc`` is on the PATH;
- ``resources/<kernel>.dat``: the model data (:mod:`nativefmu.data`).

With ``fmi=3`` the same kernels make an FMI 3.0 co-simulation FMU: ``fmi3.c`` replaces
``fmi2.c`` over the shared core ``jfcore.c``, the model description is the FMI 2.0 one
written the FMI 3.0 way (:mod:`nativefmu.fmi3xml`), and ``sources/buildDescription.xml``
lists the C files.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import uuid
import zipfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from importlib import resources as _res
from pathlib import Path
from xml.etree import ElementTree as ET

import fmpy

from fmutools.atomic import replaced_when_done
from fmutools.build import FmuSpec, build_fmu
from fmutools.registry import collect_specs
from fmutools.validate import validate_fmu
from nativefmu.data import KERNELS, kernel_of, model_data, zip_compression
from nativefmu.fmi3xml import build_description, fmi3_model_description
from structfmu.fmuspec import build_structure_fmu, spec_from_npz

__all__ = ["CFLAGS", "C_STRING_MAX", "FMI_VERSIONS", "c_string", "NativeBuildError", "NativeReport", "build_native", "build_all_native",
           "build_native_structure",
           "compile_sources", "mingw_compiler", "native_model_description", "source_files"]

#: Flags the sources must compile with (libc and libm only); no fused multiply-add and
#: no fast-math rewriting, so that with jfmath.c's own sin, exp, log, ... the Linux and
#: the Windows binaries give the same bits.
CFLAGS = ("-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-ffp-contract=off",
          "-fno-fast-math")
#: The linker version script of a Linux binary: the FMI functions global, the rest local.
EXPORTS_SCRIPT = "{\n  global: fmi2*; fmi3*;\n  local: *;\n};\n"
#: The FMI 2.0 and 3.0 headers shipped with fmpy (Modelica Association, BSD licence).
_FMI_HEADERS = {2: ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h"),
                3: ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")}
#: The FMI versions a native FMU can be built for.
FMI_VERSIONS = (2, 3)
#: Binary folders (Linux, Windows) of each FMI version.
_PLATFORMS = {2: ("linux64", "win64"), 3: ("x86_64-linux", "x86_64-windows")}
_COMMON = ("jfcore.c", "data.c", "linalg.c", "jfmath.c")
#: Headers of the API layer of each FMI version (fmi3.c's refused functions).
_LAYER_HEADERS = {2: (), 3: ("fmi3_refusals.h",)}
_GENERATION_TOOL = "jitterfmu nativefmu 1"
_TYPES = {"Real": "JF_REAL", "Integer": "JF_INTEGER", "Boolean": "JF_BOOLEAN",
          "String": "JF_STRING"}
_CAUSALITIES = {"parameter": "JF_PARAMETER", "input": "JF_INPUT", "output": "JF_OUTPUT",
                "local": "JF_LOCAL"}


class NativeBuildError(RuntimeError):
    """A native FMU could not be built."""


def mingw_compiler() -> str | None:
    """Path of ``x86_64-w64-mingw32-gcc``, or None when it is not installed."""
    return shutil.which("x86_64-w64-mingw32-gcc")


def _fmi_header_dir() -> Path:
    return Path(fmpy.__file__).parent / "c-code"


#: The longest string literal an ISO C99 compiler must accept (-pedantic refuses more).
C_STRING_MAX = 4095


def c_string(text: str, what: str = "a name") -> str:
    """``text`` as a C99 string literal, for the generated sources.

    Printable ASCII stays as it is; every other byte of its UTF-8 (a newline, a control
    character, a non-ASCII letter), the quote, the backslash and ``?`` (``??/`` is a
    trigraph for a backslash in C99) become three-digit octal escapes.

    Parameters
    ----------
    text : str
        The string.
    what : str
        What it is, for the message (``"String parameter 'file' start value"``).

    Raises
    ------
    NativeBuildError
        When the literal would be longer than :data:`C_STRING_MAX` bytes.
    """
    data = str(text).encode("utf-8")
    if len(data) > C_STRING_MAX:
        raise NativeBuildError(f"{what} is {len(data)} bytes long, more than the "
                               f"{C_STRING_MAX} a C string of a native FMU's sources holds; "
                               "shorten it")
    return '"' + "".join(chr(b) if 32 <= b < 127 and chr(b) not in '"\\?' else f"\\{b:03o}"
                         for b in data) + '"'


#: The range of a Real that declares none (the largest finite double).
_BIG = sys.float_info.max


def _model_config(root: ET.Element) -> str:
    """``model_config.h``: identifier, GUID and the variable table of ``root``."""
    model_id = root.find("CoSimulation").get("modelIdentifier")
    rows, max_vr, first = [], -1, {}
    for sv in root.iterfind("ModelVariables/ScalarVariable"):
        typed = next(child for child in sv if child.tag in _TYPES)
        vr = int(sv.get("valueReference"))
        max_vr = max(max_vr, vr)
        first.setdefault(vr, len(rows))
        start = typed.get("start")
        number, text = "0.0", "NULL"
        if typed.tag == "Real" and start is not None:
            number = float(start).hex()
        elif typed.tag == "Integer" and start is not None:
            number = f"{int(start)}.0"
        elif typed.tag == "Boolean" and start is not None:
            number = "1.0" if start in ("true", "1") else "0.0"
        elif typed.tag == "String":
            text = c_string(start or "", f"String {sv.get('name')!r} start value")
        tunable = int(sv.get("variability", "continuous") != "fixed"
                      and sv.get("variability") != "constant")
        causality = _CAUSALITIES.get(sv.get("causality", "local"), "JF_OTHER")
        lo, hi = (float(typed.get(k, default)).hex() if typed.tag == "Real" else
                  float(default).hex() for k, default in (("min", -_BIG), ("max", _BIG)))
        rows.append(f"    {{{c_string(sv.get('name'))}, {vr}u, {_TYPES[typed.tag]}, "
                    f"{causality}, {tunable}, {number}, {text}, {lo}, {hi}}},")
    index = [first.get(v, -1) for v in range(max_vr + 1)] + [-1]
    return "\n".join([
        f"/* Generated from the model description of {model_id} (do not edit). */",
        "#ifndef MODEL_CONFIG_H",
        "#define MODEL_CONFIG_H",
        f"#define JF_MODEL_IDENTIFIER {c_string(model_id)}",
        f"#define JF_GUID {c_string(root.get('guid'))}",
        f"#define JF_N_VARS {len(rows)}u",
        f"#define JF_N_VR {max_vr + 1}u",
        "static const JfVar JF_VARS[JF_N_VARS] = {",
        *rows,
        "};",
        "/* per value reference, its first row of JF_VARS (-1: none): a lookup per call;",
        "   one entry more, -1, so that the table is never empty */",
        "static const int JF_VAR_INDEX[JF_N_VR + 1u] = {",
        *[f"    {', '.join(str(index[i:i + 16]).strip('[]').split(', '))},"
          for i in range(0, len(index), 16)],
        "};",
        "#endif",
        "",
    ])


def _check_fmi(fmi: int) -> int:
    if fmi not in FMI_VERSIONS:
        raise NativeBuildError(f"FMI version {fmi!r} is not one a native FMU is built for; "
                               f"expected one of {', '.join(map(str, FMI_VERSIONS))}")
    return fmi


def source_files(kernel: str, fmi: int = 2) -> tuple[str, ...]:
    """The ``.c`` files of a native FMU with C kernel ``kernel``, in compile order.

    Parameters
    ----------
    kernel : str
        C kernel name (``structure``, ``piezo``, ...).
    fmi : {2, 3}
        FMI version of the API layer (``fmi2.c`` or ``fmi3.c``).
    """
    return (f"fmi{_check_fmi(fmi)}.c", *_COMMON, f"{kernel}.c")


def native_model_description(python_xml: bytes, kernel: str) -> ET.Element:
    """The native FMU's model description made from the Python FMU's.

    Variables, units, ModelStructure and the DefaultExperiment are kept as they are;
    the GUID is a new one derived from the Python FMU's (the binaries differ), the
    generation tool is this package, ``needsExecutionTool`` is false and
    ``<SourceFiles>`` lists the C sources.

    Parameters
    ----------
    python_xml : bytes
        ``modelDescription.xml`` of the Python FMU.
    kernel : str
        C kernel name (``structure``, ``piezo``, ``controller``, ``excitation``).
    """
    root = ET.fromstring(python_xml)
    if root.get("fmiVersion") != "2.0" or root.find("CoSimulation") is None:
        raise NativeBuildError("the Python FMU's model description is not FMI 2.0 "
                               "co-simulation")
    root.set("guid", "{" + str(uuid.uuid5(uuid.NAMESPACE_URL,
                                          "jitterfmu-native:" + root.get("guid", ""))) + "}")
    root.set("generationTool", _GENERATION_TOOL)
    cs = root.find("CoSimulation")
    cs.set("needsExecutionTool", "false")
    for old in cs.findall("SourceFiles"):
        cs.remove(old)
    files = ET.SubElement(cs, "SourceFiles")
    for name in source_files(kernel):
        ET.SubElement(files, "File", {"name": name})
    return root


def _sources(root: ET.Element, kernel: str, fmi: int = 2) -> dict[str, bytes]:
    """Every file of ``sources/``: C files, headers, ``model_config.h`` (from FMI 2.0
    ``root``), and for FMI 3.0 ``buildDescription.xml``."""
    csrc = _res.files("nativefmu") / "csrc"
    out = {name: (_fmi_header_dir() / name).read_bytes() for name in _FMI_HEADERS[fmi]}
    for name in (*source_files(kernel, fmi), "jfmu.h", "jfmath.h", "jfcore.h", "jfstate.h",
                 *_LAYER_HEADERS[fmi]):
        out[name] = (csrc / name).read_bytes()
    config = root if fmi == 2 else _with_guid(root, fmi3_model_description(root)
                                               .get("instantiationToken"))
    out["model_config.h"] = _model_config(config).encode()
    if fmi == 3:
        model_id = root.find("CoSimulation").get("modelIdentifier")
        out["buildDescription.xml"] = build_description(model_id, source_files(kernel, 3))
    return out


def _with_guid(root: ET.Element, guid: str) -> ET.Element:
    copy = ET.fromstring(ET.tostring(root))
    copy.set("guid", guid)
    return copy


def compile_sources(sources: Path, out: Path, *, compiler: str = "gcc",
                    windows: bool = False) -> Path:
    """Compile a native FMU's ``sources/`` folder into a shared library.

    Parameters
    ----------
    sources : Path
        Folder with the ``.c`` and ``.h`` files (the ``.c`` files are all compiled).
    out : Path
        Library to write (``.so`` or ``.dll``).
    compiler : str
        C compiler command.
    windows : bool
        Cross-compile a DLL (no ``-fPIC``, libgcc linked statically).

    Raises
    ------
    NativeBuildError
        With the compiler's messages, if it fails.
    """
    c_files = sorted(p.name for p in Path(sources).glob("*.c"))
    pic = [] if windows else ["-fPIC"]
    extra = ["-static-libgcc"] if windows else []
    with tempfile.TemporaryDirectory(prefix="nativefmu_link_") as tmp:
        if not windows:
            # only the FMI functions are global: a host that loads two FMUs into one
            # symbol scope (RTLD_GLOBAL, LD_PRELOAD) never binds one to the other's helpers
            script = Path(tmp) / "exports.map"
            script.write_text(EXPORTS_SCRIPT)
            extra = [f"-Wl,--version-script={script}"]
        # relative file names and a neutral cwd: no path of this machine in the binary
        cmd = [compiler, *CFLAGS, "-O2", "-shared", *pic, *extra, "-o",
               str(Path(out).resolve()), *c_files, "-lm"]
        proc = subprocess.run(cmd, cwd=sources, capture_output=True, text=True)
    if proc.returncode != 0:
        raise NativeBuildError(f"{compiler} failed on {Path(out).name}: "
                               f"{proc.stderr.strip()[-3000:]}")
    return Path(out)


def _from_python_fmu(spec: FmuSpec, python_fmu: Path | None) -> tuple[FmuSpec, bytes]:
    """The Python FMU's model description, and ``spec`` with the FMU's own resources.

    The model data (reduced model, control law) are taken from the Python FMU, not
    recomputed, so both flavours carry the same model even if the code that makes it
    changed since the Python FMU was built.
    """
    if python_fmu is None:
        with tempfile.TemporaryDirectory(prefix="nativefmu_py_") as tmp:
            return _from_python_fmu(spec, build_fmu(spec, tmp, c_loader=False))
    with zipfile.ZipFile(python_fmu) as z:
        xml = z.read("modelDescription.xml")
        names = set(z.namelist())
        resources = {name: z.read(f"resources/{name}") if f"resources/{name}" in names else src
                     for name, src in spec.resources.items()}
    return replace(spec, resources=resources), xml


def build_native(spec: FmuSpec, out_dir: str | Path, *, python_fmu: str | Path | None = None,
                 windows: bool | None = None, fmi: int = 2) -> Path:
    """Build the native FMU of ``spec`` into ``out_dir``.

    Parameters
    ----------
    spec : FmuSpec
        The Python FMU's spec (from a package's ``fmuspec``).
    out_dir : str or Path
        Destination folder (created if missing).
    python_fmu : str or Path, optional
        An already built Python FMU of ``spec`` to take the model description from;
        built in a temporary folder when omitted.
    windows : bool, optional
        Also build ``binaries/win64``; None: when the mingw-w64 compiler is installed.
    fmi : {2, 3}
        FMI version: 2.0 (``binaries/linux64``, ``win64``) or 3.0 (the same kernels;
        ``binaries/x86_64-linux``, ``x86_64-windows``).

    Returns
    -------
    Path
        ``out_dir / f"{spec.model_identifier}.fmu"``.

    Raises
    ------
    nativefmu.data.NativeUnsupportedError
        If the spec's slave has no C kernel.
    NativeBuildError
        If compiling fails, or ``windows=True`` without the cross compiler.
    """
    kernel = kernel_of(spec)
    _check_fmi(fmi)
    mingw = mingw_compiler()
    if windows and mingw is None:
        raise NativeBuildError("windows=True needs x86_64-w64-mingw32-gcc (Debian package "
                               "gcc-mingw-w64-x86-64); install it or pass windows=None")
    windows = mingw is not None if windows is None else windows
    spec, python_xml = _from_python_fmu(spec, Path(python_fmu) if python_fmu else None)
    root = native_model_description(python_xml, kernel)
    vrs = {sv.get("name"): int(sv.get("valueReference"))
           for sv in root.iterfind("ModelVariables/ScalarVariable")}
    model_id = spec.model_identifier
    if root.find("CoSimulation").get("modelIdentifier") != model_id:
        raise NativeBuildError(f"Python FMU has modelIdentifier "
                               f"{root.find('CoSimulation').get('modelIdentifier')!r}; "
                               f"expected {model_id!r}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / f"{model_id}.fmu"
    with tempfile.TemporaryDirectory(prefix="nativefmu_") as tmp:
        src = Path(tmp) / "sources"
        src.mkdir()
        for name, content in _sources(root, kernel, fmi).items():
            (src / name).write_bytes(content)
        linux, win = _PLATFORMS[fmi]
        binaries = {f"binaries/{linux}/{model_id}.so":
                    compile_sources(src, Path(tmp) / f"{model_id}.so")}
        if windows:
            binaries[f"binaries/{win}/{model_id}.dll"] = compile_sources(
                src, Path(tmp) / f"{model_id}.dll", compiler=mingw, windows=True)
        xml = ET.tostring(root if fmi == 2 else fmi3_model_description(root),
                          encoding="UTF-8", xml_declaration=True)
        with replaced_when_done(target) as part, \
                zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr("modelDescription.xml", xml)
            for name in sorted(p.name for p in src.iterdir()):
                z.write(src / name, f"sources/{name}")
            for arcname, path in binaries.items():
                z.write(path, arcname)
            for name, content in model_data(spec, vrs).items():
                z.writestr(f"resources/{name}", content, zip_compression(name))
    return target


@dataclass(frozen=True)
class NativeReport:
    """Result of :func:`build_all_native`: built FMUs, skipped models, problems."""

    fmus: tuple[Path, ...]
    skipped: tuple[str, ...]
    problems: tuple[str, ...]

    def __iter__(self):
        return iter((self.fmus, self.skipped, self.problems))


def build_all_native(out_dir: str | Path, models: Sequence[str] | None = None, *,
                     progress: Callable[[str], None] | None = None,
                     python_dir: str | Path | None = None, fmi: int = 2) -> NativeReport:
    """Build and validate the native FMU of every model that has a C kernel.

    Parameters
    ----------
    out_dir : str or Path
        Destination folder.
    models : sequence of str, optional
        modelIdentifiers; None for all of the project's FMUs.
    progress : callable, optional
        Called with one line per FMU.
    python_dir : str or Path, optional
        Folder of the already built Python FMUs to take the model descriptions from;
        each is built in a temporary folder when omitted.
    fmi : {2, 3}
        FMI version of the FMUs.

    Returns
    -------
    NativeReport
        Built FMUs, models without a C kernel (skipped, named) and validation problems.
    """
    specs = collect_specs(models)
    fmus, skipped, problems = [], [], []
    for i, spec in enumerate(specs, start=1):
        if spec.slave_class not in KERNELS:
            skipped.append(spec.model_identifier)
            if progress is not None:
                progress(f"[{i}/{len(specs)}] {spec.model_identifier}: no native kernel yet, "
                         "skipped")
            continue
        twin = None if python_dir is None else Path(python_dir) / f"{spec.model_identifier}.fmu"
        path = build_native(spec, out_dir, python_fmu=twin, fmi=fmi)
        found = validate_fmu(path, strict=True)
        fmus.append(path)
        problems += found
        if progress is not None:
            status = "ok" if not found else f"{len(found)} problem(s)"
            flavour = "native" if fmi == 2 else "native, FMI 3.0"
            progress(f"[{i}/{len(specs)}] {spec.model_identifier}: {path} ({flavour}) {status}")
    return NativeReport(tuple(fmus), tuple(skipped), tuple(problems))


def build_native_structure(npz: str | Path, out_dir: str | Path,
                           model_identifier: str | None = None, fmi: int = 2) -> NativeReport:
    """Build and validate the native structure FMU of a reduced model file.

    The native twin of :func:`structfmu.fmuspec.build_structure_fmu` (same name rule:
    ``<npz stem>_structure`` unless ``model_identifier``).

    Parameters
    ----------
    npz : str or Path
        A file written by ``ReducedModel.save`` (e.g. by ``jitterfmu import-nastran``).
    out_dir : str or Path
        Destination folder.
    model_identifier : str, optional
        FMI modelIdentifier and file stem.
    fmi : {2, 3}
        FMI version of the FMU.

    Returns
    -------
    NativeReport
        The FMU path and its validation problems.
    """
    with tempfile.TemporaryDirectory(prefix="nativefmu_py_") as tmp:
        python_fmu = build_structure_fmu(npz, tmp, model_identifier).fmus[0]
        spec = spec_from_npz(npz, python_fmu.stem)
        path = build_native(spec, out_dir, python_fmu=python_fmu, fmi=fmi)
    return NativeReport((path,), (), tuple(validate_fmu(path, strict=True)))
