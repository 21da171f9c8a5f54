"""mtcomp: geometric error models, identification and bounded compensation for CNC machine tools.

Importing mtcomp is cheap: heavy and optional parts (pyvista, cvxpy) are imported where used.
"""
from .errors import InputError
from .machine import Axis, Machine, load_machine

__version__ = "0.1.0"
__all__ = ["InputError", "Axis", "Machine", "load_machine", "__version__"]
