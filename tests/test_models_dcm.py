"""The differential change construction (seed 001): first-order term of the exact chain, quadratic
remainder, Jacobian against finite differences and CasADi, the pseudo-inverse step, and eq. 26."""
import casadi as ca
import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.kinematics import forward, tool2wp
from mtcomp.models import Backlash, ErrorModel, deviation, deviation_and_jacobians
from mtcomp.models.chain import polynomial_orders
from oracles.dcm import (dcm_deviation, differential_change_matrix, machine_jacobian,
                               pinv_correction, tool_in_axis_frames)
from oracles.poe import adjoint, exp_twist
from test_models_chain import machine_size_params, random_context, random_poses

MACHINES = ["xfyz", "cafxyz", "cbfxyz"]


def _setup(name, seed, n):
    m = load_machine(name)
    model = ErrorModel(m)
    rng = np.random.default_rng(seed)
    return m, model, random_poses(m, rng, n), machine_size_params(model, rng), random_context(model, rng, n)


@pytest.mark.parametrize("name", MACHINES)
def test_dcm_is_the_first_order_term_of_the_exact_chain(name):
    m, model, q, p, c = _setup(name, 7, 30)
    _, _, Jp0 = deviation_and_jacobians(model, q, np.zeros(model.n_params), c)
    first_order = np.einsum("nij,j->ni", Jp0, p)
    dcm = dcm_deviation(model, p, q, c)
    np.testing.assert_allclose(dcm, first_order, rtol=0, atol=1e-12 * np.abs(first_order).max())
    # exact minus first order is second order: halving p quarters it
    r1 = np.abs(deviation(model, q, p, c) - dcm).max()
    r2 = np.abs(deviation(model, q, p / 2, c) - dcm_deviation(model, p / 2, q, c)).max()
    assert 1e-3 * np.abs(dcm).max() > r1 > 1e-8  # a real, small remainder
    np.testing.assert_allclose(r1 / r2, 4.0, rtol=2e-2, atol=0)


def test_differential_change_matrix_is_eq4_and_the_inverse_adjoint():
    """Eq. 4 entry by entry, and C(T) = Ad(T^-1); eq. 12 for XFYZ (tool in the X frame at
    (-x_seed, y, z), the seed's table displacement x_seed being minus our x)."""
    rng = np.random.default_rng(2)
    T = exp_twist(rng.normal(size=(5, 6)), rng.uniform(-2, 2, 5))
    C = differential_change_matrix(T)
    np.testing.assert_allclose(C, adjoint(np.linalg.inv(T)), rtol=0, atol=1e-13)
    n, o, a, pp = T[0, :3, 0], T[0, :3, 1], T[0, :3, 2], T[0, :3, 3]
    eq4 = np.zeros((6, 6))
    eq4[0, :3], eq4[1, :3], eq4[2, :3] = n, o, a
    eq4[0, 3:], eq4[1, 3:], eq4[2, 3:] = np.cross(pp, n), np.cross(pp, o), np.cross(pp, a)
    eq4[3, 3:], eq4[4, 3:], eq4[5, 3:] = n, o, a
    np.testing.assert_allclose(C[0], eq4, rtol=0, atol=1e-13)
    x, y, z = 120.0, -40.0, 35.0  # our coordinates
    m = load_machine("xfyz")
    frames = tool_in_axis_frames(ErrorModel(m), [[x, y, z]])
    xs = -x
    eq12 = np.eye(6)
    eq12[0, 4], eq12[0, 5] = z, -y
    eq12[1, 3], eq12[1, 5] = -z, -xs
    eq12[2, 3], eq12[2, 4] = y, xs
    np.testing.assert_allclose(differential_change_matrix(frames["X"][0]), eq12, rtol=0, atol=1e-13)


@pytest.mark.parametrize("name", MACHINES)
def test_machine_jacobian_is_the_derivative_of_the_nominal_pose(name):
    m, model, q, _, _ = _setup(name, 9, 12)
    J = machine_jacobian(model, q)
    R = tool2wp(m, q)[:, :3, :3]
    # tool-frame differential motion -> workpiece-frame derivative of tip and tool axis
    dtip = np.einsum("nij,njk->nik", R, J[:, :3, :])
    daxis = np.einsum("nij,njk->nik", R, np.cross(J[:, 3:, :], [0.0, 0.0, 1.0], axisa=1, axisc=1))
    # oracle 1: CasADi's exact Jacobian of the nominal chain
    qs = ca.SX.sym("q", m.n_axes)
    tip, axis = model.nominal_function(qs)
    jac = ca.Function("nominal_jacobian", [qs], [ca.jacobian(ca.vertcat(tip, axis), qs)])
    ref = np.array([np.array(jac(q[i])) for i in range(len(q))])
    np.testing.assert_allclose(dtip, ref[:, :3, :], rtol=0, atol=1e-11)
    np.testing.assert_allclose(daxis, ref[:, 3:, :], rtol=0, atol=1e-13)
    # oracle 2: central differences of the numpy kinematics
    for j in range(m.n_axes):
        h = 1e-3 if not m.axes[j].is_rotary else 1e-5
        qp, qm = q.copy(), q.copy()
        qp[:, j] += h
        qm[:, j] -= h
        (tp, ap), (tm, am) = forward(m, qp), forward(m, qm)
        # truncation h^2/6 |d3 tip| <~ 1e-10 * 500 mm; rounding 1e-16 * 500 mm / h
        np.testing.assert_allclose(dtip[:, :, j], (tp - tm) / (2 * h), rtol=0, atol=1e-7)
        np.testing.assert_allclose(daxis[:, :, j], (ap - am) / (2 * h), rtol=0, atol=1e-9)


