"""``fmu_kind``: which build of the suite's FMUs a scenario runs (native in an FMU
folder, Python in its ``python/`` subfolder)."""

import shutil

import pytest

from orchestrator import ScenarioError, load_scenario
from orchestrator.cosim import find_fmu


def scenario(kind=None):
    exp = {"stop": 0.01, "output_interval": 1e-3}
    if kind is not None:
        exp["fmu_kind"] = kind
    return load_scenario({"experiment": exp, "fmus": {"g": {"fmu": "MtGain", "period": 1e-3}}})


def test_the_key_is_parsed_checked_and_kept_in_the_digest():
    assert scenario().experiment.fmu_kind == "native"
    assert scenario("Python").experiment.fmu_kind == "python"
    assert scenario("python").digest() != scenario().digest()
    assert scenario("native").digest() == scenario().digest()
    assert scenario().with_experiment(fmu_kind="python").experiment.fmu_kind == "python"
    with pytest.raises(ScenarioError, match="fmu_kind 'natve' is unknown.*native"):
        scenario("natve")


def test_python_kind_prefers_the_python_subfolder(fmu_dir, tmp_path):
    d = tmp_path / "fmus"
    (d / "python").mkdir(parents=True)
    shutil.copy(fmu_dir / "MtGain.fmu", d / "python" / "MtGain.fmu")
    # only a Python build: the native lookup says so and how to go on
    with pytest.raises(ScenarioError, match="only a Python build.*--python-fmus"):
        find_fmu("MtGain", scenario(), d)
    assert find_fmu("MtGain", scenario("python"), d) == d / "python" / "MtGain.fmu"
    shutil.copy(fmu_dir / "MtGain.fmu", d / "MtGain.fmu")
    assert find_fmu("MtGain", scenario(), d) == d / "MtGain.fmu"
    assert find_fmu("MtGain", scenario("python"), d) == d / "python" / "MtGain.fmu"
    # an FMU of one build only (a user's own component) is found under either kind
    (d / "python" / "MtGain.fmu").unlink()
    assert find_fmu("MtGain", scenario("python"), d) == d / "MtGain.fmu"
