"""Build FMI 2.0 co-simulation FMUs from :class:`fmukit.slave.FmuSlave` subclasses.

:func:`build_fmu` writes a generated slave script with a unique module name and a
class named after the modelIdentifier, copies the pure-Python packages the slave
needs into ``resources/`` (so the FMU carries its own code), lets pythonfmu build the
archive, then installs the C loader (:mod:`fmutools.loader`, compiled once per
configuration) as ``binaries/linux64/<modelIdentifier>.so`` with pythonfmu's binary
renamed beside it, so that C-only hosts can load the FMU.

This module is build tooling: it is never bundled into an FMU.  Only :mod:`fmukit`
(the runtime) and the slave's own packages are.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.util
import re
import shutil
import sys
import tempfile
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

from fmukit import slave as fmukit_slave
from fmukit.modeldesc import CAPABILITIES
from fmutools.atomic import replaced_when_done
from fmutools.loader import REAL_BINARY_SUFFIX, cached_loader

__all__ = ["FmuSpec", "BuildError", "BuildReport", "build_fmu", "REAL_BINARY_SUFFIX"]

_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_CLASS_PATH = re.compile(r"^[A-Za-z_][\w.]*:[A-Za-z_]\w*$")
_RESERVED = {"pythonfmu", "slavemodule.txt"}


class BuildError(RuntimeError):
    """An FMU could not be built."""


@dataclass(frozen=True)
class BuildReport:
    """Built FMUs and one line per validation problem; unpacks as ``fmus, problems``."""

    fmus: tuple[Path, ...]
    problems: tuple[str, ...]

    def __iter__(self):
        return iter((self.fmus, self.problems))


@dataclass(frozen=True)
class FmuSpec:
    """Everything needed to build one FMU.

    Parameters
    ----------
    model_identifier : str
        FMI modelIdentifier, a C identifier unique in the project (e.g.
        ``"PiezoLongeron"``).  Also the FMU file stem and the generated class name.
    slave_class : str
        Import path ``"package.module:ClassName"`` of an :class:`FmuSlave` subclass.
    resources : mapping of str to (path or bytes)
        Files copied into ``resources/`` under the given name; the slave opens them
        with ``self.resource_path(name)``.
    packages : tuple of str
        Extra top-level pure-Python packages to bundle (``fmukit`` and the slave's
        own top-level package are always bundled).
    description : str
        One-line model description.
    start_time, stop_time, step_size : float or None
        ``DefaultExperiment`` (s).
    init_kwargs : mapping of str to object
        Class attributes set on the generated slave class (e.g. a preset name the
        slave reads in ``__init__``); values must have a valid ``repr``.
    """

    model_identifier: str
    slave_class: str
    resources: Mapping[str, Path | str | bytes] = field(default_factory=dict)
    packages: tuple[str, ...] = ()
    description: str = ""
    start_time: float | None = 0.0
    stop_time: float | None = None
    step_size: float | None = None
    init_kwargs: Mapping[str, object] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not _IDENT.match(self.model_identifier):
            raise ValueError(f"model_identifier {self.model_identifier!r} is not a C "
                             "identifier; expected letters, digits and underscores")
        if not _CLASS_PATH.match(self.slave_class):
            raise ValueError(f"slave_class {self.slave_class!r} of {self.model_identifier!r} "
                             "is not of the form 'package.module:ClassName'")
        for name in self.resources:
            if "/" in name or "\\" in name or name in _RESERVED or name.endswith(".py"):
                raise ValueError(f"resource name {name!r} of {self.model_identifier!r} is "
                                 "not a plain file name (no '/', not .py, not reserved)")
        for key in self.init_kwargs:
            if not key.isidentifier():
                raise ValueError(f"init_kwargs key {key!r} of {self.model_identifier!r} is "
                                 "not an identifier")

    @property
    def module_name(self) -> str:
        """Unique name of the generated slave module inside the FMU."""
        return f"fmuslave_{self.model_identifier}"

    @property
    def bundled_packages(self) -> tuple[str, ...]:
        """Top-level packages copied into ``resources/``, in order, without repeats."""
        top = self.slave_class.split(":")[0].split(".")[0]
        out: list[str] = []
        for pkg in ("fmukit", top, *self.packages):
            if pkg not in out:
                out.append(pkg)
        return tuple(out)


def _generated_script(spec: FmuSpec) -> str:
    module, cls = spec.slave_class.split(":")
    lines = [
        f'"""Generated slave module of FMU {spec.model_identifier} (do not edit)."""',
        "from pythonfmu.default_experiment import DefaultExperiment",
        f"from {module} import {cls} as Fmi2Slave",
        "",
        "# pythonfmu 0.7 re-executes this file on every fmi2Instantiate and then releases",
        "# a reference to the module's globals that it never owned (a borrowed",
        "# reference).  Taking one reference per execution keeps the balance, otherwise",
        "# the module dict is freed after a few instantiations and the host crashes.",
        "globals().setdefault('_fmukit_globals_refs', []).append(globals())",
        "",
        "",
        # pythonfmu finds the class with the regex ``^class (\w+)\(\s*Fmi2Slave\s*\)\s*:``.
        f"class {spec.model_identifier}(Fmi2Slave):",
        f"    model_identifier = {spec.model_identifier!r}",
        f"    description = {spec.description or None!r}",
        f"    default_experiment = DefaultExperiment(start_time={spec.start_time!r}, "
        f"stop_time={spec.stop_time!r}, step_size={spec.step_size!r})",
    ]
    for key, value in spec.init_kwargs.items():
        lines.append(f"    {key} = {value!r}")
    return "\n".join(lines) + "\n"


def _package_source(name: str) -> Path:
    """Folder of package ``name``, or the ``.py`` file of a top-level module."""
    found = importlib.util.find_spec(name)
    if found is not None and found.submodule_search_locations:
        return Path(list(found.submodule_search_locations)[0])
    if found is not None and found.origin and found.origin.endswith(".py"):
        return Path(found.origin)
    raise BuildError(f"package {name!r} to bundle was not found; expected an importable "
                     "pure-Python package or module")


def _copy_package(src: Path, stage: Path) -> Path:
    if src.is_file():
        dest = stage / src.name
        shutil.copy2(src, dest)
    else:
        dest = stage / src.name
        shutil.copytree(src, dest, ignore=shutil.ignore_patterns("__pycache__", "*.pyc",
                                                                 "*.so", "*.o"))
    return dest


def build_fmu(spec: FmuSpec, out_dir: str | Path, *, c_loader: bool = True) -> Path:
    """Build the FMU described by ``spec`` into ``out_dir``.

    Parameters
    ----------
    spec : FmuSpec
        What to build.
    out_dir : str or Path
        Destination folder (created if missing).
    c_loader : bool
        Install the C loader so that C-only hosts can run the FMU (Linux only).

    Returns
    -------
    Path
        ``out_dir / f"{spec.model_identifier}.fmu"``.

    Raises
    ------
    BuildError
        If a package, resource or the compiler is missing, or pythonfmu fails.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / f"{spec.model_identifier}.fmu"
    module_name = spec.module_name
    with tempfile.TemporaryDirectory(prefix=f"fmukit_{spec.model_identifier}_") as tmp:
        tmp = Path(tmp)
        stage = tmp / "stage"
        stage.mkdir()
        script = stage / f"{module_name}.py"
        script.write_text(_generated_script(spec))
        project_files = []
        for pkg in spec.bundled_packages:
            project_files.append(_copy_package(_package_source(pkg), stage))
        for name, src in spec.resources.items():
            dest = stage / name
            if name in spec.bundled_packages:
                raise BuildError(f"resource {name!r} of {spec.model_identifier!r} clashes with "
                                 "a bundled package name")
            if isinstance(src, bytes):
                dest.write_bytes(src)
            else:
                src = Path(src)
                if not src.is_file():
                    raise BuildError(f"resource {name!r} of {spec.model_identifier!r} is "
                                     f"{src}, which is not a file")
                shutil.copy2(src, dest)
            project_files.append(dest)
        options = {k: v == "true" for k, v in CAPABILITIES.items()}
        saved_path = list(sys.path)
        # An instance of this FMU running in this process (a co-simulation before the
        # build) has its slave module under the same name in sys.modules; pythonfmu
        # would inspect that one instead of the staged script and write an FMU without
        # its Linux binary.  Set it aside for the build, then put it back.
        running = sys.modules.pop(module_name, None)
        try:
            with _installed_builder() as builder:
                built = builder.build_FMU(script, dest=tmp / "raw.fmu",
                                          project_files=project_files, **options)
        except Exception as exc:
            raise BuildError(f"pythonfmu could not build {spec.model_identifier!r}: "
                             f"{exc}") from exc
        finally:
            sys.path[:] = saved_path
            sys.modules.pop(module_name, None)
            if running is not None:
                sys.modules[module_name] = running
        loader = None
        if c_loader:  # a fresh copy: the archive entry is dated now, as the FMU's others
            loader = Path(shutil.copy(cached_loader(), tmp / "loader.so"))
        _rewrite_archive(Path(built), target, spec.model_identifier, loader)
    return target


