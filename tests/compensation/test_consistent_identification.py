"""Physically consistent payload identification (pseudo-inertia ⪰ 0, mass > 0, prior)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from ftdrake.compensation.estimators.physics import (
    PARAMETER_NAMES,
    payload_regressor,
    weighted_least_squares,
)
from ftdrake.compensation.identification import consistent
from ftdrake.compensation.identification.consistent import (
    STATIC_PARAMETERS,
    IdentificationError,
    identify_consistent,
    is_physically_consistent,
    physical_violations,
    pseudo_inertia,
)

BIAS = np.array([0.6, -0.4, 1.2, 0.02, -0.01, 0.03])
SIGMA = np.array([1 / 40, 1 / 40, 1 / 20, 1 / 800, 1 / 800, 1 / 800])  # ati_gamma noise


def box_parameters(mass=1.2, dims=(0.08, 0.05, 0.12), com=(0.02, -0.01, 0.09),
                   rotvec=(0.3, -0.2, 0.5)):
    """φ of a solid box (side lengths `dims`, rotated by `rotvec`) centred at `com` from So:
    inertia about the centre m/12·(b² + c², ...), moved to So by the parallel-axis theorem."""
    a, b, c = dims
    R = Rotation.from_rotvec(rotvec).as_matrix()
    I_com = R @ np.diag(mass / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])) @ R.T
    com = np.asarray(com, float)
    I_So = I_com + mass * (com @ com * np.eye(3) - np.outer(com, com))
    return np.array([mass, *(mass * com), I_So[0, 0], I_So[0, 1], I_So[0, 2],
                     I_So[1, 1], I_So[1, 2], I_So[2, 2]])


BOX = box_parameters()
THETA = np.concatenate([BOX, BIAS])


def rich_regressor(rng, n):
    """Well-excited motion: rotations about every axis, gravity in every direction."""
    g = Rotation.random(n, random_state=rng).apply([0, 0, -9.81])
    return payload_regressor(rng.normal(size=(n, 3)) * 2, rng.normal(size=(n, 3)) * 10,
                             rng.normal(size=(n, 3)) * 2 - g)


def two_axis_regressor(rng, n):
    """Motion of two axes only (x and y): nothing excites Izz."""
    w = np.c_[rng.normal(size=(n, 2)) * 0.5, np.zeros(n)]
    alpha = np.c_[rng.normal(size=(n, 2)) * 3, np.zeros(n)]
    g = Rotation.from_rotvec(np.c_[rng.normal(size=(n, 2)) * 0.4, np.zeros(n)]).apply(
        [0, 0, -9.81])
    return payload_regressor(w, alpha, -g)


def one_axis_regressor(rng, n):
    """Rotation about z only, gravity tilted up to ~0.5 rad: Ixx, Ixy, Iyy not excited."""
    wz, az = rng.normal(size=n), rng.normal(size=n) * 5
    zeros = np.zeros(n)
    tilt = Rotation.from_rotvec(np.c_[rng.normal(size=(n, 2)) * 0.3,
                                      rng.uniform(-np.pi, np.pi, n)])
    return payload_regressor(np.c_[zeros, zeros, wz], np.c_[zeros, zeros, az],
                             -tilt.apply([0, 0, -9.81]))


def slow_regressor(rng, n):
    """Slow motion: small ω, α, a — the inertia's torques are near the noise."""
    g = Rotation.from_rotvec(rng.normal(size=(n, 3)) * 0.5).apply([0, 0, -9.81])
    return payload_regressor(rng.normal(size=(n, 3)) * 0.2, rng.normal(size=(n, 3)) * 0.5,
                             rng.normal(size=(n, 3)) * 0.2 - g)


def measure(A, theta, rng):
    return A @ theta + rng.normal(size=A.shape[:2]) * SIGMA


def held_out_rms(theta, seed=1000):
    """RMS prediction error on well-excited noise-free data, in units of the sensor noise."""
    A = rich_regressor(np.random.default_rng(seed), 400)
    return float(np.sqrt(np.mean(((A @ theta - A @ THETA) / SIGMA) ** 2)))


