"""The master is exact: the ten-bay closed loop co-simulated equals the loop assembled by hand.

The co-simulation runs the six FMUs of ``scenarios/truss10_closed_loop.toml`` (structure,
two piezo amplifiers, two 250 Hz strain-feedback controllers with an additive excitation
input ``r1``, excitation).  The loop is kept linear: small excitation (1 V), no rail or
slew limit reached (checked), no hysteresis, no gauge noise (the FMU defaults).  Every
signal is compared relative to its own peak, to 1e-9.

Timing of one tick ``t_k`` in the master (:mod:`orchestrator.cosim`, Gauss–Seidel)
------------------------------------------------------------------------------------
* Step order is the topological order of the direct-feedthrough graph
  (:func:`orchestrator.cosim.graph.step_groups`).  Only the controller outputs ``u1`` have
  feedthrough (from ``r1``), so the edges are ``ctrl_* -> piezo_*``: each controller
  steps before its amplifier.  Strain, elongation, force and the excitation have none.
  The piezo ``force`` has feedthrough from ``v_cmd`` (``coupling = 1``, the default: the
  mean force over the coming step with the command held), so each amplifier steps
  before the structure: ``ctrl_* -> piezo_* -> structure``.
* An input fed by an output *without* feedthrough reads the source's value at ``t_k``:
  a controller reads ``strain(t_k)`` and the excitation ``v(t_k)``; a 4 ms source is read
  at the value it had at the last of its own communication points.  With
  ``coupling = 0`` the structure reads ``force(t_k)``, the amplifier state at ``t_k``
  (the command of ``t_k`` reaches it one step later).
* An input fed by a feedthrough output reads the output at ``t_k`` for the inputs set at
  ``t_k`` (FMI 2.0): every due instance first gets its inputs (sources first) and a
  feedthrough source's outputs are read then, before any instance steps.  The
  controller's output at ``t_j`` is ``w_j + r_j`` with ``w_j = clip(C x_{j-1} + D
  y_{j-1})`` computed at the previous sample (Eq. 11's one-sample delay), held over
  ``[t_j, t_{j+1})``.
* Recorded rows hold each variable's value at ``t_k`` before the tick's steps (for a
  feedthrough output: the value read for the inputs at ``t_k``).

Jacobi: every input reads its source's value at ``t_k``; the amplifier then gets the
controller output computed at ``t_{j-1}``, i.e. Eq. 11 with the excitation one controller
sample late (libcosim's fixed-step algorithm, checked on the exported SSP archive), and
the structure the mean force published after the amplifier's last step, for the command
it held then.
"""

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import control
import numpy as np
import pytest
import scipy.signal
import tomli_w

from ctrlfmu import law as lawmod
from ctrlfmu.designs import design
from distfmu.excitation import sine_burst
from orchestrator import run_scenario
from piezofmu import actuator as ac
from piezofmu.amplifier import AmplifierState
from structfmu import discrete
from structfmu.models import truss10
from structfmu.statespace import first_order

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "truss10_closed_loop.toml"
FMUS = ("truss10_structure", "piezo_p243_40", "piezo_p243_30",
        "controller_truss10_strain_diag", "controller_truss10_strain_long", "excitation")
MEMBERS = {"diag": ("P-243.40", "truss10_strain_diag", 8.4),
           "long": ("P-243.30", "truss10_strain_long", 9.5)}
RTOL = 1e-9
AMP = 1.0         # V: the commands stay far below rails and slew limit
T_STOP = 1.0005   # s: burst end between communication points (no rounding-sensitive edge)
RECORD = ["structure.strain_diag", "structure.strain_long", "structure.los_tip_pitch",
          "piezo_diag.voltage", "piezo_long.voltage", "ctrl_diag.u1", "ctrl_long.u1",
          "piezo_diag.sat_voltage", "piezo_long.sat_voltage",
          "piezo_diag.sat_slew", "piezo_long.sat_slew"]
SIGNALS = [r for r in RECORD if ".sat_" not in r]


@pytest.fixture(scope="module")
def fmu_dir(suite_fmus, suite_fmu_dir):
    suite_fmus(*FMUS)
    return suite_fmu_dir


