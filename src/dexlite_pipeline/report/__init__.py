"""The HTML report: tables, plots and rendered grasps of an evaluation (the numbers come from ``evaluation``)."""
