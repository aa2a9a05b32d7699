"""The sampled-data reference (orchestrator.reference) and the coupling it checks.

References: the reference itself refined (a structure sampled exactly is the same at
any sampling period, so the reference at 1 ms and at 0.25 ms agree at their common
instants), the co-simulation converging to it as the piezo/structure step shrinks, and
the coupling that holds the force one step late, which the reference must show as about
the hold of a late sample (half a step of delay on average) at each loop's crossover.
The check itself runs the scenario as shipped (controllers switching on at 4.5 s), and
its residual there is stated with its measured cause (SHIPPED_RESIDUAL).
"""

import tomllib
import warnings

import numpy as np
import pytest

from orchestrator import run_scenario
from orchestrator.analysis import linearize
from orchestrator.reference import check, compare_loops, report, sampled_data

SCENARIO = "scenarios/truss10_closed_loop.toml"
OUTS = ["structure.strain_diag", "structure.strain_long", "structure.los_tip_pitch"]


@pytest.fixture(scope="module")
def fmus(suite_fmus, suite_fmu_dir):
    from orchestrator.experiments.truss_decay import FMUS

    suite_fmus(*FMUS)
    return suite_fmu_dir


def _scenario(period, coupling=1, stop=3.0):
    """The truss loop with controllers on from the start, structure and piezos at ``period``."""
    with open(SCENARIO, "rb") as f:
        sc = tomllib.load(f)
    for name in ("structure", "piezo_diag", "piezo_long"):
        sc["fmus"][name]["period"] = period
    for m in ("diag", "long"):
        sc["fmus"][f"piezo_{m}"]["parameters"] = {"coupling": coupling,
                                                   "hold_step": float(period)}
        sc["fmus"][f"ctrl_{m}"]["parameters"] = {"t_on": 0.0}
    sc["experiment"].update(stop=stop, output_interval=period)
    sc["record"]["variables"] = OUTS + ["excitation.v1", "excitation.v2"]
    return sc


def _runs(fmus, period, coupling=1):
    sc = _scenario(period, coupling)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lin = linearize(sc, fmu_dir=fmus)
        table = run_scenario(sc, fmu_dir=fmus).table
    ex = np.c_[table["excitation.v1"], table["excitation.v2"]]
    n = len(table["time"])
    y_ref, _ = sampled_data(lin).simulate(n, w=lambda name, k: ex[k], record=OUTS)
    return table, y_ref


def test_reference_does_not_depend_on_its_sampling_and_the_cosimulation_converges(fmus):
    coarse, ref_coarse = _runs(fmus, "1e-3")
    fine, ref_fine = _runs(fmus, "2.5e-4")
    for j, o in enumerate(OUTS):
        peak = np.abs(ref_coarse[:, j]).max()
        assert peak > 0
        # exact sampling: the same continuous system at every common instant
        np.testing.assert_allclose(ref_fine[::4, j], ref_coarse[:, j], rtol=0,
                                   atol=1e-8 * peak)
        # the co-simulation (a held force per step) converges to it as the step shrinks
        e_coarse = np.abs(coarse[o] - ref_coarse[:, j]).max() / peak
        e_fine = np.abs(fine[o][::4] - ref_coarse[:, j]).max() / peak
        assert e_fine < e_coarse / 2.5, (o, e_coarse, e_fine)
    # the line of sight, the performance output, is within 1 % of its peak at 1 ms
    los = OUTS.index("structure.los_tip_pitch")
    peak = np.abs(ref_coarse[:, los]).max()
    assert np.abs(coarse["structure.los_tip_pitch"] - ref_coarse[:, los]).max() < 0.01 * peak


def test_step_mean_coupling_adds_no_delay_and_the_old_one_adds_a_step(fmus):
    delays = {}
    for coupling in (1, 0):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            lin = linearize(_scenario("1e-3", coupling), fmu_dir=fmus)
        delays[coupling] = {c.controller: c for c in compare_loops(lin)}
    for ctrl in ("ctrl_diag", "ctrl_long"):
        new, old = delays[1][ctrl], delays[0][ctrl]
        assert new.crosses and old.crosses
        # the reference is the same loop either way
        assert new.crossover_hz == old.crossover_hz
        # step-mean: within a tenth of the 1 ms step and 0.5 deg of the hardware at the
        # crossover (what is left is the hold of the mean force over the step)
        assert abs(new.delay_s) < 0.1e-3 and abs(new.phase_deg) < 0.5
        # the force of the amplifier state held over the step: about half a step more
        # (500-570 us measured; a held sample lags h/2 on average), a degree or more
        assert old.delay_s > 300e-6 and old.phase_deg < -1.0