def closed_loop(*, stop, t_on, one_rate=None, output_interval=1e-3, coupling=1):
    """The closed-loop scenario as a dict, linear, optionally with every period ``one_rate``."""
    sc = tomllib.loads(SCENARIO.read_text(encoding="utf-8"))
    if one_rate is not None:
        for inst in sc["fmus"].values():
            inst["period"] = one_rate
    for m in MEMBERS:
        sc["fmus"][f"piezo_{m}"]["parameters"] = {
            "coupling": coupling, "hold_step": float(sc["fmus"][f"piezo_{m}"]["period"])}
    sc["fmus"]["structure"]["parameters"] = {"f_tip_x": 0.0, "f_tip_y": 0.0}
    for m in MEMBERS:
        sc["fmus"][f"ctrl_{m}"]["parameters"] = {"t_on": t_on, "enable": True}
    sc["fmus"]["excitation"]["parameters"] = {
        "amp1": AMP, "freq1": MEMBERS["diag"][2], "amp2": AMP, "freq2": MEMBERS["long"][2],
        "t_stop": T_STOP}
    sc["experiment"].update(stop=stop, output_interval=output_interval)
    sc["record"]["variables"] = RECORD
    return sc


def excitation(m, t):
    """Excitation channel of member ``m`` at times ``t`` (what the FMU outputs there)."""
    return sine_burst(t, AMP, MEMBERS[m][2], 0.0, T_STOP)


def rel_err(actual, desired):
    """Largest difference relative to the peak of ``desired``."""
    return float(np.max(np.abs(actual - desired)) / np.max(np.abs(desired)))


def assert_linear_region(table):
    for ref in RECORD:
        if ".sat_" in ref:
            assert not np.any(table[ref]), f"{ref} became active: the loop is not linear"


# ----------------------------------------------------------------------------------------
# 1. one rate: monolithic discrete loop assembled with python-control

H1 = 4e-3


def structure_ss(model, h):
    """Structure: Eq. (9)-(10) discretised with ZOH by scipy (independent of the FMU kernel)."""
    A, B, C, D = first_order(model)
    Ad, Bd, Cd, Dd, _ = scipy.signal.cont2discrete((A, B, C, D), h, method="zoh")
    return control.ss(Ad, Bd, Cd, Dd, h, inputs=list(model.input_names),
                      outputs=list(model.output_names), name="structure")


def amplifier_map(act, h):
    """Exact one-step map ``[v, dv/dt, f_mean](k+1) = A [v, dv/dt](k) + B v_cmd(k)`` over
    ``h``, with ``f_mean`` the mean force over the step (``piezofmu.actuator.step_mean``).

    The amplifier sub-steps internally (``h / internal_step`` exact ZOH steps of its
    second-order low-pass); without an active limit that composition is linear, so its
    matrices are the responses of the pure step function to unit states and a unit input.
    """
    def one(v, rate, cmd):
        state, _, mean = ac.step_mean(act, ac.ActuatorState(AmplifierState(v, rate)), cmd, h)
        return np.array([state.amp.voltage, state.amp.rate, mean])

    A = np.column_stack([one(1.0, 0.0, 0.0), one(0.0, 1.0, 0.0)])
    B = one(0.0, 0.0, 1.0)[:, None]
    # the probe is legitimate only if the step is linear there: check superposition
    # (round-off of a few hundred sub-steps, relative to the terms summed)
    x, u = np.array([3.0, -2.0e3]), 5.0
    scale = np.max(np.abs(A) @ np.abs(x) + np.abs(B[:, 0]) * abs(u))
    np.testing.assert_allclose(one(*x, u), A @ x + B[:, 0] * u, rtol=0, atol=1e-10 * scale)
    return A, B


def amplifier_ss(m, h):
    """Amplifier + stack: outputs ``force`` (N), the mean over the coming step for the
    command held (direct feedthrough), and ``voltage`` (V)."""
    act = ac.actuator_preset(MEMBERS[m][0])
    A, B = amplifier_map(act, h)
    return control.ss(A[:2], B[:2], [A[2], [1.0, 0.0]], [B[2], [0.0]], h, inputs=["v_cmd"],
                      outputs=["force", "voltage"], name=f"piezo_{m}")