# -- pseudo-inertia ----------------------------------------------------------------------
def test_parameter_layout_matches_the_physics_model():
    assert list(consistent.PARAMETER_NAMES) == PARAMETER_NAMES


@settings(max_examples=40, deadline=None)
@given(points=arrays(np.float64, (5, 3), elements=st.floats(-0.3, 0.3)),
       masses=arrays(np.float64, (5,), elements=st.floats(0.01, 2.0)))
def test_pseudo_inertia_of_point_masses_is_its_definition(points, masses):
    # φ from the definitions (m = Σmᵢ, h = Σmᵢpᵢ, I = Σmᵢ(|pᵢ|²1 − pᵢpᵢᵀ)); J = Σmᵢ[pᵢ;1][pᵢ;1]ᵀ.
    I = sum(m * (p @ p * np.eye(3) - np.outer(p, p)) for m, p in zip(masses, points, strict=True))
    phi = np.array([masses.sum(), *(masses @ points), I[0, 0], I[0, 1], I[0, 2], I[1, 1],
                    I[1, 2], I[2, 2]])
    ph = np.c_[points, np.ones(5)]
    expected = sum(m * np.outer(p, p) for m, p in zip(masses, ph, strict=True))
    np.testing.assert_allclose(pseudo_inertia(phi), expected, atol=1e-12)
    np.testing.assert_allclose(consistent.from_pseudo_inertia(expected), phi, atol=1e-12)
    assert is_physically_consistent(phi)


def test_a_box_is_consistent_and_a_body_breaking_the_triangle_inequality_is_not():
    J = pseudo_inertia(BOX)
    assert np.linalg.eigvalsh(J).min() > 0
    assert is_physically_consistent(BOX) and physical_violations(BOX) == []

    # Principal moments (1, 1, 3)·1e-3 about the centre of mass: 1 + 1 < 3, no body has them;
    # each moment is positive and the inertia matrix positive definite, about So as well.
    com = np.array([0.0, 0.0, 0.1])
    I_So = np.diag([1e-3, 1e-3, 3e-3]) + 1.0 * (com @ com * np.eye(3) - np.outer(com, com))
    impossible = np.array([1.0, *com, I_So[0, 0], 0, 0, I_So[1, 1], 0, I_So[2, 2]])
    assert np.linalg.eigvalsh(I_So).min() > 0
    assert np.linalg.eigvalsh(pseudo_inertia(impossible)).min() < 0
    assert not is_physically_consistent(impossible)
    assert "triangle inequality" in physical_violations(impossible)[0]

    negative = BOX.copy()
    negative[0] = -0.1
    assert not is_physically_consistent(negative)
    assert "not positive" in physical_violations(negative)[0]


# -- identification ----------------------------------------------------------------------
def test_recovers_a_box_from_well_excited_data_like_least_squares():
    rng = np.random.default_rng(0)
    A = rich_regressor(rng, 400)
    Y = measure(A, THETA, rng)
    dut = identify_consistent(A, Y)

    assert dut.solver == "Clarabel" and dut.status == "kSolutionFound"
    assert dut.active_constraints == () and dut.poorly_determined == ()
    assert is_physically_consistent(dut.theta)
    z = (dut.theta - THETA) / dut.standard_errors
    assert np.all(np.abs(z) < 4.5), z
    assert dut.theta[0] == pytest.approx(1.2, rel=1e-3)
    # No constraint active: the same answer, errors and conditioning as least squares.
    theta, cov, rms, cond = weighted_least_squares(A, Y)
    np.testing.assert_allclose(dut.theta, theta, atol=1e-3 * dut.standard_errors.min())
    np.testing.assert_allclose(dut.standard_errors, np.sqrt(np.diag(cov)), rtol=1e-6)
    np.testing.assert_allclose(dut.residual_rms, rms, rtol=1e-6)
    assert dut.condition_number == pytest.approx(cond, rel=1e-6)
    assert np.all(dut.prior_share == 0)
    assert dut.solve_time < 1.0


