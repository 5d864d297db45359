"""Figures, one module per stage (texture, mesh, solver, calibration, regression, diagnosis).

Every figure function takes data (arrays, DataFrames) and a path, writes a PNG (and nothing else), and
uses :func:`skidsim.plotting.style.figure` so that all figures share one readable style: units on axes,
consistent fonts and colours.
"""