@pytest.fixture(scope="module")
def shipped(fmus):
    """:func:`check` on the scenario as shipped: the controllers switch on at 4.5 s."""
    return check(SCENARIO, OUTS, stop_time=6.0, fmu_dir=fmus)


def test_check_runs_the_shipped_switch_on(shipped):
    # the co-simulation runs its controllers from t_on = 4.5 s; the linear models switch
    # them on at the same tick (ctrlfmu.law: from rest) and equal it to round-off, which
    # they could not if either ran the loops from the start
    for o in shipped.outputs:
        assert o.peak > 0 and o.linear < 1e-9
        assert o.reference_on is not None
    text = report(shipped)
    assert "ctrl_diag" in text and "structure.los_tip_pitch" in text and "after switch-on" in text
    loops, outputs = shipped
    assert len(loops) == 2 and len(outputs) == len(OUTS)


def test_switch_on_ticks_are_the_laws_first_active_sample(fmus):
    from orchestrator.reference import switch_on_ticks
    from orchestrator.scenario import load_scenario

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lin = linearize(SCENARIO, fmu_dir=fmus)
    # 4.5 s on the 1 ms base is tick 4500, a sample of the 4 ms laws
    assert switch_on_ticks(lin, load_scenario(SCENARIO)) == {"ctrl_diag": 4500, "ctrl_long": 4500}
    # 4.501 s is not a 4 ms sample: the first one after it, 4.504 s
    sc = load_scenario(SCENARIO).with_overrides({"ctrl_long.t_on": 4.501, "ctrl_diag.t_on": 0.0})
    assert switch_on_ticks(lin, sc) == {"ctrl_long": 4504}


#: The shipped scenario's residual against the reference, measured with ``jitterfmu
#: analyze scenarios/truss10_closed_loop.toml --reference --stop 6``: tip line of sight
#: 1.148 % of its peak (2.63 % of the peak after the switch-on), strains 5.40 / 3.89 %.
#: Its cause, measured (docs/coupling.md): the active members' stiff local modes (1.41 and
#: 1.50 kHz, 2 % damped) ring under the 1 ms staircase of held forces where the hardware's
#: force is smooth, the strain gauges read that ringing and the 250 Hz laws feed it back:
#: the closed-loop poles at 6.4 and 11.9 Hz move by 1.7 and 2.1 % (a loop-gain error of
#: the in-band size, 3e-4, moves them 1e-4); at 0.25 ms it falls to 0.04 %, with those
#: two modes damped to 10 % to 0.11 %.
SHIPPED_RESIDUAL = ("the tip line of sight of the shipped scenario is 1.15 % of its peak "
                    "from the reference: the members' 1.4-1.5 kHz local modes ringing under "
                    "the 1 ms held forces, fed back by the strain loops (docs/coupling.md)")


@pytest.mark.xfail(strict=True, reason=SHIPPED_RESIDUAL)
def test_shipped_line_of_sight_within_one_percent_of_the_reference(shipped):
    los = next(o for o in shipped.outputs if o.output == "structure.los_tip_pitch")
    assert los.reference < 0.01


def test_shipped_reference_residual_regression_pin(shipped):
    """A regression pin, not a reference check: today's residuals of the shipped scenario
    against the sampled-data reference (%, of the run's peak; SHIPPED_RESIDUAL), to 5 %
    of their values; a change of the coupling, the laws or the structure moves them."""
    got = {o.output: 100 * o.reference for o in shipped.outputs}
    assert got["structure.los_tip_pitch"] == pytest.approx(1.148, rel=0.05)
    assert got["structure.strain_diag"] == pytest.approx(5.40, rel=0.05)
    assert got["structure.strain_long"] == pytest.approx(3.89, rel=0.05)


