"""The product-of-exponentials formulation (seed 003) against the CasADi HTM chain, scipy's matrix
exponential and hand cases."""
import dataclasses
import math

import numpy as np
import pytest
from scipy.linalg import expm

from mtcomp import load_machine
from mtcomp.models import ErrorModel, deviation
from oracles.poe import (adjoint, exp_twist, hat, poe_deviation, poe_tool_pose,
                               rotation_twist)
from test_models_chain import machine_size_params, random_context, random_poses

MACHINES = ["xfyz", "cafxyz", "cbfxyz"]


def test_exp_twist_matches_matrix_exponential():
    rng = np.random.default_rng(0)
    xi = rng.normal(size=(40, 6))
    xi[:10, 3:] = 0.0  # pure translations
    theta = rng.uniform(-4.0, 4.0, 40)
    T = exp_twist(xi, theta)
    ref = np.array([expm(hat(xi[i]) * theta[i]) for i in range(40)])
    np.testing.assert_allclose(T, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_adjoint_moves_twists():
    rng = np.random.default_rng(1)
    g = exp_twist(rng.normal(size=(10, 6)), rng.uniform(-2, 2, 10))
    xi = rng.normal(size=(10, 6))
    lhs = hat(np.einsum("nij,nj->ni", adjoint(g), xi))
    rhs = g @ hat(xi) @ np.linalg.inv(g)
    np.testing.assert_allclose(lhs, rhs, rtol=0, atol=1e-12)


def test_rotation_twist_hand_case():
    """C turning 90 deg about the line x = 10, y = 0 takes the origin to (10, -10, 0)."""
    T = exp_twist(rotation_twist([0, 0, 1.0], [10.0, 0, 0]), np.array([math.pi / 2]))[0]
    np.testing.assert_allclose(T[:3, 3], [10.0, -10.0, 0.0], rtol=0, atol=1e-14)
    np.testing.assert_allclose(T[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], rtol=0, atol=1e-15)


@pytest.mark.parametrize("name", MACHINES)
def test_poe_matches_htm_chain(name):
    m = load_machine(name)
    model = ErrorModel(m)
    rng = np.random.default_rng(21)
    n = 40
    q = random_poses(m, rng, n)  # rotary angles 0, +-90 and 180 deg among them
    p = machine_size_params(model, rng)
    c = random_context(model, rng, n)
    tip, axis = poe_tool_pose(model, p, q, c)
    ref = [model.pose_function(q[i], p, c[i]) for i in range(n)]
    ref_tip = np.array([np.array(r[0]).ravel() for r in ref])
    ref_axis = np.array([np.array(r[1]).ravel() for r in ref])
    scale = np.abs(ref_tip).max()
    np.testing.assert_allclose(tip, ref_tip, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(axis, ref_axis, rtol=0, atol=1e-12)
    # deviations: both sides subtract two ~scale mm positions, so the floor is 1e-12 of the pose
    dev = poe_deviation(model, p, q, c)
    ref_dev = deviation(model, q, p, c)
    assert np.abs(ref_dev[:, :3]).max() > 1e-3  # errors of machine size act
    np.testing.assert_allclose(dev, ref_dev, rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("name", MACHINES)
def test_poe_single_parameters_match_chain(name):
    """Each parameter alone (larger than machine size, to make wrong signs or arms obvious)."""
    m = load_machine(name)
    model = ErrorModel(m)
    rng = np.random.default_rng(4)
    q = random_poses(m, rng, 6)
    c = random_context(model, rng, 6)
    idle = []
    for k, spec in enumerate(model.param_specs):
        p = np.zeros(model.n_params)
        p[k] = {"um": 0.05, "urad": 1e-3}[spec.unit]
        ref = deviation(model, q, p, c, backend="casadi")
        if np.abs(ref).max() == 0.0:
            idle.append(spec.name)
        np.testing.assert_allclose(poe_deviation(model, p, q, c), ref, rtol=0, atol=1e-12 * 1000,
                                   err_msg=spec.name)
    # only the yaws of Y and Z turn the tool about its own axis line (the tip lies on it)
    assert idle == [n for n in model.param_names if n.startswith(("ECY_", "ECZ_"))]


def test_eq9_order_contradicts_fixed_frame_error_motions():
    """Seed 003 eq. 9 multiplies ideal . error; with the radial error motion EXC (fixed frame, as
    eqs. 7, 10-14 identify it) that order turns the error with the table. Only eq. 4's order matches
    the chain, and at 90 deg eq. 9's order puts a 10 um EXC on the part's X instead of its Y."""
    m = load_machine("cafxyz")
    axes = tuple(dataclasses.replace(a, error_motion_order=2) if a.name == "C" else a for a in m.axes)
    m = dataclasses.replace(m, axes=axes)
    model = ErrorModel(m)
    q2 = np.zeros((1, 5))
    q2[0, 4] = math.pi / 2
    p2 = np.zeros(model.n_params)
    p2[model.param_names.index("EXC_c2")] = -10e-3  # EXC(90 deg) = 10 um
    c = model.default_context(1)
    ref = deviation(model, q2, p2, c, backend="casadi")[0]
    left = poe_deviation(model, p2, q2, c)[0]
    np.testing.assert_allclose(left, ref, rtol=0, atol=1e-12)
    # the table moves +10 um along the fixed X; the part is turned by 90 deg, so in part coordinates
    # the tool moves by Rz(-90 deg) (-10 um, 0, 0) = (0, +10 um, 0)
    np.testing.assert_allclose(ref[:3], [0, 10e-3, 0], rtol=0, atol=1e-12)
    # eq. 9's order applies the error in the turned table frame: as if the table had not turned
    tip_r, _ = poe_tool_pose(model, p2, q2, c, error_side="right")
    tip0, _ = poe_tool_pose(model, p2, q2, c, errors=False)
    np.testing.assert_allclose(tip_r[0] - tip0[0], [-10e-3, 0, 0], rtol=0, atol=1e-12)
