"""Evaluation metrics, plots, rendering and the HTML report."""