def test_two_axis_motion_least_squares_is_impossible_the_constrained_fit_predicts_better():
    rng = np.random.default_rng(0)
    A = two_axis_regressor(rng, 40)
    Y = measure(A, THETA, rng)
    dut = identify_consistent(A, Y)

    assert not dut.least_squares_consistent
    assert not is_physically_consistent(dut.theta_least_squares)
    assert is_physically_consistent(dut.theta)
    assert "pseudo_inertia" in dut.active_constraints
    assert "Izz" in dut.poorly_determined
    assert dut.condition_number > 1e10
    rms_ls, rms_c = held_out_rms(dut.theta_least_squares), held_out_rms(dut.theta)
    assert rms_c < 0.6 * rms_ls, (rms_c, rms_ls)


def test_noisy_slow_motion_least_squares_goes_unphysical_the_constrained_fit_does_not():
    non_physical = []
    for seed in range(8):
        rng = np.random.default_rng(seed)
        A = slow_regressor(rng, 30)
        dut = identify_consistent(A, measure(A, THETA, rng))
        assert is_physically_consistent(dut.theta)
        rms_ls, rms_c = held_out_rms(dut.theta_least_squares), held_out_rms(dut.theta)
        assert rms_c <= rms_ls * 1.01, (seed, rms_c, rms_ls)
        if not is_physically_consistent(dut.theta_least_squares):
            non_physical.append((rms_ls, rms_c))
    assert non_physical, "expected least squares to give an impossible body on some seed"
    rms_ls, rms_c = np.mean(non_physical, axis=0)
    assert rms_c < 0.9 * rms_ls, non_physical


def test_prior_decides_what_the_data_do_not_excite_and_nothing_else():
    rng = np.random.default_rng(3)
    A = one_axis_regressor(rng, 200)
    Y = measure(A, THETA, rng)
    prior = box_parameters(mass=1.3, dims=(0.09, 0.05, 0.11), com=(0.025, -0.01, 0.085))
    dut = identify_consistent(A, Y, prior=prior)
    alone = identify_consistent(A, Y)

    share = dict(zip(PARAMETER_NAMES[:16], dut.prior_share, strict=True))
    for name in ("Ixx", "Ixy", "Iyy"):  # rotation about z only: not excited
        assert share[name] > 0.95, share
    for name in ("m", "mcx", "mcy", "mcz"):  # gravity in many directions: determined
        assert share[name] < 0.05, share
    assert all(share[name] == 0 for name in PARAMETER_NAMES[10:16])
    # The data alone cannot determine those; the prior does not change that verdict.
    assert set(alone.poorly_determined) == {"Ixx", "Ixy", "Iyy"}
    assert dut.poorly_determined == alone.poorly_determined
    # The well-excited mass follows the data (1.2 kg), not the prior (1.3 kg).
    assert dut.theta[0] == pytest.approx(1.2, abs=0.005)
    assert held_out_rms(dut.theta) < 0.5 * held_out_rms(alone.theta)


def test_prior_weight_sets_how_far_the_estimate_follows_the_prior():
    rng = np.random.default_rng(4)
    A = slow_regressor(rng, 30)
    Y = measure(A, THETA, rng)
    loose = identify_consistent(A, Y, prior=BOX, prior_weight=1e-2)
    tight = identify_consistent(A, Y, prior=BOX, prior_weight=1e6)
    assert np.all(tight.prior_share[4:10] > loose.prior_share[4:10])
    assert np.abs(tight.theta[4:10] - BOX[4:10]).max() < np.abs(
        loose.theta[4:10] - BOX[4:10]).max()