@pytest.mark.parametrize("name", MACHINES)
def test_pinv_step_removes_the_first_order_error(name):
    """One eq. 29/30 step leaves a residual of second order: halving the errors quarters it."""
    m, model, q, p, c = _setup(name, 13, 25)
    # away from the singular pose (tilt axis at 0: the C turn cannot tilt the tool)
    regular = np.abs(q[:, 3]) > 1e-3 if m.is_five_axis else np.ones(len(q), bool)
    assert regular.sum() > 15
    tip0, axis0 = forward(m, q)

    def residual(scale):
        q1 = q - pinv_correction(model, scale * p, q, c)
        t, a = forward(m, q1)
        d = deviation(model, q1, scale * p, c)
        return t + d[:, :3] - tip0, a + d[:, 3:] - axis0

    dev = deviation(model, q, p, c)
    r_tip, r_axis = residual(1.0)
    assert np.abs(r_tip).max() < 2e-3 * np.abs(dev[:, :3]).max()
    if m.is_five_axis:  # orientation is solved jointly with position
        assert np.abs(r_axis[regular]).max() < 2e-3 * np.abs(dev[:, 3:]).max()
    else:  # three linear axes cannot tilt the tool: the axis error stays (up to its change along dq)
        np.testing.assert_allclose(r_axis, dev[:, 3:], rtol=0, atol=1e-3 * np.abs(dev[:, 3:]).max())
    h_tip, h_axis = residual(0.5)
    ratio = np.abs(r_tip[regular]).max() / np.abs(h_tip[regular]).max()
    np.testing.assert_allclose(ratio, 4.0, rtol=0.1, atol=0)
    if m.is_five_axis:
        ratio = np.abs(r_axis[regular]).max() / np.abs(h_axis[regular]).max()
        np.testing.assert_allclose(ratio, 4.0, rtol=0.1, atol=0)


def test_pinv_correction_with_extension_terms_uses_the_exact_chain():
    m = load_machine("xfyz")
    model = ErrorModel(m, [Backlash("X")])
    p = np.zeros(model.n_params)
    p[model.param_names.index("BL_X")] = 8e-3
    q = np.array([[100.0, 20.0, -30.0], [100.0, 20.0, -30.0]])
    c = model.default_context(2)
    c[:, model.context_names.index("dir_X")] = [1.0, -1.0]
    dq = pinv_correction(model, p, q, c)
    np.testing.assert_allclose(dq, [[4e-3, 0, 0], [-4e-3, 0, 0]], rtol=0, atol=1e-12)
    with pytest.raises(NotImplementedError):
        pinv_correction(model, p, q, c, errors="dcm")


# ------------------------------------------------------------------------------- seed 001, eq. 26
#: the 21 errors of seed 001 in its notation
SEED_TERMS = ["dxx", "dyx", "dzx", "exx", "eyx", "ezx", "dxy", "dyy", "dzy", "exy", "eyy", "ezy",
              "dxz", "dyz", "dzz", "exz", "eyz", "ezz", "Sxy", "Syz", "Szx"]


def eq26_printed(xs, y, z, e):
    """Seed 001 eq. 26 as printed (xs: the seed's X, the table displacement)."""
    return np.array([
        y * e["Sxy"] - e["dxx"] + e["dxy"] + e["dxz"] - z * e["eyx"] + z * e["eyy"] + y * e["ezx"],
        xs * e["Sxy"] - e["dyx"] + e["dyy"] + e["dyz"] + z * e["exx"] - z * e["exy"] + xs * e["ezx"],
        -e["dzx"] + e["dzy"] + e["dzz"] - y * e["exx"] - xs * e["eyx"]])


def eq26_corrected(xs, y, z, e, L=0.0, L0=None):
    """Eq. 26 re-derived by hand: squareness S_xy tilts Y's travel (no xs*S_xy term), S_zx and S_yz
    tilt Z's travel (terms eq. 26 lacks), and a tool of length L on a machine whose reference tool
    (tip at q = 0 with every axis at zero) has length L0 (default L: the seed's tool, L = L0 = 0):

    * Y's angular errors turn the Y carriage about a point fixed on it, the gauge point at q = 0 with
      the reference tool: arm z - L0 from it to the tip, whatever the tool;
    * tool length compensation puts the ram at its machine position zr = z + L - L0 for the tip at z:
      Z's errors (the d_.z, e_.z given here) are its values there and its squareness tilts the travel
      by zr; its angular errors turn it about the gauge point, L above the tip.
    """
    L0 = L if L0 is None else L0
    zr = z + L - L0
    return np.array([
        y * e["Sxy"] - e["dxx"] + e["dxy"] + e["dxz"] - z * e["eyx"] + (z - L0) * e["eyy"]
        - L * e["eyz"] + y * e["ezx"] + zr * e["Szx"],
        -e["dyx"] + e["dyy"] + e["dyz"] + z * e["exx"] - (z - L0) * e["exy"] + L * e["exz"]
        + xs * e["ezx"] - zr * e["Syz"],
        -e["dzx"] + e["dzy"] + e["dzz"] - y * e["exx"] - xs * e["eyx"]])


