"""Oracles of the tests: second formulations of what mtcomp computes (the product of exponentials,
the differential change construction, the planner's nonlinear problem in CasADi Opti) and test
helpers (image comparison). Test code: not part of the mtcomp package."""
