"""The EOS Dynamics Testbed-like model: rigid-body modes, calibration, sensors, reduction."""

from dataclasses import replace

import numpy as np
import pytest

from structfmu.fem import assemble, channel_matrix
from structfmu.models import eos_testbed as eos
from structfmu.statespace import frf, full_frf


@pytest.fixture(scope="module")
def truss():
    return eos.build()


@pytest.fixture(scope="module")
def modes(truss):
    return eos.modes(truss, 40)


@pytest.fixture(scope="module")
def red(truss):
    return eos.reduced(truss=truss)


def _rigid_field(truss, t=(0.0, 0.0, 0.0), theta=(0.0, 0.0, 0.0)):
    """Small rigid motion u_i = t + theta x (x_i - x_0) on all DOFs, shape (n_dof,)."""
    r = truss.nodes - truss.nodes.mean(axis=0)
    return (np.asarray(t) + np.cross(np.asarray(theta), r)).ravel()


def _read(truss, names, u):
    chans = {c.name: c for c in truss.outputs}
    return channel_matrix([chans[n] for n in names], truss.n_dof) @ u


# -- modes ---------------------------------------------------------------------------------
def test_free_free_six_rigid_body_modes(truss, modes):
    f, _ = modes
    assert np.all(f[:6] == 0.0)
    assert f[6] > 0.3                       # no seventh zero: no mechanism anywhere
    # the six rigid fields are in the null space of the assembled stiffness
    K, _ = assemble(truss)
    for t, th in [((1, 0, 0), (0, 0, 0)), ((0, 1, 0), (0, 0, 0)), ((0, 0, 1), (0, 0, 0)),
                  ((0, 0, 0), (1, 0, 0)), ((0, 0, 0), (0, 1, 0)), ((0, 0, 0), (0, 0, 1))]:
        u = _rigid_field(truss, t, th)
        assert np.linalg.norm(K @ u) < 1e-6 * abs(K).max() * np.linalg.norm(u)


def test_suspension_puts_rigid_body_modes_below_0p3_hz():
    f = eos.frequencies_hz(eos.build(suspension=True), 8)
    assert np.all((f[:6] > 0.02) & (f[:6] < 0.3))   # paper: all six below 0.3 Hz
    assert f[6] > 0.45                               # the array mode stays near 0.5 Hz


def test_first_array_mode_is_0p5_hz(truss, modes):
    m, f = eos.first_mode_of("array", truss)
    assert m == 6                                    # the first flexible mode
    assert f == pytest.approx(0.5, rel=0.10)         # paper: first solar array mode 0.5 Hz


def test_first_bus_mode_is_23_hz_and_the_first_one_mostly_in_the_bus(truss, modes):
    f, phi = modes
    bus = np.nan_to_num(eos.strain_energy_fractions(truss, phi)["bus"])
    m, fb = eos.first_mode_of("bus", truss)
    assert fb == pytest.approx(23.0, rel=0.10)       # paper: first bus mode 23 Hz
    assert bus[m] >= 0.5
    assert np.all(bus[6:m] < 0.5)                    # every earlier flexible mode is not
    assert m > 6                                     # array and antenna modes come first


def test_strain_energy_fractions_sum_to_one(truss, modes):
    _, phi = modes
    frac = eos.strain_energy_fractions(truss, phi[:, 6:])
    np.testing.assert_allclose(sum(frac.values()), 1.0, rtol=1e-12)


def test_calibration_reproduces_stored_constants():
    eta, ea = eos.calibrate()
    assert eta == pytest.approx(eos.ETA_BUS, rel=1e-3)
    assert ea == pytest.approx(eos.EA_ARRAY, rel=1e-3)