@pytest.mark.slow
@pytest.mark.paper
def test_the_shipped_residual_is_the_partition_step(fmus):
    """The cause of SHIPPED_RESIDUAL, tested: the same scenario, switch-on included, with
    structure and amplifiers at 0.25 ms is within 0.1 % of its reference on the line of
    sight (the hold of a 1.4 kHz ringing shrinks with the step), and at 1 ms with the
    members' two local modes (above 1 kHz) damped to 10 % it is within 0.2 %."""
    import dataclasses

    import scipy.linalg as la

    from orchestrator.analysis.scenario import LinearScenario
    from orchestrator.reference import simulate_switched, switch_on_ticks
    from orchestrator.scenario import load_scenario

    sc = _scenario("2.5e-4", stop=6.0)
    for m in ("diag", "long"):
        sc["fmus"][f"ctrl_{m}"]["parameters"] = {"t_on": 4.5}
    fine = check(sc, OUTS, fmu_dir=fmus, loops=False)
    los = {o.output: o for o in fine.outputs}["structure.los_tip_pitch"]
    assert los.reference < 1e-3

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lin = linearize(SCENARIO, fmu_dir=fmus)
    st = lin.blocks["structure"]
    A, B, C, D = st.continuous
    n = A.shape[0] // 2
    ev = np.linalg.eigvals(A)
    local = np.abs(ev) / (2 * np.pi) > 1000.0
    assert local.sum() == 4            # two modes, each a complex pair
    # the structure's second-order form (A = [[0, I], [-K, -D]]): raise the damping of
    # the block of the stiff modes (the Ritz block, where K is largest) to 10 % of critical
    stiff = np.flatnonzero(np.diag(-A[n:, :n]) > (2 * np.pi * 1000.0) ** 2)
    Kb = -A[n:, :n][np.ix_(stiff, stiff)]
    A2 = A.copy()
    A2[np.ix_(n + stiff, n + stiff)] -= 2 * 0.08 * np.real(la.sqrtm(Kb))
    zeta = -np.linalg.eigvals(A2)[np.abs(np.linalg.eigvals(A2)) / (2 * np.pi) > 1000.0]
    assert np.all(zeta.real / np.abs(zeta) > 0.09)
    h = st.period * lin.base
    M = np.zeros((A.shape[0] + B.shape[1],) * 2)
    M[:A.shape[0], :A.shape[0]], M[:A.shape[0], A.shape[0]:] = A2 * h, B * h
    E = la.expm(M)
    blocks = dict(lin.blocks)
    blocks["structure"] = dataclasses.replace(st, A=E[:A.shape[0], :A.shape[0]],
                                              B=E[:A.shape[0], A.shape[0]:], C=C, D=D,
                                              continuous=(A2, B, C, D))
    damped = LinearScenario(lin.plan, blocks, lin.order)
    ticks = switch_on_ticks(lin, load_scenario(SCENARIO))

    def w(name, k):
        t = k * lin.base
        return np.array([10 * np.sin(2 * np.pi * 8.4 * t) * (t < 4.5),
                         10 * np.sin(2 * np.pi * 9.5 * t) * (t < 4.5)])

    out = ["structure.los_tip_pitch"]
    y = simulate_switched(damped, 6000, w, out, ticks)[:, 0]
    y_ref = simulate_switched(sampled_data(damped), 6000, w, out, ticks)[:, 0]
    assert np.abs(y - y_ref).max() < 2e-3 * np.abs(y).max()


def test_cli_analyze_reference(fmus, capsys):
    from orchestrator.cli import main

    assert main(["analyze", SCENARIO, "--reference", "--stop", "1", "--fmu-dir", str(fmus),
                 "--output", "structure.los_tip_pitch"]) == 0
    out = capsys.readouterr().out
    assert "sampled-data reference" in out and "delay (us)" in out


def _step_study(fmus, capsys, period, *extra):
    """``jitterfmu analyze --reference`` of the shipped scenario with structure and
    amplifiers at ``period`` (the command docs/coupling.md gives): its output table."""
    from orchestrator.cli import main

    args = ["analyze", SCENARIO, "--reference", "--fmu-dir", str(fmus),
            "--output", "structure.los_tip_pitch", "--output", "structure.strain_diag"]
    for name in ("structure", "piezo_diag", "piezo_long"):
        args += ["--period", f"{name}={period}"]
    for m in ("diag", "long"):
        args += ["--set", f"piezo_{m}.hold_step={period}"]
    assert main(args + list(extra)) == 0
    rows = {"saturated": []}
    for line in capsys.readouterr().out.splitlines():
        if "the co-simulation reached" in line:
            rows["saturated"].append(line.split()[3])
        parts = line.split()
        if parts and parts[0] in ("structure.los_tip_pitch", "structure.strain_diag"):
            rows[parts[0]] = (float(parts[2]), float(parts[3].rstrip("%")))
    return rows


