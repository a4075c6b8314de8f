"""Experiments: one script per figure, table or ablation (``make figures``).

Figures go to files only: matplotlib's Agg backend, set before any script imports pyplot.
"""
import matplotlib

matplotlib.use("Agg")