@contextlib.contextmanager
def _installed_builder():
    """pythonfmu's ``FmuBuilder`` from the installed distribution, for one build.

    A pythonfmu FMU that ran in this process put its own bundled copy of pythonfmu (pure
    Python, without the binaries the builder copies into every FMU) in ``sys.modules``;
    building with that copy writes FMUs without binaries.  For the build the installed
    package takes its place (its builder recognising the slave base class this project's
    slaves derive from); afterwards the bundled modules are put back, so running FMUs
    keep theirs.
    """
    try:
        site = Path(metadata.distribution("pythonfmu").locate_file("")).resolve()
    except metadata.PackageNotFoundError:
        raise BuildError("pythonfmu is not installed; install the project with its "
                         "dependencies (make setup)") from None
    current = sys.modules.get("pythonfmu.builder")
    if current is not None and Path(current.__file__).resolve().is_relative_to(site):
        yield current.FmuBuilder
        return

    def ours(name):
        return name == "pythonfmu" or name.startswith("pythonfmu.")

    saved = {n: m for n, m in sys.modules.items() if ours(n)}
    saved_path = list(sys.path)
    for name in saved:
        del sys.modules[name]
    sys.path.insert(0, str(site))
    try:
        builder = importlib.import_module("pythonfmu.builder")
        builder.Fmi2Slave = fmukit_slave.Fmi2Slave   # the base our slave classes have
        yield builder.FmuBuilder
    finally:
        sys.path[:] = saved_path
        for name in [n for n in sys.modules if ours(n)]:
            del sys.modules[name]
        sys.modules.update(saved)


def _rewrite_archive(src: Path, dest: Path, model_identifier: str, loader: Path | None) -> None:
    """Copy ``src`` to ``dest``, swapping the Linux binary for the loader."""
    linux_bin = f"binaries/linux64/{model_identifier}.so"
    with replaced_when_done(dest) as tmp_dest, zipfile.ZipFile(src) as zin, \
            zipfile.ZipFile(tmp_dest, "w", zipfile.ZIP_DEFLATED) as zout:
        names = zin.namelist()
        if loader is not None and linux_bin not in names:
            raise BuildError(f"FMU {model_identifier!r} has no {linux_bin}; pythonfmu ships no "
                             "Linux binary")
        for info in zin.infolist():
            data = zin.read(info)
            if info.filename == linux_bin and loader is not None:
                zout.writestr(f"binaries/linux64/{model_identifier}{REAL_BINARY_SUFFIX}", data)
                continue
            zout.writestr(info.filename, data)
        if loader is not None:
            zout.write(loader, linux_bin)
