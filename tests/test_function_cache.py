"""One cache of CasADi functions (mtcomp.models.function_cache): every function built from an error
model is built once per model structure and shared by the models of that structure, whichever module
asks for it; a model of another structure gets its own; the structures used last are kept."""
import numpy as np
import pytest

from mtcomp.export._tables import _rotation_function
from mtcomp.machine import load_machine
from mtcomp.measurement.readings import chain_function
from mtcomp.measurement.readings_extra import normal_deviation_function, velocity_function
from mtcomp.models import ErrorModel, PeriodicError, function_cache
from mtcomp.models.evaluate import casadi_map_call

SITES = {
    "pose": lambda m: m.pose_function,
    "nominal": lambda m: m.nominal_function,
    "deviation": lambda m: m.deviation_function,
    "deviation_jac": lambda m: m.deviation_jacobian_function,
    "deviation_qjac": lambda m: m.deviation_qjacobian_function,
    "tip_pjac": lambda m: m.tip_pjacobian_function,
    "measurement tip": lambda m: chain_function(m, "tip"),
    "measurement laser_jac": lambda m: chain_function(m, "laser_jac"),
    "cmm normal": normal_deviation_function,
    "grid velocity": lambda m: velocity_function(m, "X"),
    "export rotation": _rotation_function,
}


@pytest.fixture(autouse=True)
def fresh_cache():
    function_cache.forget()
    yield
    function_cache.forget()


@pytest.mark.parametrize("site", list(SITES))
def test_models_of_one_structure_share_their_functions(site):
    get = SITES[site]
    a = ErrorModel(load_machine("xfyz"))
    b = ErrorModel(load_machine("xfyz"))               # another object, the same structure
    other = ErrorModel(load_machine("xfyz"), [PeriodicError("X", 25.0)])
    assert a.structure_key() == b.structure_key() != other.structure_key()
    assert get(a) is get(b)
    assert get(other) is not get(a)
    if get(a).n_in() > 1:                               # the parameter vector is each model's own
        assert get(other).size_in(1) == (other.n_params, 1)
        assert get(a).size_in(1) == (a.n_params, 1)


def test_a_shared_function_gives_each_model_its_own_numbers():
    """The shared function is the one each model would build: checked against a model built after
    the cache was emptied."""
    m = load_machine("cafxyz").with_basis("polynomial")
    a, b = ErrorModel(m), ErrorModel(m)
    rng = np.random.default_rng(3)
    q = rng.uniform(*m.travel_bounds(), (6, m.n_axes))
    p = rng.normal(size=a.n_params) * 1e-3
    c = a.default_context(6)
    shared = casadi_map_call(b.deviation_function, q, p, c)[0]
    assert a.deviation_function is b.deviation_function
    function_cache.forget()
    own = casadi_map_call(ErrorModel(m).deviation_function, q, p, c)[0]
    np.testing.assert_array_equal(shared, own)
    assert np.abs(own).max() > 1e-6                     # not a trivial zero


def test_the_structures_used_last_are_kept():
    models = [ErrorModel(load_machine("xfyz"), [PeriodicError("X", 10.0 + k)])
              for k in range(function_cache.KEPT + 1)]
    built = [function_cache.model_function(m, "probe", object) for m in models[:-1]]
    # the first structure was used last: it stays when one more arrives, the second goes
    assert function_cache.model_function(models[0], "probe", object) is built[0]
    function_cache.model_function(models[-1], "probe", object)
    assert function_cache.model_function(models[0], "probe", object) is built[0]
    assert function_cache.model_function(models[1], "probe", object) is not built[1]
