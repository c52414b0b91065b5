"""Figures. Computing lives elsewhere; these functions only draw what they are given."""

from quadest.plot.errors import plot_errors
from quadest.plot.flight import plot_flight
from quadest.plot.recording import plot_recording
from quadest.plot.recovery import plot_recovery, plot_recovery_histograms

__all__ = ["plot_errors", "plot_flight", "plot_recording", "plot_recovery", "plot_recovery_histograms"]
