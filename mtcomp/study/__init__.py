"""Correction studies: many compensations (programs x models x methods x bounds x temperatures x
draws of a model from its covariance), run on Dask, cached, summarised in a table and plots.

    from mtcomp.study import load_study, run_study, write_tables
    study = load_study("STUDY.toml")
    run = run_study(study, "RESULTS/")          # a LocalCluster on this machine
    write_tables(run.rows, "RESULTS/")

docs/study.md describes STUDY.toml and the results.
"""
from .plots import pareto_front, plot_summary, write_html
from .runner import StudyRun, check_study, run_study, write_tables
from .spec import Study, Task, load_study
from .task import COLUMNS, draw_model, run_task

__all__ = ["COLUMNS", "Study", "StudyRun", "Task", "check_study", "draw_model", "load_study",
           "pareto_front", "plot_summary", "run_study", "run_task", "write_html", "write_tables"]
