"""The linear closed loop of a scenario (orchestrator.analysis).

References: a hand-solved two-state loop (amplifier + pure-gain law), the co-simulation
of the same scenario through the FMUs, and algebraic properties of the ceiling.
"""

import math
import tomllib
import warnings

import numpy as np
import pytest

from orchestrator.analysis import AnalysisError, ceiling, linearize, report

SCENARIO = "scenarios/truss10_closed_loop.toml"


@pytest.fixture(scope="module")
def fmus(suite_fmus, suite_fmu_dir):
    from orchestrator.experiments.truss_decay import FMUS

    suite_fmus(*FMUS, "piezo_p845_37")
    return suite_fmu_dir


@pytest.fixture(scope="module")
def gain_loop(fmus):
    """A P-845.37 amplifier whose voltage a pure-gain delayed law feeds back."""
    from ctrlfmu.law import DiscreteLaw, save_law
    from fmutools.build import FmuSpec, build_fmu

    g0 = 0.5
    law = DiscreteLaw(np.zeros((1, 1)), np.zeros((1, 1)), np.zeros((1, 1)), [[g0]], 1e-3,
                      name="gain", input_units=("V",), output_units=("V",))
    path = save_law(law, fmus / "gain_law.npz")
    fmu = build_fmu(FmuSpec("ctrl_gain_test", "ctrlfmu.slave:ControllerSlave",
                            resources={"law.npz": path}, step_size=1e-3), fmus)
    sc = {"experiment": {"stop": 0.1, "output_interval": 1e-3},
          "fmus": {"amp": {"fmu": str(fmus / "piezo_p845_37.fmu"), "period": 1e-3,
                           "parameters": {"bandwidth": 100.0}},
                   "ctrl": {"fmu": str(fmu), "period": 1e-3}},
          "connections": [{"from": "amp.voltage", "to": "ctrl.y1"},
                          {"from": "ctrl.u1", "to": "amp.v_cmd"}],
          "record": {"variables": ["amp.voltage"]}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return linearize(sc), g0


def test_hand_solved_loop_poles_and_margins(gain_loop):
    lin, g0 = gain_loop
    # amplifier low-pass over 1 ms: v+ = a v + (1 - a) u, a = exp(-2 pi 100 Hz 1 ms);
    # Eq. 11 law: u+ = g v.  Closed loop: z^2 - a z - g (1 - a) = 0.
    a = math.exp(-2 * math.pi * 100.0 * 1e-3)
    want = np.sort_complex(np.roots([1.0, -a, -g0 * (1 - a)]))
    got = np.sort_complex(np.array([p.z for p in lin.poles()]))
    np.testing.assert_allclose(got, want, rtol=1e-12)
    # unstable where a real root reaches z = 1 (g = 1), or, for negative g, where the
    # complex pair reaches the unit circle: |z|^2 = -g (1 - a) = 1
    m = lin.gain_margins("ctrl", rtol=1e-6)
    assert m.stable
    assert m.upper == pytest.approx(1.0 / g0, rel=1e-5)
    assert m.lower == pytest.approx(-1.0 / ((1 - a) * g0), rel=1e-5)
    assert m.upper_db == pytest.approx(20 * math.log10(2.0), rel=1e-5)
    text = report(lin)
    assert "ctrl" in text and "6.02" in text and "stable: yes" in text


@pytest.fixture(scope="module")
def truss_run(fmus):
    from orchestrator import run_scenario

    with open(SCENARIO, "rb") as f:
        sc = tomllib.load(f)
    sc["experiment"]["output_interval"] = 1e-3
    rec = ["structure.strain_diag", "structure.strain_long", "ctrl_diag.u1",
           "ctrl_long.u1", "piezo_diag.force", "excitation.v1", "excitation.v2"]
    sc["record"]["variables"] = rec
    ov = {"ctrl_diag.t_on": 0.0, "ctrl_long.t_on": 0.0}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = run_scenario(sc, stop_time=0.6, overrides=ov, fmu_dir=fmus).table
        lin = linearize(sc, overrides=ov, fmu_dir=fmus)
    return table, lin


def test_linear_loop_is_the_cosimulation(truss_run):
    # the same discretised models, assembled with the master's rules: the linear
    # simulation driven by the recorded excitation reproduces the FMUs' run
    table, lin = truss_run
    ex = np.c_[table["excitation.v1"], table["excitation.v2"]]
    rec = ["structure.strain_diag", "structure.strain_long", "ctrl_diag.u1", "ctrl_long.u1",
           "piezo_diag.force"]
    y, _ = lin.simulate(len(table["time"]), w=lambda name, k: ex[k], record=rec)
    for i, ref in enumerate(rec):
        peak = np.abs(table[ref]).max()
        assert peak > 0
        np.testing.assert_allclose(y[:, i], table[ref], rtol=0, atol=1e-10 * peak)
    # mixed rates: structure and amplifiers at 1 ms, laws and excitation at 4 ms
    assert lin.hyper == 4 and lin.T == pytest.approx(4e-3)


def test_shipped_truss_loops_damp_and_have_margin(truss_run):
    _, lin = truss_run
    assert lin.is_stable()
    for c in ("ctrl_diag", "ctrl_long"):
        m = lin.gain_margins(c)
        assert m.stable and m.upper_db >= 6.0 and m.lower < 0.5
    # without control the two modes keep their test damping (0.18 %, 0.4 %); the
    # uncoupled absorber poles (zeta 0.73 and more) are left out
    off = lin.with_gain("ctrl_diag", 0.0).with_gain("ctrl_long", 0.0)
    zetas = sorted(p.zeta for p in off.poles()
                   if 8 < p.freq_hz < 10 and p.z.imag > 0 and p.zeta < 0.1)
    np.testing.assert_allclose(zetas, [0.0018, 0.004], rtol=1e-6)
    # with control no pole between 3 and 20 Hz keeps less than 3 % damping
    assert min(p.zeta for p in lin.poles() if 3 < p.freq_hz < 20) > 0.03


def test_stored_tuning_decays_in_two_cycles_on_the_linear_loop(fmus):
    from orchestrator.experiments.truss_decay import linear_decay

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lin = linearize(SCENARIO, fmu_dir=fmus)
    cycles, volts = linear_decay(lin)
    assert all(c is not None and c <= 2.0 for c in cycles.values())
    assert volts < 1000.0
    # the former tuning (largest smallest damping of all poles within 0.5-2x each
    # mode, each loop alone) misses the paper's two cycles on the diagonal (3.7 cycles
    # with the step-mean coupling, 4.5 with the force one step late)
    from ctrlfmu.designs import truss10_strain_diag, truss10_strain_long
    old = {"ctrl_diag": truss10_strain_diag(tuning=0.6, zeta=1.0, loop_gain=0.5 * 1.2399),
           "ctrl_long": truss10_strain_long(tuning=0.8, zeta=0.7, loop_gain=0.5 * 0.6616)}
    cycles_old, _ = linear_decay(lin, old)
    assert cycles_old["diagonal"] > 2.0


def test_ceiling_properties(fmus):
    # disturbance: the excitation straight into the diagonal stack; actuator: the
    # longeron loop.  Cancelling the longeron gauge removes all of the longeron gauge's
    # response (100 %), and the best commands do at least as well as cancelling a
    # sensor on any other output.
    with open(SCENARIO, "rb") as f:
        sc = tomllib.load(f)
    sc["connections"] = [c for c in sc["connections"]
                         if c["to"] not in ("ctrl_diag.r1", "piezo_diag.v_cmd")]
    sc["connections"].append({"from": "excitation.v1", "to": "piezo_diag.v_cmd"})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lin = linearize(sc, fmu_dir=fmus)
    freqs = [8.4, 9.5, 20.0]
    c = ceiling(lin, ["structure.strain_long"], "excitation.v1", freqs,
                actuators=["ctrl_long"], method="cancel")
    assert c.sensors == ("structure.strain_long",)
    assert c.reduction_pct == pytest.approx(100.0, abs=1e-6)
    cancel = ceiling(lin, ["structure.los_tip_pitch"], "excitation.v1", freqs,
                     actuators=["ctrl_long"], method="cancel")
    best = ceiling(lin, ["structure.los_tip_pitch"], "excitation.v1", freqs,
                   actuators=["ctrl_long"], method="optimal")
    assert np.all(best.ideal <= cancel.ideal * (1 + 1e-9))
    assert best.reduction_pct >= cancel.reduction_pct - 1e-9
    assert np.all(cancel.open_loop > 0)
    with pytest.raises(AnalysisError, match="ceiling method"):
        ceiling(lin, ["structure.strain_long"], "excitation.v1", freqs,
                actuators=["ctrl_long"], method="psychic")
    with pytest.raises(AnalysisError, match="not an output of a source"):
        ceiling(lin, ["structure.strain_long"], "structure.strain_diag", freqs,
                actuators=["ctrl_long"])
    with pytest.raises(AnalysisError, match=r"excitation.v9 is not an output of a source "
                       r"instance \(did you mean 'excitation.v[12]' or 'excitation.v[12]'\?\); "
                       r"source outputs: (.*, )?excitation.v1, excitation.v2"):
        ceiling(lin, ["structure.strain_long"], "excitation.v9", freqs,
                actuators=["ctrl_long"])
    with pytest.raises(AnalysisError, match=r"structure.los_tip_yw is not an output of "
                                            r"'structure' \(did you mean 'los_tip_yaw'"):
        lin.index("structure.los_tip_yw")
    with pytest.raises(AnalysisError, match=r"no instance 'structur' in the scenario "
                                            r"\(did you mean 'structure'"):
        lin.index("structur.los_tip_yaw")


def test_native_fmus_without_their_python_twins_are_named(fmus, tmp_path):
    """The linear analysis reads the Python build; a folder of native FMUs alone gets one
    sentence saying so and what to run."""
    import shutil

    from orchestrator.experiments.truss_decay import FMUS

    for name in FMUS:
        shutil.copy(fmus / f"{name}.fmu", tmp_path / f"{name}.fmu")   # native ones only
    with pytest.raises(AnalysisError, match="is a native build .* run 'jitterfmu build'"):
        linearize(SCENARIO, fmu_dir=tmp_path)


def test_stability_margin_db_against_known_limits():
    from orchestrator.analysis import stability_margin_db

    # stable below a factor of 3.7 (up) and above 0.25 (down): margins 20 log10 of those,
    # to the bracket tolerance, from the stable side
    up = stability_margin_db(lambda f: f < 3.7, tol=1.001)
    assert 20 * np.log10(3.7 / 1.001) <= up <= 20 * np.log10(3.7)
    down = stability_margin_db(lambda f: f > 0.25, step=0.5, tol=1.001)
    assert 20 * np.log10(4 / 1.001) <= down <= 20 * np.log10(4.0)
    assert stability_margin_db(lambda f: False) == -np.inf
    assert stability_margin_db(lambda f: True, limit=64.0, beyond=36.0) == 36.0


def test_frequency_response_of_a_source_slower_than_the_loop(fmus):
    # The excitation at 8 ms drives a loop whose hyperperiod is 4 ms: the periodic steady
    # state then repeats every 8 ms.  Reference: the tick-by-tick linear simulation driven
    # by cos and sin (their complex sum is the response to exp(j w t)), each value held
    # over the source's 8 ms as the co-simulation steps it, settled, whose fundamental
    # over whole 8 ms periods is what frequency_response defines.
    with open(SCENARIO, "rb") as f:
        sc = tomllib.load(f)
    sc["fmus"]["excitation"]["period"] = "8e-3"
    ov = {"ctrl_diag.t_on": 0.0, "ctrl_long.t_on": 0.0}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lin = linearize(sc, overrides=ov, fmu_dir=fmus)
    assert lin.hyper == 4 and lin.blocks["excitation"].period == 8
    f_hz, out = 10.0, "structure.strain_diag"
    H = lin.frequency_response(["excitation.v1"], [out], [f_hz])[0, 0, 0]
    n, w = 12000, 2 * np.pi * f_hz            # 12 s: the loop's poles settle in ~1 s

    def run(phase):
        def src(name, k):
            # simulate() publishes sources every hyperperiod (4 ms); hold the 8 ms value
            return np.array([math.cos(w * (k - k % 8) * lin.base - phase), 0.0])
        return lin.simulate(n, w=src, record=[out])[0][:, 0]

    y = run(0.0) + 1j * run(math.pi / 2)
    k = np.arange(n - 800, n)                  # 800 ticks: 100 periods of 8 ms, 8 of 10 Hz
    ref = np.mean(y[k] * np.exp(-1j * w * k * lin.base))
    assert abs(ref) > 0
    np.testing.assert_allclose(H, ref, rtol=1e-9)
