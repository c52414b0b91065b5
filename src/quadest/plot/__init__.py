"""Figures. Computing lives elsewhere; these functions only draw what they are given."""
from quadest.plot.recording import plot_recording

__all__ = ["plot_recording"]