def controller_ss(m, h, delayed):
    """Controller ``u1 = law(y1) + r1``; Eq. (11)'s delay as a held-command state if asked.

    ``delayed=False``: ``u(k) = C x(k) + D y(k) + r(k)`` (the master's Gauss–Seidel timing).
    ``delayed=True``: Eq. (11), ``u(k) = w(k) + r(k)`` with ``w(k+1) = C x(k) + D y(k)``.
    """
    law = design(MEMBERS[m][1])
    assert law.dt == h
    n = law.n_states
    if not delayed:
        return control.ss(law.A, np.hstack([law.B, np.zeros((n, 1))]), law.C,
                          np.hstack([law.D, [[1.0]]]), h, inputs=["y1", "r1"],
                          outputs=["u1"], name=f"ctrl_{m}")
    A = np.block([[law.A, np.zeros((n, 1))], [law.C, np.zeros((1, 1))]])
    B = np.block([[law.B, np.zeros((n, 1))], [law.D, np.zeros((1, 1))]])
    C = np.hstack([np.zeros((1, n)), [[1.0]]])
    return control.ss(A, B, C, [[0.0, 1.0]], h, inputs=["y1", "r1"], outputs=["u1"],
                      name=f"ctrl_{m}")


def monolithic(n_rows, delayed):
    """Outputs of the interconnected discrete loop for the excitation sequence, by name."""
    model = truss10.reduced()
    keep_in = [f"fc_{m}" for m in MEMBERS]
    keep_out = ["strain_diag", "strain_long", "los_tip_pitch"]
    full = structure_ss(model, H1)
    iu = [list(model.input_names).index(n) for n in keep_in]
    iy = [list(model.output_names).index(n) for n in keep_out]
    struct = control.ss(full.A, full.B[:, iu], full.C[iy], full.D[np.ix_(iy, iu)], H1,
                        inputs=keep_in, outputs=keep_out, name="structure")
    parts = [struct] + [amplifier_ss(m, H1) for m in MEMBERS] \
        + [controller_ss(m, H1, delayed) for m in MEMBERS]
    connections = []
    for m in MEMBERS:
        connections += [[f"ctrl_{m}.y1", f"structure.strain_{m}"],
                        [f"piezo_{m}.v_cmd", f"ctrl_{m}.u1"],
                        [f"structure.fc_{m}", f"piezo_{m}.force"]]
    loop = control.interconnect(parts, connections=connections,
                                inplist=[f"ctrl_{m}.r1" for m in MEMBERS], outlist=SIGNALS)
    t = np.arange(n_rows) * H1
    r = np.vstack([excitation(m, t) for m in MEMBERS])
    y = control.forced_response(loop, T=t, U=r).outputs
    return dict(zip(SIGNALS, y))


@pytest.fixture(scope="module")
def one_rate_run(fmu_dir):
    table = run_scenario(closed_loop(stop=2.0, t_on=0.0, one_rate=H1, output_interval=H1),
                         fmu_dir=fmu_dir).table
    assert_linear_region(table)
    return table


def compare_one_rate(table, ref, signals):
    errors = {}
    for s in signals:
        got, want = table[s], ref[s]
        if s.endswith(".u1"):  # the command applied over [t_k, t_k+1) is recorded at t_k+1
            got, want = got[1:], want[:-1]
        errors[s] = rel_err(got, want)
    return errors


def test_one_rate_cosimulation_equals_the_monolithic_discrete_loop(one_rate_run):
    ref = monolithic(len(one_rate_run["time"]), delayed=True)
    # the commands u1 are compared exactly in the multi-rate test below
    signals = [s for s in SIGNALS if not s.endswith(".u1")]
    errors = compare_one_rate(one_rate_run, ref, signals)
    assert max(errors.values()) < RTOL, errors
    assert np.max(np.abs(ref["structure.strain_diag"])) > 1e-8  # the loop really moved
    assert np.max(np.abs(ref["ctrl_long.u1"] - excitation("long", one_rate_run["time"]))) > 0.1