def seed_to_iso(x, e):
    """Component error values (ISO 230-1 names, our conventions) for seed errors e at our x.

    Seed table errors are the table carriage's own errors in its displacement xs = -x, turning it
    about the workpiece origin; ours are errors of the tool relative to the table, turning about the
    machine origin: EXX = -dxx, EAX = -exx, ..., and the straightness of X carries the arm x:
    dyx = -EYX + x ECX, dzx = -EZX - x EBX. Tool-side axes map one to one. Squareness:
    C0Y = -Sxy, A0Z = Syz, B0Z = Szx.
    """
    iso = {"EXX": -e["dxx"], "EYX": -e["dyx"] - x * e["ezx"], "EZX": -e["dzx"] + x * e["eyx"],
           "EAX": -e["exx"], "EBX": -e["eyx"], "ECX": -e["ezx"],
           "C0Y": -e["Sxy"], "A0Z": e["Syz"], "B0Z": e["Szx"]}
    for ax in "yz":
        for i, d in enumerate("XYZ"):
            iso[f"E{d}{ax.upper()}"] = e[f"d{d.lower()}{ax}"]
            iso[f"E{'ABC'[i]}{ax.upper()}"] = e[f"e{d.lower()}{ax}"]
    return iso


def _first_order_ours(model, q, iso, L):
    """Our first-order deviation (exact chain's J_p at p = 0) for component values at the pose."""
    p = np.zeros(model.n_params)
    for name, value in iso.items():
        if name in ("C0Y", "A0Z", "B0Z"):
            p[model.param_names.index(name)] = value
        else:  # E?A(s) = E?A_k * (s / 1 m)^k: the value at this pose, with the lowest power the
            # base model has (EXY_1, EXZ_1, EYZ_1 are carried by the squareness)
            s = q["XYZ".index(name[2])]
            if name[2] == "Z":   # the values are those at the ram's machine position
                s = s + L - model.machine.tool_length
            k = polynomial_orders(model.machine, name[2], name)[0]
            p[model.param_names.index(f"{name}_{k}")] = value / (s / 1000.0) ** k
    c = model.default_context(1)
    c[0, model.context_names.index("tool_length")] = L
    _, _, Jp0 = deviation_and_jacobians(model, q[None, :], np.zeros(model.n_params), c)
    return (Jp0[0] @ p)[:3], dcm_deviation(model, p, q[None, :], c)[0, :3]


@pytest.mark.parametrize("L", [0.0, 100.0, 250.0])
def test_eq26_corrected_matches_our_model(L):
    m = load_machine("xfyz").with_basis("polynomial")  # the eq. 26 check sets values through the powers
    model = ErrorModel(m)
    rng = np.random.default_rng(26)
    for _ in range(5):
        q = rng.uniform([-400, -300, -250], [400, 300, 150])
        e = dict(zip(SEED_TERMS, rng.normal(size=21) * np.where(
            np.array([t[0] == "d" for t in SEED_TERMS]), 5e-3, 30e-6)))
        ours, dcm = _first_order_ours(model, q, seed_to_iso(q[0], e), L)
        seed = eq26_corrected(-q[0], q[1], q[2], e, L, model.machine.tool_length)
        np.testing.assert_allclose(ours, seed, rtol=0, atol=1e-12 * np.abs(seed).max())
        np.testing.assert_allclose(dcm, seed, rtol=0, atol=1e-12 * np.abs(seed).max())


@pytest.mark.parametrize("L", [0.0, 100.0])
def test_eq26_printed_discrepancies(L):
    """Term by term (one seed error at a time), the printed eq. 26 differs from the derivation
    exactly in these places (docs/models.md)."""
    xs, y, z = -150.0, 80.0, -60.0
    differ = set()
    for t in SEED_TERMS:
        e = {k: float(k == t) for k in SEED_TERMS}
        a, b = eq26_printed(xs, y, z, e), eq26_corrected(xs, y, z, e, L)
        for row in range(3):
            if not np.isclose(a[row], b[row], rtol=0, atol=1e-12):
                differ.add(("xyz"[row], t))
    expected = {("y", "Sxy"),  # printed xs*Sxy: squareness as a yaw of the table = a rigid rotation
                ("x", "Szx"), ("y", "Syz")}  # squareness of Z missing (C_Z^t = I, no tool length)
    if L:
        expected |= {("x", "eyy"), ("x", "eyz"), ("y", "exy"), ("y", "exz")}  # arms to the gauge point
    assert differ == expected