@pytest.mark.parametrize("prior, match", [
    (np.r_[-0.5, BOX[1:]], r"prior is not a physically possible body: mass -0\.5 kg"),
    (np.r_[1.0, 0, 0, 0.1, 1e-3 + 0.01, 0, 0, 1e-3 + 0.01, 0, 3e-3], "triangle inequality"),
    (BOX[:4], "10 inertial parameters"),
    (np.r_[np.nan, BOX[1:]], "NaN"),
])
def test_a_bad_prior_is_refused_by_name(prior, match):
    A = rich_regressor(np.random.default_rng(0), 20)
    with pytest.raises(ValueError, match=match):
        identify_consistent(A, A @ THETA, prior=prior)


def test_static_fit_keeps_the_mass_positive():
    hits = 0
    for seed in range(6, 12):
        rng = np.random.default_rng(seed)
        n = 50
        g = Rotation.from_rotvec(rng.normal(size=(n, 3)) * 0.3).apply([0, 0, -9.81])
        A = payload_regressor(np.zeros((n, 3)), np.zeros((n, 3)), -g)
        nothing = np.r_[np.zeros(10), BIAS]  # no payload on the sensor
        dut = identify_consistent(A, measure(A, nothing, rng), static=True, min_mass=1e-4)
        assert dut.theta[0] >= 1e-4
        assert np.all(dut.theta[4:10] == 0) and np.all(np.isnan(dut.standard_errors[4:10]))
        assert dut.parameters == STATIC_PARAMETERS
        if dut.theta_least_squares[0] < 0:
            hits += 1
            assert not dut.least_squares_consistent
            assert dut.active_constraints == ("min_mass",)
            assert dut.theta[0] == pytest.approx(1e-4, rel=1e-5)
    assert hits > 0


def test_dynamic_model_on_static_poses_names_the_inertia_as_undetermined():
    rng = np.random.default_rng(2)
    n = 60
    g = Rotation.random(n, random_state=rng).apply([0, 0, -9.81])
    A = payload_regressor(np.zeros((n, 3)), np.zeros((n, 3)), -g)  # ω = α = 0: I unseen
    dut = identify_consistent(A, measure(A, THETA, rng))
    assert dut.condition_number > 1e12
    assert set(PARAMETER_NAMES[4:10]) <= set(dut.poorly_determined)
    assert not {"m", "mcx", "mcy", "mcz"} & set(dut.poorly_determined)
    assert is_physically_consistent(dut.theta)
    assert "pseudo_inertia" in dut.active_constraints  # the smallest inertia that fits
    assert np.all(np.isinf(dut.standard_errors[4:10]))
    assert np.all(np.isfinite(dut.standard_errors[:4]))


def test_scs_agrees_with_clarabel():
    rng = np.random.default_rng(5)
    A = two_axis_regressor(rng, 60)
    Y = measure(A, THETA, rng)
    clarabel = identify_consistent(A, Y, solver="clarabel")
    scs = identify_consistent(A, Y, solver="scs")
    assert scs.solver == "SCS"
    np.testing.assert_allclose(scs.theta[:4], clarabel.theta[:4], rtol=1e-3)
    assert held_out_rms(scs.theta) == pytest.approx(held_out_rms(clarabel.theta), rel=0.05)


def test_solver_failure_raises_a_clear_error():
    A = rich_regressor(np.random.default_rng(0), 50)
    with pytest.raises(IdentificationError, match=r"did not solve.*kIterationLimit"):
        identify_consistent(A, A @ THETA, solver_options={"max_iter": 1})


def test_bad_input_is_refused():
    A = rich_regressor(np.random.default_rng(0), 20)
    Y = A @ THETA
    with pytest.raises(ValueError, match="min_mass"):
        identify_consistent(A, Y, min_mass=0.0)
    with pytest.raises(ValueError, match="weights"):
        identify_consistent(A, Y, weights=[1, 1, 1, 1, 1, -1])
    with pytest.raises(ValueError, match="Y must have shape"):
        identify_consistent(A, Y[:, :3])
    Y[3, 2] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        identify_consistent(A, Y)
