"""The testbed isolation design on the linear model: per-mount gains, the law's bus path as
feedforward and the bounds, each checked against an independent computation."""

import numpy as np
import pytest

from orchestrator.experiments import testbed_isolation as tb

pytestmark = pytest.mark.paper   # the paper's experiments' designs: make test-full


@pytest.fixture(scope="module")
def plant(suite_fmu_dir):
    return tb.linear_plant(tb.linear_model(suite_fmu_dir))


def test_per_mount_gains_frequency_domain_equals_the_closed_loop(plant):
    # the frequency-domain closed loop (closed_frf, used for the reductions) against the
    # state-space feedback interconnection of python-control, with three different gains
    g = (0.3, -0.2, 1.0)
    f = list(tb.HARMONICS)
    Gh = tb.plant_frf(plant, f)
    fd = tb.closed_frf(Gh, tb.law_frf(f, g), (1, 2, 3))
    ss = tb.plant_frf(tb.closed_loop(plant, (1, 2, 3), g), f)[:, :, 3]
    np.testing.assert_allclose(fd, ss, rtol=1e-8, atol=1e-12 * np.abs(ss).max())
    # a number is the same factor at every mount; the per-mount factors matter
    assert tb.per_mount(0.5) == (0.5, 0.5, 0.5)
    same = tb.closed_frf(Gh, tb.law_frf(f, 1.0), (1, 2, 3))
    assert np.abs(same - fd).max() > 1e-3 * np.abs(fd).max()


def test_per_mount_refuses_two_factors():
    with pytest.raises(ValueError, match="one per mount"):
        tb.per_mount((1.0, 2.0))


def test_all_mounts_design_keeps_6db_and_beats_mount3_alone(plant):
    # every loop closed (no zero factor), 6 dB with the three scaled together, and at
    # least what mount #3 alone removes (the design could always pick that direction)
    g = tb.NOMINAL_GAINS["all_mounts"]
    assert all(x != 0.0 for x in g)
    # every loop: the three scaled together and each alone with the others closed
    margins = tb.loop_margins_db(plant, (1, 2, 3), g)
    assert set(margins) == {"all", "iso1", "iso2", "iso3"}
    assert min(margins.values()) >= 6.0
    assert (tb.boresight_reduction(plant, (1, 2, 3), g)
            >= tb.boresight_reduction(plant, (3,), tb.NOMINAL_GAINS["mount3"]))


def test_feedforward_best_gain_is_the_best_real_gain(plant):
    # brute force over the gain of the bus path applied to the open-loop bus acceleration
    f = np.array(list(tb.HARMONICS))
    a = np.array(list(tb.HARMONICS.values()))
    Gh = tb.plant_frf(plant, f)
    c = np.array([tb.law_frf(x, law=tb.to_statespace(
        tb.design("testbed_isolation", payload_gain=0.0, bus_gain=1.0)))[0, 2, 1] for x in f])
    ref = np.sqrt(np.sum(a[:, None] ** 2 * np.abs(Gh[:, 6:8, 3]) ** 2))

    def red(k):
        y = Gh[:, 6:8, 3] + k * Gh[:, 6:8, 2] * (c * Gh[:, 5, 3])[:, None]
        return 100 * (1 - np.sqrt(np.sum(a[:, None] ** 2 * np.abs(y) ** 2)) / ref)

    ks = np.concatenate([-np.geomspace(1e-2, 1e5, 3000), np.geomspace(1e-2, 1e5, 3000)])
    brute = max(red(k) for k in ks)
    bound = tb.feedforward_best_gain(plant, 3, Gh)
    assert brute <= bound + 1e-9
    assert brute == pytest.approx(bound, abs=0.05)
    # the stiff strut's bus path cannot give the paper's 80 % even without its loop
    assert bound < 70.0


def test_a_loop_alone_has_the_single_loop_margin(plant):
    # with the other two loops closed at zero gain, scaling mount #3 alone is the
    # single-loop problem gain_margin_db solves for mounts (3,)
    m = tb.loop_margins_db(plant, (1, 2, 3), (0.0, 0.0, 1.0))
    assert m["iso3"] == pytest.approx(tb.gain_margin_db(plant, (3,), 1.0), abs=0.05)
    assert m["all"] == pytest.approx(m["iso3"], abs=0.05)


@pytest.fixture(scope="module")
def hybrid_plant(suite_fmu_dir):
    return tb.linear_plant(tb.linear_model(suite_fmu_dir, "hybrid"))


def test_the_upper_bound_holds_and_the_accelerometer_null_is_not_one(hybrid_plant):
    # A stable law with margin removes more than holding the payload accelerometer at
    # zero, so that number must not be called a ceiling; the least-squares upper bound
    # still holds for it, and for random strut commands at each line.  The law: the
    # design law in the hybrid plant's own best direction (docs/eos_experiments.md:
    # design_gains, 72 directions).
    def law_at(k):
        return tb.to_statespace(tb.design("testbed_isolation", payload_gain=-89.5 * k,
                                          bus_gain=333.9 * k))

    # the gains as the docs print them (to 0.1) keep 6 dB only to the search's
    # resolution; scaled down by what they lack, the law keeps the full 6 dB
    m = tb.gain_margin_db(hybrid_plant, (3,), law=law_at(1.0), max_factor=1e6)
    law = law_at(min(1.0, 10 ** ((m - 6.01) / 20)))
    assert tb.gain_margin_db(hybrid_plant, (3,), law=law, max_factor=1e6) >= 6.0
    red = tb.boresight_reduction(hybrid_plant, (3,), law=law)
    b = tb.strut_bounds(hybrid_plant, (3,))
    assert red > b["accel_null"] + 5.0
    assert red <= b["upper_bound"]
    # independent: random strut commands at each harmonic never beat the bound
    f = list(tb.HARMONICS)
    a = np.array(list(tb.HARMONICS.values()))
    Gh = tb.plant_frf(hybrid_plant, f)
    d, u = Gh[:, 6:8, 3], Gh[:, 6:8, 2]
    ref = np.sqrt(np.sum(a[:, None] ** 2 * np.abs(d) ** 2))
    rng = np.random.default_rng(3)
    best = -np.inf
    for _ in range(2000):
        w = rng.normal(size=len(f)) + 1j * rng.normal(size=len(f))
        w *= np.abs(d).max(axis=1) / np.abs(u).max(axis=1) * rng.uniform(0, 3)
        y = d + u * w[:, None]
        best = max(best, 100 * (1 - np.sqrt(np.sum(a[:, None] ** 2 * np.abs(y) ** 2)) / ref))
    assert best <= b["upper_bound"] + 1e-9
