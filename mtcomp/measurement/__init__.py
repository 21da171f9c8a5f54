"""What each instrument reads: measurement files and the model of every reading.

* :mod:`.files`: the readers of the measurement files (points, laser, ballbar, cmm, thermal,
  velocity), the unit of every column and the conversion to internal units (mm, rad);
* :mod:`.readings` and :mod:`.readings_extra`: the measurement models, which turn an error model's
  parameters and a file's set-up (nuisance) parameters into the readings of that file, with exact
  CasADi Jacobians.

identify, diagnose, predict and the simulator all go through these; nothing else models a reading.
"""
from .files import MeasurementSet, read_measurements
from .readings import MeasurementModel, measurement_model, model_class_for

__all__ = ["MeasurementSet", "read_measurements", "MeasurementModel", "measurement_model",
           "model_class_for"]
