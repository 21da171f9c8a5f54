"""Fixtures shared by several test files."""
import pytest

from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel


@pytest.fixture(scope="module")
def xfyz():
    """(machine, base ErrorModel) of the built-in 3-axis machine."""
    m = load_machine("xfyz")
    return m, ErrorModel(m)


@pytest.fixture(scope="module")
def cafxyz():
    """(machine, base ErrorModel) of the built-in CAFXYZ double-turntable machine."""
    m = load_machine("cafxyz")
    return m, ErrorModel(m)
