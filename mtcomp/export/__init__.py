"""Compensation tables in the controllers' own formats (`mtcomp export`, docs/export.md).

Public names:

* :data:`FORMATS`: format name -> exporter module (``linuxcnc``, ``siemens``, ``heidenhain``,
  ``fanuc``, ``isg``, ``klipper``); each has ``export(tables, **options) -> ExportResult``,
  ``MAX_POINTS`` (grid points per table), ``INCLUDE_END`` (whether the last grid point may sit off
  the equidistant grid) and ``SINGLE_FILE``.
* :func:`component_tables`, :func:`table_region`, :func:`plan_grids`, :func:`parse_ranges`
  (_tables.py): the model's component errors evaluated on each axis's grid.
* :class:`ExportResult`, :func:`write_result` (_output.py).
* :func:`reversal_note` (_reversal.py): the one line saying that the model's data show a reversal
  the model does not hold (export prints it; compensate can print the same).
"""
from importlib import import_module

from ._output import ExportResult, write_result
from ._reversal import reversal_note
from ._tables import (AxisTable, ComponentTables, component_names, component_tables, parse_ranges,
                      plan_grids, table_region)

FORMAT_NAMES = ("linuxcnc", "siemens", "heidenhain", "fanuc", "isg", "klipper")


def exporter(name: str):
    """The exporter module of format ``name``."""
    if name not in FORMAT_NAMES:
        raise KeyError(name)
    return import_module(f"{__name__}.{name}")


__all__ = ["FORMAT_NAMES", "exporter", "ExportResult", "write_result", "AxisTable", "ComponentTables",
           "component_names", "component_tables", "parse_ranges", "plan_grids", "table_region", "reversal_note"]
