"""What each instrument reads: measurement files and the model of every reading.

* :mod:`.files`: the readers of the measurement files (points, laser, ballbar, cmm, thermal,
  velocity), the unit of every column and the conversion to internal units (mm, rad);
* :mod:`.readings` (points, laser, ballbar) and :mod:`.readings_extra` (cmm, thermal, velocity): the
  measurement models, which turn an error model's parameters and a file's set-up (nuisance)
  parameters into the readings of that file, with exact CasADi Jacobians; each kind registers its
  model in :data:`.readings.MEASUREMENT_MODELS` (both modules are imported here, so every kind is
  registered whatever is imported first);
* :mod:`.drift`: the drift features a file's time, temperature and spindle columns give;
  :mod:`.cut`: where a program cut the points of a CMM file.

identify, diagnose, predict and the simulator all go through these; nothing else models a reading.
"""
from .files import MeasurementSet, read_measurements
from .readings import MeasurementModel, measurement_model, model_class_for
from . import readings_extra  # noqa: F401  (registers the cmm, thermal and velocity models)

__all__ = ["MeasurementSet", "read_measurements", "MeasurementModel", "measurement_model",
           "model_class_for"]