def test_hybrid_mount3_calibration_and_elastomer_mode():
    # build(iso3="hybrid"): mount #3's stack in series with an elastomer stage; the bus
    # and array keep their paper frequencies with their own stored constants
    eta, ea = eos.calibrate(iso3="hybrid")
    assert eta == pytest.approx(eos.ETA_BUS_HYBRID, rel=1e-3)
    assert ea == pytest.approx(eos.EA_ARRAY_HYBRID, rel=1e-3)
    t = eos.build(iso3="hybrid")
    assert eos.first_mode_of("bus", t)[1] == pytest.approx(23.0, rel=1e-3)
    assert eos.first_mode_of("array", t)[1] == pytest.approx(0.5, rel=1e-3)
    # one elastomer element, in iso3 only; its share of the element's energy is the
    # series compliance ratio
    (i, share), = eos._elastomer_elements(t)
    assert set(t.elements[i]) == {t.node("misr_fit_iso3"), t.node("misr_p2")}
    _, length = t.element_geometry()
    k_rod = eos.E_AL * eos.ROD_AREA / length[i]
    assert share == pytest.approx(k_rod / (k_rod + eos.ISO3_SERIES_K), rel=1e-9)
    assert eos._elastomer_elements(eos.build()) == []
    # the mount mode: MISR plate pitch on the elastomer at about 15.7 Hz, damped by the
    # modal strain energy method (loss factor / 2 x its elastomer energy fraction)
    f, phi = eos.modes(t, 40)
    frac = eos.elastomer_fractions(t, phi)
    m = int(np.argmax(frac))
    assert 15.0 < f[m] < 16.5 and frac[m] > 0.8
    d = eos.damping(40, t)
    assert d.zeta[m] == pytest.approx(eos.ZETA + 0.5 * eos.ISO3_LOSS_FACTOR * frac[m])


# -- sensors and loads -----------------------------------------------------------------------
def test_angle_outputs_read_a_rigid_rotation(truss):
    theta = np.array([3e-6, -2e-6, 5e-6])
    u = _rigid_field(truss, t=(1e-4, -2e-4, 3e-4), theta=theta)
    for prefix in [f"los_{i}" for i in eos.INSTRUMENTS] + ["att"]:
        y = _read(truss, [f"{prefix}_{ax}" for ax in ("roll", "pitch", "yaw")], u)
        np.testing.assert_allclose(y, theta, rtol=1e-9, atol=1e-18)
    y = _read(truss, ["rate_roll", "rate_pitch", "rate_yaw"], u)   # same rows, rate kind
    np.testing.assert_allclose(y, theta, rtol=1e-9)
    # a rigid motion does not strain the mounts
    names = [c.name for c in truss.outputs if c.kind in ("strain", "elong")]
    assert len(names) == 10
    assert np.abs(_read(truss, names, u)).max() < 1e-12 * np.abs(u).max()


def test_los_output_follows_its_own_payload_only(truss):
    # rotate only the MISR gimballed body: MISR reads it, the other instruments read 0
    u = np.zeros(truss.n_dof)
    idx = [truss.node(n) for n in eos.payload_nodes("misr")]
    r = truss.nodes[idx] - truss.nodes[idx].mean(axis=0)
    theta = np.array([0.0, 4e-6, 0.0])
    for i, ri in zip(idx, r):
        u[3 * i:3 * i + 3] = np.cross(theta, ri)
    assert _read(truss, ["los_misr_pitch"], u)[0] == pytest.approx(4e-6, rel=1e-9)
    other = _read(truss, [f"los_{i}_pitch" for i in ("ceres", "tir", "swir", "vnir")], u)
    assert np.all(other == 0.0)


