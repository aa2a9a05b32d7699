"""Fixtures shared by the whole suite.

``suite_fmus(*names)`` gives the suite's FMUs from one folder for the whole test run:
each FMU of the registry (and the EOS all-legs structure, through the experiments' own
``ensure_fmus``) is built there at most once, however many tests use it.  Under
pytest-xdist (``make test`` runs two workers) the workers share that folder:
``ensure_fmus`` locks it, so one builds while the other waits.  Tests that check building itself, or that
change an FMU, build into their own folders.
"""

from __future__ import annotations

import pytest

from fmutools.ensure import ensure_fmus


@pytest.fixture(scope="session")
def suite_fmu_dir(tmp_path_factory, request):
    """The run's folder of built suite FMUs (filled on demand; shared by xdist workers)."""
    base = tmp_path_factory.getbasetemp()
    worker = hasattr(request.config, "workerinput")   # an xdist worker: base is per worker
    return (base.parent if worker else base) / "suite_fmus"


@pytest.fixture(scope="session")
def suite_fmus(suite_fmu_dir):
    """``suite_fmus(*names, kind="native") -> {name: path}``: the named registry FMUs of
    one build (native in the folder, Python in its ``python/``), each built once."""
    def get(*names, kind="native"):
        return ensure_fmus(names, suite_fmu_dir, kind=kind)
    return get


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
