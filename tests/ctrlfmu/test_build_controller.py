"""``jitterfmu build --controller LAW.npz``: a user's law as a controller FMU, both kinds."""

import numpy as np
import pytest

from ctrlfmu.law import DiscreteLaw, LawFileError, load_law, save_law, simulate
from fmutools.validate import validate_fmu
from orchestrator import run_scenario
from orchestrator.cli import main

DT = 4e-3


def user_law() -> DiscreteLaw:
    """A second-order filter with a direct path in the form of Eq. (11) (one-sample
    delay), driven by a voltage so that a sine source can feed it."""
    a = np.array([[0.9, 0.2], [-0.2, 0.85]])
    return DiscreteLaw(a, [[1.0], [0.5]], [[0.3, -0.7]], [[0.25]], DT,
                       name="my filter", inputs=("sense",), outputs=("drive",),
                       input_units=("V",), output_units=("V",), description="a test law")


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["native", "python"])
def test_built_fmu_gives_the_laws_own_response(tmp_path, suite_fmus, kind, capsys):
    law = user_law()
    path = save_law(law, tmp_path / "law.npz")
    out = tmp_path / "fmus"
    flag = "--native" if kind == "native" else "--python"
    assert main(["build", "--controller", str(path), "--out", str(out), flag]) == 0
    printed = capsys.readouterr().out
    fmu = out / ("controller_my_filter.fmu" if kind == "native"
                 else "python/controller_my_filter.fmu")
    assert str(fmu) in printed and "ok" in printed
    assert fmu.is_file() and validate_fmu(fmu, strict=True) == []
    other = out / ("python" if kind == "native" else "") / "controller_my_filter.fmu"
    assert not other.is_file() or other == fmu       # only the flavour asked for
    src = suite_fmus("excitation", kind=kind)["excitation"]
    scenario = {
        "experiment": {"stop": 0.4, "output_interval": DT, "fmu_kind": kind},
        "fmus": {"src": {"fmu": str(src), "period": DT,
                         "parameters": {"amp1": 2.0, "freq1": 7.0, "t_stop": 10.0}},
                 "ctrl": {"fmu": str(fmu), "period": DT}},
        "connections": [{"from": "src.v1", "to": "ctrl.y1"}],
        "record": {"variables": ["src.v1", "ctrl.u1"]},
    }
    table = run_scenario(scenario, tmp_path / "run", quiet=True).table
    y = np.asarray(table["src.v1"])
    expected, _ = simulate(law, y)
    assert np.max(np.abs(expected)) > 1.0          # a response worth comparing
    np.testing.assert_allclose(np.asarray(table["ctrl.u1"]), expected[:, 0],
                               rtol=1e-12, atol=1e-12)


def _non_delayed_run(tmp_path, suite_fmus, consumer: bool):
    """A non-delayed law (u(t_k) = C x(k) + D y(t_k)) fed by a sine; its command is
    recorded, and with ``consumer`` also fed to a second instance of the same FMU."""
    from dataclasses import replace

    law = replace(user_law(), delayed=False)
    path = save_law(law, tmp_path / "nd.npz")
    assert main(["build", "--controller", str(path), "--out", str(tmp_path / "f"),
                 "--native"]) == 0
    fmu = str(tmp_path / "f" / "controller_my_filter.fmu")
    src = str(suite_fmus("excitation")["excitation"])
    fmus = {"src": {"fmu": src, "period": DT,
                    "parameters": {"amp1": 2.0, "freq1": 7.0, "t_stop": 10.0}},
            "ctrl": {"fmu": fmu, "period": DT}}
    connections = [{"from": "src.v1", "to": "ctrl.y1"}]
    if consumer:
        fmus["next"] = {"fmu": fmu, "period": DT}
        connections.append({"from": "ctrl.u1", "to": "next.y1"})
    scenario = {"experiment": {"stop": 0.1, "output_interval": DT}, "fmus": fmus,
                "connections": connections,
                "record": {"variables": ["src.v1", "ctrl.u1"]}}
    table = run_scenario(scenario, tmp_path / "run", quiet=True).table
    expected, _ = simulate(law, np.asarray(table["src.v1"]))
    return np.asarray(table["ctrl.u1"]), expected[:, 0]


@pytest.mark.slow
def test_non_delayed_law_feeding_an_instance(tmp_path, suite_fmus, capsys):
    got, expected = _non_delayed_run(tmp_path, suite_fmus, consumer=True)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


@pytest.mark.slow
def test_non_delayed_law_recorded_only(tmp_path, suite_fmus, capsys):
    """A feedthrough output that feeds no instance is recorded at t_k for the inputs of
    t_k, C x(k) + D y(t_k) (it was C x(k) + D y(t_(k-1)), one sample late)."""
    got, expected = _non_delayed_run(tmp_path, suite_fmus, consumer=False)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


@pytest.mark.slow
def test_both_kinds_and_model_name(tmp_path, capsys):
    path = save_law(user_law(), tmp_path / "law")
    out = tmp_path / "fmus"
    assert main(["build", "--controller", str(path), "--out", str(out),
                 "--model", "ctrl_x"]) == 0
    for f in (out / "ctrl_x.fmu", out / "python" / "ctrl_x.fmu"):
        assert validate_fmu(f, strict=True) == []


def test_bad_input_is_one_sentence(tmp_path, capsys):
    np.savez(tmp_path / "model.npz", A=np.eye(2))       # an npz, not a law
    (tmp_path / "notes.txt").write_text("not an archive")
    save_law(user_law(), tmp_path / "law.npz")
    cases = [
        (tmp_path / "missing.npz", "No such file or directory"),
        (tmp_path / "model.npz", "is not a control law file"),
        (tmp_path / "notes.txt", "is not a control law file"),
        (tmp_path, "is not a control law file"),
    ]
    for path, words in cases:
        code = main(["build", "--controller", str(path), "--out", str(tmp_path / "f")])
        err = capsys.readouterr().err
        assert code == 2, err
        first = err.splitlines()[0]
        assert first.startswith("jitterfmu: error: ") and words in first, err
        assert "Traceback" not in err
    code = main(["build", "--controller", str(tmp_path / "law.npz"), "--model", "a",
                 "--model", "b", "--out", str(tmp_path / "f")])
    assert code == 2 and "at most one --model" in capsys.readouterr().err
    assert not list((tmp_path / "f").rglob("*.fmu"))
    with pytest.raises(LawFileError):
        load_law(tmp_path / "notes.txt")