def test_gauss_seidel_keeps_eq11_delay(one_rate_run):
    # without Eq. 11's one-sample delay the loop is measurably different: the
    # comparison above would catch a master that dropped it
    ref = monolithic(len(one_rate_run["time"]), delayed=False)
    signals = [s for s in SIGNALS if not s.endswith(".u1")]
    errors = compare_one_rate(one_rate_run, ref, signals)
    assert max(errors.values()) > 0.05, errors


# ----------------------------------------------------------------------------------------
# 2. multi-rate: plain numpy loop over 1 kHz ticks calling the pure step functions

H2 = 1e-3
P_CTRL = 4        # controller and excitation period in 1 ms ticks
T_ON = 0.5        # s: controllers switch on inside the run (state reset before)


def multirate_reference(n_ticks, algorithm, coupling=1):
    """Recorded signals at every 1 ms tick, built from the packages' pure step functions.

    Controllers sample at ticks ``k = 4 j`` (``ctrlfmu.law.step``); their command is held
    (ZOH) for the amplifiers, which step at 1 kHz with the structure.  Gauss–Seidel: the
    amplifiers get ``w + r(t_j)``, ``w`` the law output computed at the previous sample
    (Eq. 11), which is also what is recorded; Jacobi: the controller output published
    after its previous step (``o_{j-1}``), recorded from the controller's next
    communication point on.  The structure holds, per amplifier, the mean force over the
    step for the command it gets at ``t_k`` (``coupling = 1``; Jacobi: for the command it
    held before), or the force of its state at ``t_k`` (``coupling = 0``).
    """
    model = truss10.reduced()
    dm = discrete.discretize(model, H2)
    names_in, names_out = list(model.input_names), list(model.output_names)
    acts = {m: ac.actuator_preset(MEMBERS[m][0]) for m in MEMBERS}
    laws = {m: design(MEMBERS[m][1]).with_t_on(T_ON) for m in MEMBERS}
    x = np.zeros(model.n_states)
    amp = {m: ac.initial_state(acts[m]) for m in MEMBERS}
    ctl = {m: lawmod.initial_state(laws[m]) for m in MEMBERS}
    o_new = {m: 0.0 for m in MEMBERS}   # output of the latest sample (initially r(0) = 0)
    o_old = dict(o_new)                 # output of the sample before
    w = {m: 0.0 for m in MEMBERS}       # Gauss-Seidel: law output pending (Eq. 11)
    gs_cmd = {m: 0.0 for m in MEMBERS}  # Gauss-Seidel: command held over the sample
    held = {m: 0.0 for m in MEMBERS}    # command each amplifier held over the last step
    out = {s: np.empty(n_ticks + 1) for s in SIGNALS}
    for k in range(n_ticks + 1):
        y = discrete.output(model, x, np.zeros(model.n_inputs))
        for s in ("strain_diag", "strain_long", "los_tip_pitch"):
            out[f"structure.{s}"][k] = y[names_out.index(s)]
        if k % P_CTRL == 0:
            for m in MEMBERS:
                gs_cmd[m] = w[m] + float(excitation(m, k * H2))
        for m in MEMBERS:
            out[f"piezo_{m}.voltage"][k] = amp[m].amp.voltage
            if algorithm == "gauss-seidel":
                out[f"ctrl_{m}.u1"][k] = gs_cmd[m]
            else:
                out[f"ctrl_{m}.u1"][k] = (o_new[m] if k % P_CTRL == 0
                                          else out[f"ctrl_{m}.u1"][k - 1])
        if k == n_ticks:
            break
        if k % P_CTRL == 0:
            for m in MEMBERS:
                ctl[m], u = lawmod.step(laws[m], ctl[m], y[names_out.index(f"strain_{m}")])
                o_old[m], o_new[m] = o_new[m], float(u[0]) + float(excitation(m, k * H2))
                w[m] = float(u[0])
        command = gs_cmd if algorithm == "gauss-seidel" else o_old
        forces = np.zeros(model.n_inputs)
        for m in MEMBERS:
            if coupling == 0:
                f = ac.outputs(acts[m], amp[m]).force
            else:
                seen = command[m] if algorithm == "gauss-seidel" else held[m]
                f = ac.step_mean(acts[m], amp[m], seen, H2)[2]
            forces[names_in.index(f"fc_{m}")] = f
        x = discrete.step(dm, x, forces)
        for m in MEMBERS:
            amp[m], _ = ac.step(acts[m], amp[m], command[m], H2)
            held[m] = command[m]
    return out