@pytest.mark.slow
@pytest.mark.paper
def test_cli_period_the_residual_falls_only_once_the_step_resolves_the_ringing(fmus,
                                                                              capsys):
    """The step study of docs/coupling.md, by its commands: at 0.5 ms the line of sight
    is further from the reference than at the shipped 1 ms (1.15 %), at 0.125 ms within
    0.05 % of it (measured 1.55 % and 0.016 %).  At 0.5 ms the diagonal's amplifier
    reaches its current limit inside steps, so the linear model departs from the
    co-simulation (5e-3 of the strain's peak) unless the limit is raised (then 1e-14);
    the co-simulation reports it (the amplifier's flag is set by a limit at any sub-step)
    and the report names it."""
    coarse = _step_study(fmus, capsys, "5e-4")
    assert coarse["structure.los_tip_pitch"][1] > 1.2
    assert coarse["structure.strain_diag"][0] > 1e-3          # the slew limit acts
    assert coarse["saturated"] == ["piezo_diag.sat_slew"]      # and is reported
    free = _step_study(fmus, capsys, "5e-4", "--set", "piezo_diag.i_max=1",
                       "--set", "piezo_long.i_max=1")
    assert free["structure.strain_diag"][0] < 1e-12
    assert free["saturated"] == []
    assert free["structure.los_tip_pitch"][1] == pytest.approx(
        coarse["structure.los_tip_pitch"][1], abs=0.02)
    fine = _step_study(fmus, capsys, "1.25e-4")
    assert fine["structure.los_tip_pitch"][1] < 0.05


def test_periods_of_a_scenario_are_checked():
    """``--period`` (Scenario.with_periods): an unknown instance or a non-positive or
    unreadable period is one sentence."""
    from orchestrator.cli import main
    from orchestrator.scenario import ScenarioError, load_scenario

    sc = load_scenario(SCENARIO)
    assert sc.with_periods({"structure": "5e-4"}).instance("structure").period * 2000 == 1
    with pytest.raises(ScenarioError, match="no instance of the scenario"):
        sc.with_periods({"structur": 1e-3})
    with pytest.raises(ScenarioError, match="expected a positive time"):
        sc.with_periods({"structure": 0})
    with pytest.raises(ScenarioError, match="is not INST=SECONDS"):
        from orchestrator.cli.analyze import _with_periods
        _with_periods(SCENARIO, ["structure"])
    assert main(["analyze", SCENARIO, "--period", "structure"]) != 0


@pytest.mark.slow
@pytest.mark.paper
def test_testbed_experiment_as_shipped_against_its_reference(suite_fmu_dir):
    """The testbed-isolation experiment's mount-#3 run as it ships (the cryocooler at
    SWIR, the robust gains, switch-on at 8.4 s; scenarios/eos_budget.toml): the linear
    model equals the co-simulation to round-off through the switch-on, and the
    reference's payload accelerometer and strut command are within 1 % of their peaks
    (measured 0.24 % and 0.08 %; docs/coupling.md)."""
    from orchestrator.experiments import eos
    from orchestrator.experiments import testbed_isolation as ti

    fdir = ti.ensure_fmus(suite_fmu_dir)
    ov = {"dist_swir.preset": "swir_cryocooler"}
    for i, g in zip((1, 2, 3), (0.0, 0.0, ti.GAINS["mount3"])):
        ov[f"ctrl_iso{i}.gain"] = g
        ov[f"ctrl_iso{i}.t_on"] = ti.T_ON
    outs = ["structure.acc_pay_iso3", "ctrl_iso3.u1", "structure.los_misr_pitch"]
    res = check(eos.SCENARIO, outs, stop_time=ti.T_ON + 4.1, overrides=ov, fmu_dir=fdir,
                loops=False)
    got = {o.output: o for o in res.outputs}
    assert all(o.linear < 1e-9 for o in res.outputs)
    assert got["structure.acc_pay_iso3"].reference < 0.01
    assert got["ctrl_iso3.u1"].reference < 0.01
