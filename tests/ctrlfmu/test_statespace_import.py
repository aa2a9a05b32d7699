"""``jitterfmu build --controller law.mat``: a controller brought as MATLAB's ``ssdata``.

The reference is the same law built in Python: ``DiscreteLaw`` on the matrices (discrete)
or on ``scipy.signal.cont2discrete``'s zero-order hold (continuous).  The Python FMU's own
``resources/law.npz`` is compared with it matrix by matrix and by its response; the native
FMU by co-simulation (the slow test).
"""

import zipfile

import numpy as np
import pytest
import scipy.io
from scipy.signal import cont2discrete

from ctrlfmu.law import DiscreteLaw, LawFileError, load_law, save_law, simulate
from ctrlfmu.statespace import discretise, read_controller
from orchestrator.cli import main

DT = 2e-3
# a lightly damped 12 Hz band-pass with a direct path: two states, one gauge voltage in,
# one command out (continuous, rad/s)
W, ZETA = 2 * np.pi * 12.0, 0.2
A_C = np.array([[0.0, 1.0], [-W**2, -2 * ZETA * W]])
B_C = np.array([[0.0], [1.0]])
C_C = np.array([[0.0, 3.0e4]])
D_C = np.array([[50.0]])


def python_law(continuous: bool) -> DiscreteLaw:
    """The law a Python user builds with ctrlfmu.law (the reference)."""
    if continuous:
        a, b, c, d, _ = cont2discrete((A_C, B_C, C_C, D_C), DT, method="zoh")
        return DiscreteLaw(a, b, c, d, DT, delayed=False, inputs=("strain",),
                           outputs=("drive",), input_units=("V",))
    return DiscreteLaw(*discrete_matrices(), DT, delayed=False)


def discrete_matrices():
    """A discrete law with two inputs and two outputs (D 2x2), written as given."""
    rng = np.random.default_rng(3)
    a = np.diag([0.9, 0.5, -0.3]) + 0.05 * rng.standard_normal((3, 3))
    return a, rng.standard_normal((3, 2)), rng.standard_normal((2, 3)), \
        rng.standard_normal((2, 2))


def write_mat(path, continuous: bool):
    """What ``[A,B,C,D,Ts] = ssdata(sys); save law.mat A B C D Ts InputName OutputName``
    writes, here by scipy."""
    if continuous:
        data = dict(A=A_C, B=B_C, C=C_C, D=D_C, Ts=0.0,
                    InputName=np.array(["strain"], dtype=object),
                    OutputName=np.array(["drive"], dtype=object),
                    InputUnit=np.array(["V"], dtype=object))   # a gauge's bridge voltage
    else:
        a, b, c, d = discrete_matrices()
        data = dict(A=a, B=b, C=c, D=d, Ts=DT)
    scipy.io.savemat(path, data)
    return path


def fmu_law(fmu) -> DiscreteLaw:
    """The law inside a built controller FMU."""
    with zipfile.ZipFile(fmu) as z:
        return load_law(z.open("resources/law.npz"))