@pytest.mark.parametrize("algorithm,coupling", [("gauss-seidel", 1), ("jacobi", 1),
                                                ("gauss-seidel", 0)])
def test_multirate_cosimulation_equals_the_reference_loop(fmu_dir, algorithm, coupling):
    stop = 2.0
    table = run_scenario(closed_loop(stop=stop, t_on=T_ON, coupling=coupling),
                         algorithm=algorithm, fmu_dir=fmu_dir).table
    assert_linear_region(table)
    ref = multirate_reference(round(stop / H2), algorithm, coupling)
    errors = {s: rel_err(table[s], ref[s]) for s in SIGNALS}
    assert max(errors.values()) < RTOL, errors
    # after the burst the commands are the laws' alone: the loop is closed
    after = table["time"] > T_STOP + 0.01
    for m in MEMBERS:
        assert np.max(np.abs(table[f"ctrl_{m}.u1"][after])) > 0.05


# ----------------------------------------------------------------------------------------
# 3. the exported SSP archive in libcosim equals the master's Jacobi run

LIBCOSIM_CHILD = r"""
import json, os, sys
import numpy as np
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimObserver import CosimObserver

job = json.loads(sys.argv[1])
ex = CosimExecution.from_ssp_file(job["ssp"])
obs = CosimObserver.create_last_value()
ex.add_observer(obs)
refs = []
for ref in job["record"]:
    inst, var = ref.split(".", 1)
    i = ex.slave_index_from_instance_name(inst)
    vr = next(v.reference for v in ex.slave_variables(i) if v.name.decode() == var)
    refs.append((i, vr))
rows = np.empty((job["n_steps"], len(refs)))
for k in range(job["n_steps"]):
    if not ex.step(1):
        sys.stderr.write(f"libcosim step {k} failed\n")
        sys.stderr.flush()
        os._exit(3)
    rows[k] = [obs.last_real_values(i, [vr])[0] for i, vr in refs]
np.save(job["out"], rows)
sys.stdout.flush()
sys.stderr.flush()
os._exit(0)  # no interpreter teardown while libcosim's pythonfmu slaves are alive
"""


def run_libcosim_ssp(ssp, record, n_steps, tmp_path):
    """Run an SSP archive in libcosim in a child process; rows after every base step."""
    out = tmp_path / "libcosim.npy"
    job = {"ssp": str(ssp), "record": record, "n_steps": n_steps, "out": str(out)}
    proc = subprocess.run([sys.executable, "-c", LIBCOSIM_CHILD, json.dumps(job)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0 and out.is_file(), proc.stderr[-2000:]
    return np.load(out)


def test_libcosim_runs_the_exported_closed_loop_like_jacobi(fmu_dir, tmp_path):
    from orchestrator.cli import main

    stop = 1.5
    toml = tmp_path / "truss10_linear.toml"
    toml.write_text(tomli_w.dumps(closed_loop(stop=stop, t_on=T_ON)))
    ssp = tmp_path / "truss10_linear.ssp"
    assert main(["export-ssp", str(toml), str(ssp), "--fmu-dir", str(fmu_dir)]) == 0
    ours = run_scenario(ssp, algorithm="jacobi", fmu_dir=fmu_dir).table
    theirs = run_libcosim_ssp(ssp, SIGNALS, round(stop / H2), tmp_path)
    # each variable at its own instance's communication points, where both masters show
    # the output of the step that just ended
    for j, ref in enumerate(SIGNALS):
        p = P_CTRL if ref.startswith("ctrl_") else 1
        rows = np.arange(p, len(ours["time"]), p)
        assert rel_err(theirs[rows - 1, j], ours[ref][rows]) < RTOL, ref
    assert np.max(np.abs(ours["structure.strain_long"])) > 1e-8
