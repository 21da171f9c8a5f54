"""Simulated measurements: the one place that produces readings from an error model with known parameters.

A :class:`VirtualMachine` holds a *truth* (a :class:`~mtcomp.models.FittedModel`: base model plus any
extension terms -- backlash, periodic error, thermal drift, feed-dependent terms, rotary error
motions) and produces measurement files of every kind of docs/measurements.md from a :class:`Plan`.
The readings are produced by the SAME measurement models that identification fits
(:mod:`mtcomp.measurement.readings`, looked up in the registry by kind), plus Gaussian
noise (:func:`simulated_columns`); the files are written in the documented format (column names and
units exactly as docs/measurements.md) and read back with
:func:`mtcomp.measurement.files.read_measurements`, so what a caller gets is what the readers give for
the file.

Plans (each a function returning a :class:`Plan`; times ``t_s`` advance with moves at feed and dwells):

* :func:`iso230_2_plan`: laser positioning runs (ISO 230-2 cycle, 5 runs, bidirectional), optionally
  straightness and angular components.
* :func:`rotary_laser_plan`: the same for a rotary axis (Pi et al. (2017)).
* :func:`volumetric_points_plan`: deviations on a 3-D grid with several tool lengths (and rotary angles).
* :func:`ballbar_circles_plan`: ISO 230-4 circles in XY, YZ, ZX, CCW and CW.
* :func:`three_sphere_plan`: Tan et al. (2026) (bar along X, Y, Z from a table ball on the C axis, two
  heights, only C moving, both directions).
* :func:`thermal_plan`: a fixed set-up under a spindle-speed profile, with temperatures.
* :func:`velocity_plan`: the two-point velocities of Yang et al. (2020) (X axis, 200 mm, 5 mm steps,
  3 repeats, 180/240/300 mm/min).
* :func:`cmm_plan`: a machined part (G-code + ball-end tool) measured at given surface points.
* :func:`standard_campaign`: the plans that determine the base model of a machine.
* :func:`campaign_plans`: a realistic campaign for `diagnose` (laser runs at several feeds and Abbe
  arms, a fine scan, a points grid repeated for drift checks; rotary runs on five axes), the demo's.
* :func:`merge_plans`: one plan made of several run one after another.

Sets built in memory, without a file (tests, benchmarks): :func:`make_points`, :func:`make_laser`,
:func:`make_ballbar` from arrays, :func:`random_campaign` (random poses, laser set-ups and circles),
:func:`simulate` fills their readings from a model and parameter values, :func:`with_values` puts
given readings in, :func:`write_measurements` writes one as CSV.

:func:`random_truth` draws realistic base parameters (um-scale polynomials, tens of urad squareness);
:func:`random_parameters` draws parameter values of one flat size (or given standard deviations).
Units: files as docs/measurements.md (mm, deg, um, urad, mm/min, s); everything else mm and rad.
"""
from ._machine import VirtualMachine, noise_sd, simulate, simulated_columns
from ._plans import (CAMPAIGN_ARMS, CAMPAIGN_FEEDS, Plan, ballbar_circles_plan, campaign_plans, cmm_plan,
                     iso230_2_plan, merge_plans, rotary_laser_plan, standard_campaign, thermal_plan,
                     three_sphere_plan, velocity_plan, volumetric_points_plan)
from ._sets import (make_ballbar, make_laser, make_points, random_campaign, with_values, write_columns,
                    write_measurements)
from ._truth import random_parameters, random_truth

__all__ = ["CAMPAIGN_ARMS", "CAMPAIGN_FEEDS", "campaign_plans", "merge_plans", "Plan", "VirtualMachine", "ballbar_circles_plan", "cmm_plan", "iso230_2_plan", "make_ballbar",
           "make_laser", "make_points", "noise_sd", "random_campaign", "random_parameters", "random_truth",
           "rotary_laser_plan", "simulate", "simulated_columns", "standard_campaign", "thermal_plan",
           "three_sphere_plan", "velocity_plan", "volumetric_points_plan", "with_values", "write_columns",
           "write_measurements"]
