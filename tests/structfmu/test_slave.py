"""The structure slave as a plain Python object (no FMU build), against the pure
discretisation functions of :mod:`structfmu.discrete`."""

import numpy as np
import pytest

from structfmu.discrete import simulate
from structfmu.slave import StructureSlave

H = 1e-3


def make(model, tmp_path):
    model.save(tmp_path / "model.npz")
    slave = StructureSlave(instance_name="structure", resources=str(tmp_path))
    slave.enter_initialization_mode()
    slave.exit_initialization_mode()
    return slave


def vrs(slave, names):
    by_name = {s.name: s.value_reference for s in slave.variable_specs}
    return [by_name[n] for n in names]


def drive(slave, model, u):
    """Outputs at t_k for the inputs of step k, as the master reads them."""
    ins, outs = vrs(slave, model.input_names), vrs(slave, model.output_names)
    rows = []
    for k, uk in enumerate(u):
        slave.set_real(ins, list(uk))
        rows.append(slave.get_real(outs))
        slave.do_step(k * H, H)
    return np.array(rows)


def loads(model, n=80, seed=3):
    rng = np.random.default_rng(seed)
    return rng.standard_normal((n, model.n_inputs))


def test_slave_equals_the_pure_simulation(truss10_reduced, tmp_path):
    model, _ = truss10_reduced
    u = loads(model)
    want, _ = simulate(model, H, u)
    got = drive(make(model, tmp_path), model, u)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())


def test_accelerations_feed_through_and_the_rest_waits_for_the_step(truss10_reduced,
                                                                     tmp_path):
    model, _ = truss10_reduced
    slave = make(model, tmp_path)
    ins, outs = vrs(slave, model.input_names), vrs(slave, model.output_names)
    slave.set_real(ins, [1.0] * model.n_inputs)
    slave.do_step(0.0, H)
    before = np.array(slave.get_real(outs))
    u = loads(model, 1)[0]
    slave.set_real(ins, list(u))
    after = np.array(slave.get_real(outs))
    acc = model.is_accel
    assert acc.any()
    # only the accelerations change when the inputs change, and by exactly D u
    np.testing.assert_array_equal(after[~acc], before[~acc])
    want, _ = simulate(model, H, np.vstack([np.ones(model.n_inputs), u]))
    np.testing.assert_allclose(after[acc], want[1][acc], rtol=1e-12)
    specs = {s.name: s for s in slave.variable_specs}
    for name, is_acc in zip(model.output_names, acc):
        assert bool(specs[name].depends_on) == bool(is_acc)


def test_fmu_state_round_trip_replays_the_same_outputs(truss10_reduced, tmp_path):
    model, _ = truss10_reduced
    slave = make(model, tmp_path)
    u = loads(model, 60)
    drive(slave, model, u[:20])
    saved = slave._fmu_state_to_bytes(slave._get_fmu_state())
    first = drive(slave, model, u[20:])
    slave._set_fmu_state(slave._fmu_state_from_bytes(saved))
    again = drive(slave, model, u[20:])
    np.testing.assert_array_equal(first, again)


def test_another_step_size_is_discretised_exactly(truss10_reduced, tmp_path):
    model, _ = truss10_reduced
    slave = make(model, tmp_path)
    ins, outs = vrs(slave, model.input_names), vrs(slave, model.output_names)
    u = loads(model, 1)[0]
    slave.set_real(ins, list(u))
    slave.do_step(0.0, 2.5e-3)
    want, _ = simulate(model, 2.5e-3, np.vstack([u, u]))
    np.testing.assert_allclose(slave.get_real(outs), want[1],
                               rtol=0, atol=1e-12 * np.abs(want[1]).max())
    with pytest.raises(FileNotFoundError, match="model.npz"):
        StructureSlave(instance_name="s", resources=str(tmp_path / "nowhere"))