def assert_same_law(got: DiscreteLaw, want: DiscreteLaw):
    for m in "ABCD":
        np.testing.assert_allclose(getattr(got, m), getattr(want, m), rtol=1e-12, atol=1e-12)
    assert got.dt == want.dt and got.delayed == want.delayed
    y = np.random.default_rng(7).standard_normal((400, want.n_inputs))
    np.testing.assert_allclose(simulate(got, y)[0], simulate(want, y)[0],
                               rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("continuous", [True, False], ids=["continuous", "discrete"])
def test_build_from_mat_equals_the_python_law(tmp_path, continuous, capsys):
    path = write_mat(tmp_path / "law.mat", continuous)
    args = ["build", "--controller", str(path), "--out", str(tmp_path / "f"), "--python"]
    assert main(args + (["--period", str(DT)] if continuous else [])) == 0
    fmu = tmp_path / "f" / "python" / "controller_law.fmu"   # its law.npz is readable
    out = capsys.readouterr().out
    assert str(fmu) in out
    # the build says what it built, the discretisation method stated
    assert out.splitlines()[0] == (
        "controller_law: state-space from law.mat (continuous, discretised at 0.002 s by a "
        "zero-order hold); 2 state(s), inputs strain -> outputs drive" if continuous else
        "controller_law: state-space from law.mat (discrete at Ts = 0.002 s); 3 state(s), "
        "inputs y1, y2 -> outputs u1, u2")
    got, want = fmu_law(fmu), python_law(continuous)
    assert_same_law(got, want)
    if continuous:
        assert (got.inputs, got.outputs, got.input_units) == (("strain",), ("drive",), ("V",))
    else:
        assert got.inputs == ("y1", "y2") and got.output_units == ("V", "V")


def test_csv_and_npz_give_the_mat_law(tmp_path):
    a, b, c, d = discrete_matrices()
    lines = ["# a discrete law, one key a line, a matrix row a line"]
    lines += [f"{name}," + ",".join(repr(float(v)) for v in row)
              for name, m in (("A", a), ("B", b), ("C", c), ("D", d)) for row in m]
    lines += [f"Ts,{DT!r}", "inputs,s1,s2", "outputs,v1,v2", "OutputUnit,V,V"]
    (tmp_path / "law.csv").write_text("\n".join(lines) + "\n")
    np.savez(tmp_path / "law.npz", A=a, B=b, C=c, D=d, Ts=DT)
    want = python_law(continuous=False)
    for name in ("law.csv", "law.npz"):
        assert_same_law(read_controller(tmp_path / name), want)
    assert read_controller(tmp_path / "law.csv").inputs == ("s1", "s2")
    saved = save_law(want, tmp_path / "saved.npz")      # a saved law still reads as one
    assert_same_law(read_controller(saved), want)


def test_zoh_is_exact_for_a_held_input():
    """ZOH reference independent of the code: a first-order lag dx/dt = -x/tau + y/tau
    sampled with y held gives x(k+1) = e^(-dt/tau) x + (1 - e^(-dt/tau)) y."""
    tau = 0.05
    ad, bd, cd, dd = discretise([[-1 / tau]], [[1 / tau]], [[1.0]], [[0.0]], DT)
    np.testing.assert_allclose(ad, [[np.exp(-DT / tau)]], rtol=1e-14)
    np.testing.assert_allclose(bd, [[1 - np.exp(-DT / tau)]], rtol=1e-12)
    # Tustin: the pole maps to (1 - dt/2tau) / (1 + dt/2tau)
    at, *_ = discretise([[-1 / tau]], [[1 / tau]], [[1.0]], [[0.0]], DT, "tustin")
    r = DT / (2 * tau)
    np.testing.assert_allclose(at, [[(1 - r) / (1 + r)]], rtol=1e-14)


def test_static_gain_from_matlab_empty_matrices(tmp_path):
    """MATLAB's ssdata of a static gain gives A, B, C empty (0x0 when saved)."""
    scipy.io.savemat(tmp_path / "k.mat", dict(A=np.zeros((0, 0)), B=np.zeros((0, 0)),
                                              C=np.zeros((0, 0)), D=[[2.5, -1.0]], Ts=DT))
    law = read_controller(tmp_path / "k.mat")
    assert law.n_states == 0 and law.D.shape == (1, 2)
    np.testing.assert_allclose(simulate(law, [[1.0, 2.0]])[0], [[0.5]])


def test_bad_files_are_refused_in_one_sentence(tmp_path, capsys):
    good = dict(A=A_C, B=B_C, C=C_C, D=D_C)
    scipy.io.savemat(tmp_path / "no_ts.mat", good)
    scipy.io.savemat(tmp_path / "cont.mat", {**good, "Ts": 0.0})
    scipy.io.savemat(tmp_path / "shape.mat", {**good, "D": np.ones((1, 2)), "Ts": DT})
    scipy.io.savemat(tmp_path / "neg.mat", {**good, "Ts": -2.0})
    scipy.io.savemat(tmp_path / "nan.mat", {**good, "A": [[np.nan, 0], [0, 1]], "Ts": DT})
    scipy.io.savemat(tmp_path / "disc.mat", {**good, "Ts": DT})
    scipy.io.savemat(tmp_path / "names.mat", {**good, "Ts": DT,
                                              "InputName": np.array(["a", "b"], dtype=object)})
    (tmp_path / "text.mat").write_text("not a mat file")
    (tmp_path / "word.csv").write_text("A,1,x\nB,1\nC,1\nD,0\nTs,0.1\n")
    (tmp_path / "key.csv").write_text("A,1\nB,1\nC,1\nD,0\nTs,0.1\nGain,3\n")
    (tmp_path / "law.txt").write_text("A 1")
    cases = [
        ("no_ts.mat", [], "has no sample time Ts"),
        ("cont.mat", [], "give the FMU's period with --period"),
        ("shape.mat", [], "controller matrix B has shape (2, 1); expected (2, 2)"),
        ("neg.mat", [], "has Ts = -2"),
        ("nan.mat", [], "non-finite"),
        ("disc.mat", ["--period", "0.01"], "the period given is 0.01 s"),
        ("names.mat", [], "inputs has 2 entries; expected 1"),
        ("text.mat", [], "is not a MATLAB .mat file"),
        ("word.csv", [], "line 1: A has a value that is not a number"),
        ("key.csv", [], "line 6: unknown key 'Gain'"),
        ("law.txt", [], "expected a .mat, .npz or .csv"),
    ]
    for name, extra, words in cases:
        code = main(["build", "--controller", str(tmp_path / name), "--out",
                     str(tmp_path / "f"), "--native", *extra])
        err = capsys.readouterr().err
        assert code == 2, (name, err)
        first = err.strip().splitlines()[0]
        assert first.startswith("jitterfmu: error: ") and "Traceback" not in err, (name, err)
        assert words in first and first.count(". ") == 0, (name, first)
    assert not list((tmp_path / "f").rglob("*.fmu"))
    with pytest.raises(LawFileError):
        read_controller(tmp_path / "text.mat")
    assert main(["build", "--period", "0.01", "--out", str(tmp_path / "f")]) == 2
    assert "--period is the period of a --controller" in capsys.readouterr().err


@pytest.mark.slow
def test_continuous_mat_law_cosimulated(tmp_path, suite_fmus, capsys):
    """The FMU from a continuous ``.mat`` co-simulated by the master gives the Python
    law's response (the non-delayed form: feedthrough at each sample)."""
    path = write_mat(tmp_path / "law.mat", continuous=True)
    assert main(["build", "--controller", str(path), "--out", str(tmp_path / "f"),
                 "--native", "--period", str(DT)]) == 0
    from orchestrator import run_scenario

    src = suite_fmus("excitation")["excitation"]
    scenario = {
        "experiment": {"stop": 0.3, "output_interval": DT},
        "fmus": {"src": {"fmu": str(src), "period": DT,
                         "parameters": {"amp1": 1e-3, "freq1": 11.0, "t_stop": 10.0}},
                 "ctrl": {"fmu": str(tmp_path / "f" / "controller_law.fmu"), "period": DT}},
        "connections": [{"from": "src.v1", "to": "ctrl.y1"}],
        "record": {"variables": ["src.v1", "ctrl.u1"]},
    }
    table = run_scenario(scenario, tmp_path / "run", quiet=True).table
    expected, _ = simulate(python_law(continuous=True), np.asarray(table["src.v1"]))
    assert np.max(np.abs(expected)) > 0.1
    np.testing.assert_allclose(np.asarray(table["ctrl.u1"]), expected[:, 0],
                               rtol=1e-12, atol=1e-12)