def test_accelerometers_in_line_with_each_isolator_strut(truss):
    chans = {c.name: c for c in truss.outputs}
    e, _ = truss.element_geometry()
    act = {a.name: a for a in truss.active}
    for k in (1, 2, 3):
        pay, bus = chans[f"acc_pay_iso{k}"], chans[f"acc_bus_iso{k}"]
        assert pay.kind == bus.kind == "accel"
        n_stack_bus, _ = truss.elements[act[f"iso{k}"].element]
        assert bus.dofs[0] // 3 == n_stack_bus
        assert truss.node_names and [n for n, i in truss.node_names.items()
                                     if i == bus.dofs[0] // 3][0].startswith("bus_")
        assert [n for n, i in truss.node_names.items()
                if i == pay.dofs[0] // 3][0] == f"misr_p{k - 1}"
        axis = e[act[f"iso{k}"].element]
        np.testing.assert_allclose(pay.weights, axis, atol=1e-12)
        np.testing.assert_allclose(bus.weights, axis, atol=1e-12)
    # a rigid translation along the strut axis reads 1 on both; across it, 0
    u = _rigid_field(truss, t=axis)
    names = [f"acc_{s}_{leg}" for s in ("pay", "bus") for leg in ("iso1", "iso2", "iso3", "tube")]
    np.testing.assert_allclose(_read(truss, names, u), 1.0, rtol=1e-12)
    u = _rigid_field(truss, t=np.cross(axis, [1.0, 0, 0]))
    assert np.abs(_read(truss, names, u)).max() < 1e-12


def test_misr_isolators_are_p845_37_stacks(truss, red):
    from piezofmu import preset
    stack = preset("P-845.37")
    _, length = truss.element_geometry()
    names = [a.name for a in truss.active]
    assert names == ["iso1", "iso2", "iso3", "swir_mount", "vnir_mount"]
    for a in truss.active:
        assert a.stack.name == "P-845.37"
        assert truss.axial_stiffness[a.element] == pytest.approx(stack.k_e, rel=1e-12)
        assert truss.element_mass[a.element] == pytest.approx(stack.mass, rel=1e-12)
        assert length[a.element] == pytest.approx(stack.length, rel=1e-12)
        assert red.meta["actuators"][a.name]["ch"] == pytest.approx(stack.ch, rel=1e-12)
        # the gauge is on the stack: strain = elongation / stack length
        assert a.gauge_element == a.element


def test_all_sixty_two_inputs_and_load_resultants(truss):
    names = [c.name for c in truss.input_channels]
    assert len(names) == 9 * 6 + 3 + 5
    assert names[:6] == ["ceres_fx", "ceres_fy", "ceres_fz", "ceres_mx", "ceres_my", "ceres_mz"]
    assert {f"{loc}_{c}" for loc in eos.LOCATIONS for c in eos.WRENCH} <= set(names)
    for c in truss.loads:
        nodes = np.asarray(c.dofs)[::3] // 3
        F = np.asarray(c.weights).reshape(-1, 3)
        r = truss.nodes[nodes] - truss.nodes[nodes].mean(axis=0)
        force, moment = F.sum(axis=0), np.cross(r, F).sum(axis=0)
        comp = c.name.rsplit("_", 1)[1]
        want = np.zeros(6)
        want[{"fx": 0, "fy": 1, "fz": 2, "mx": 3, "my": 4, "mz": 5,
              "tx": 3, "ty": 4, "tz": 5}[comp]] = 1.0
        np.testing.assert_allclose(np.r_[force, moment], want, atol=1e-12)
        assert c.kind == ("force" if comp.startswith("f") else "torque")


def test_swir_loads_act_on_the_swir_payload(truss):
    chans = {c.name: c for c in truss.loads}
    nodes = {truss.node(n) for n in ["swir_cg", "swir_p0", "swir_p1", "swir_p2", "swir_p3"]}
    assert set(np.asarray(chans["swir_fz"].dofs) // 3) == nodes


def test_all_legs_active_variant_keeps_six_rigid_modes():
    t = eos.build(active_legs="all")
    names = [a.name for a in t.active]
    assert [n for n in names if n.startswith("swir")] == [f"swir_mount{i}" for i in range(1, 7)]
    assert len(names) == 3 + 12
    f = eos.frequencies_hz(t, 7)
    assert np.all(f[:6] == 0.0) and f[6] > 0.3


def test_misr_gimbal_modes_near_8_hz(truss):
    # paper: the payloads point with about 8 Hz bandwidth; the gimbal servo is the
    # spring J (2 pi 8 Hz)^2 on roll and pitch of the body relative to the plate
    g = eos.gimbal_modes(truss)
    f, _ = eos.modes(truss, 20)
    assert g.size == 2
    np.testing.assert_allclose(f[g], eos.GIMBAL_HZ, rtol=0.03)
    # a rigid rotation of the body with its plate strains no gimbal spring
    u = _rigid_field(truss, theta=(1e-6, 2e-6, 3e-6))
    body = {truss.node(f"misr_g{c}") for c in range(6)}
    for s in truss.springs:
        if {int(d) // 3 for d in s.dofs} & body:
            assert abs(np.asarray(s.weights) @ u[np.asarray(s.dofs)]) < 1e-18


def test_misr_layout_puts_mount3_in_the_dominant_22_hz_path(red):
    # holding the payload accelerometer of iso3 at zero at 22 Hz removes most of the
    # SWIR cryocooler's MISR boresight (roll, pitch); iso1 alone removes little
    outs = ["los_misr_roll", "los_misr_pitch", "acc_pay_iso1", "acc_pay_iso3"]
    H = frf(red, [22.0], outs, ["swir_fz", "fc_iso1", "fc_iso3"])[0]
    b = H[:2, 0]

    def null(row, col):
        return np.linalg.norm(b - H[:2, col] * H[row, 0] / H[row, col]) / np.linalg.norm(b)

    assert null(3, 2) < 0.25          # mount #3: >= 75 % removable
    assert null(2, 1) > 0.8           # mount #1: < 20 %
    assert abs(b[1]) > 4 * abs(b[0])  # pitch dominates (first bus mode: x-z bending)


# -- reduction ---------------------------------------------------------------------------------
def test_reduced_defaults(red):
    assert red.n_modes == eos.N_MODES
    assert red.frequencies_hz[-1] >= 150.0            # covers up to 150 Hz
    assert red.accel_lowpass == eos.ACCEL_LOWPASS and eos.ACCEL_LOWPASS.cutoff_hz == 150.0
    assert red.n_ritz == 5 + 54
    assert np.all(red.modal_damping[:6] == 0.0)       # rigid modes undamped
    zeta = np.full(red.n_modes, eos.ZETA)
    zeta[eos.gimbal_modes(eos.build())] = eos.ZETA_GIMBAL
    np.testing.assert_allclose(red.modal_damping[6:], 2 * zeta[6:] * red.omega[6:])
    assert red.output_names[0] == "los_ceres_roll" and "rate_yaw" in red.output_names


FC = ["fc_iso1", "fc_iso2", "fc_iso3", "fc_swir_mount", "fc_vnir_mount"]


def _undamped(model):
    """Structure alone, as the full FEM: no damping, no accelerometer low-pass."""
    return replace(model.with_modal_damping(0.0), D_oo=np.zeros_like(model.D_oo),
                   accel_lowpass=None)


def test_ritz_vectors_make_actuator_response_statically_exact(truss, red):
    # an actuator pair is self-equilibrated, so the free-free static problem is defined;
    # 1e-3 of the first flexible mode is quasi-static for every elastic mode
    f = [1e-3 * 0.5]
    elong = [n.replace("fc_", "elong_") for n in FC]
    full = full_frf(truss, f, elong, FC)[0]
    ritz = frf(_undamped(red), f, elong, FC)[0]
    modal = frf(_undamped(eos.reduced(truss=truss, ritz=False)), f, elong, FC)[0]
    # own elongations, and the MISR isolators on each other (same mount)
    pairs = [(i, i) for i in range(5)] + [(i, j) for i in range(3) for j in range(3) if i != j]
    for i, j in pairs:
        assert ritz[i, j].real == pytest.approx(full[i, j].real, rel=1e-6)
        assert abs(modal[i, j] - full[i, j]) > 1e-3 * abs(full[i, j])
    for i in range(5):   # eigenvectors to 158 Hz miss most of the stack's own compliance
        assert abs(modal[i, i] - full[i, i]) > 0.5 * abs(full[i, i])


def test_load_ritz_vectors_fix_the_22_hz_swir_response(truss, red):
    # the testbed experiment: 22 Hz cryocooler-like excitation at the SWIR location
    outs = ["los_misr_roll", "los_misr_pitch", "los_swir_pitch", "los_swir_yaw",
            "acc_pay_iso1", "acc_bus_iso1", "strain_iso1", "elong_swir_mount"]
    ins = [f"swir_{c}" for c in eos.WRENCH]
    full = full_frf(truss, [22.0], outs, ins)[0]
    scale = np.abs(full).max(axis=1, keepdims=True)
    err_all = np.abs(frf(_undamped(red), [22.0], outs, ins)[0] - full) / scale
    act_only = eos.reduced(truss=truss, ritz_loads=())
    err_act = np.abs(frf(_undamped(act_only), [22.0], outs, ins)[0] - full) / scale
    assert err_all.max() < 1e-3
    assert err_act.max() > 1e-2


@pytest.mark.slow
def test_structure_fmu_builds_and_validates(tmp_path):
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu
    from fmutools.build import build_fmu
    from structfmu.fmuspec import specs

    (spec,) = specs(["eos_testbed_structure"])
    fmu = build_fmu(spec, tmp_path)
    assert validate_fmu(str(fmu)) == []
    md = read_model_description(str(fmu))
    ins = [v.name for v in md.modelVariables if v.causality == "input"]
    outs = {u.variable.name: u.dependencies for u in md.outputs}
    assert "swir_fx" in ins and "acs_tz" in ins and "fc_iso3" in ins and len(ins) == 62
    assert outs["los_misr_pitch"] == [] and outs["strain_iso1"] == []
    # accelerometers see the structure through their 150 Hz low-pass: no feedthrough
    assert outs["acc_pay_iso1"] == [] and outs["acc_bus_iso3"] == []
