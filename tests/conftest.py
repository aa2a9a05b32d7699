"""Fixtures shared by the whole suite.

``suite_fmus(*names)`` gives the suite's FMUs from one folder for the whole test run:
each FMU of the registry (and the EOS all-legs structure, through the experiments' own
``ensure_fmus``) is built there at most once, however many tests use it.  Under
pytest-xdist (``make test`` runs two workers) the workers share that folder:
``ensure_fmus`` locks it for each call, and the suite asks for one FMU a call, so one
worker builds while the other waits for that FMU or builds another.  Tests that check building itself, or that
change an FMU, build into their own folders.

The FMI 3.0 native builds (``suite_fmi3``) and the container FMUs of shipped scenarios
(``suite_container``, written by ``jitterfmu export-fmu``) are made the same way: once
per run in that folder, whichever worker asks first, the other waiting on a lock.
"""

from __future__ import annotations

import contextlib
import io
import os
import tempfile
import warnings
from pathlib import Path

import pytest

from fmutools.ensure import ensure_fmus

# the store of built blocks (orchestrator.analysis.blockstore) is off for the suite: its
# tests count extractions and builds, and each test must build what it checks; the
# store's own tests turn it on in a folder of their own
os.environ["JITTERFMU_BLOCK_CACHE"] = "off"

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: one worker per run there
    fcntl = None


@pytest.fixture(scope="session")
def suite_fmu_dir(tmp_path_factory, request):
    """The run's folder of built suite FMUs (filled on demand; shared by xdist workers)."""
    base = tmp_path_factory.getbasetemp()
    worker = hasattr(request.config, "workerinput")   # an xdist worker: base is per worker
    return (base.parent if worker else base) / "suite_fmus"


@pytest.fixture(scope="session")
def suite_fmus(suite_fmu_dir):
    """``suite_fmus(*names, kind="native") -> {name: path}``: the named registry FMUs of
    one build (native in the folder, Python in its ``python/``), each built once.  They
    are ensured one at a time, so the folder's lock is held for one build: a worker
    that needs other FMUs builds them meanwhile instead of waiting for the whole list."""
    def get(*names, kind="native"):
        out = {}
        for name in dict.fromkeys(names):
            out.update(ensure_fmus([name], suite_fmu_dir, kind=kind))
        return out
    return get


def made_once(path: Path, build) -> Path:
    """``path``, made by ``build(folder) -> file`` (a file of that name in a fresh folder)
    unless a test of this run, in any worker, made it already; a lock per file makes
    the second asker wait for the first, and a build that fails leaves nothing."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.with_name(path.name + ".lock"), "a+") as lock:
        if fcntl is not None:
            fcntl.flock(lock, fcntl.LOCK_EX)
        if not path.exists():
            with tempfile.TemporaryDirectory(dir=path.parent) as tmp:
                os.replace(build(Path(tmp)), path)
    return path


@pytest.fixture(scope="session")
def suite_fmi3(suite_fmus, suite_fmu_dir):
    """``suite_fmi3(*names) -> folder``: the FMI 3.0 native builds (no win64) of the named
    registry FMUs, from the suite's Python twins, each built once per run."""
    from fmutools.registry import collect_specs
    from nativefmu.build import build_native

    out = suite_fmu_dir / "fmi3"

    def get(*names):
        specs = collect_specs(list(names))
        suite_fmus(*[s.model_identifier for s in specs])
        for spec in specs:
            twin = suite_fmu_dir / "python" / f"{spec.model_identifier}.fmu"
            made_once(out / f"{spec.model_identifier}.fmu",
                      lambda tmp, spec=spec, twin=twin: build_native(
                          spec, tmp, python_fmu=twin, windows=False, fmi=3))
        return out
    return get


@pytest.fixture(scope="session")
def suite_container(suite_fmus, suite_fmu_dir):
    """``suite_container(scenario, fmi=2) -> Path``: a scenario file exported by
    ``jitterfmu export-fmu`` (with its win64 binary when mingw-w64 is installed), once
    per run; the command's stderr and stdout are kept beside it, in ``<stem>.said``."""
    from orchestrator import load_scenario
    from orchestrator.cli import main

    def get(scenario, fmi=2):
        scenario = Path(scenario)
        suite_fmus(*{i.fmu for i in load_scenario(scenario).instances})
        path = suite_fmu_dir / "containers" / f"fmi{fmi}" / f"{scenario.stem}.fmu"

        def export(tmp):
            said = io.StringIO()
            with contextlib.redirect_stderr(said), contextlib.redirect_stdout(said), \
                    warnings.catch_warnings():
                warnings.simplefilter("ignore")
                code = main(["export-fmu", str(scenario), str(tmp / path.name),
                             "--fmi", str(fmi), "--fmu-dir", str(suite_fmu_dir)])
            assert code == 0, said.getvalue()
            path.with_suffix(".said").write_text(said.getvalue())
            return tmp / path.name
        return made_once(path, export)
    return get


@pytest.fixture(autouse=True)
def _import_path_kept():
    """Every test leaves ``sys.path`` as it found it.  pythonfmu puts a Python FMU's
    resources folder first on ``sys.path`` at each instantiation and never takes it
    off; left so, a test worker's ``sys.path`` grew to about 90 entries, and each import
    that fails walked them all (python-control retries its optional slycot at every
    evaluation: a 2 s test took 15-26 s late in a worker)."""
    import sys

    before = list(sys.path)
    yield
    sys.path[:] = before


@pytest.fixture(autouse=True)
def _working_folder_kept():
    """Every test leaves the working folder where it found it: the suite runs from the
    repository root, and a test that moves it breaks every later relative path of its
    worker (seen: test_reference's scenarios/... not found)."""
    import os

    before = os.getcwd()
    yield
    after = os.getcwd()
    if after != before:
        os.chdir(before)
        pytest.fail(f"the test changed the working folder to {after} and left it there",
                    pytrace=False)
