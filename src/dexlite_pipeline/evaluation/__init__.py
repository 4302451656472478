"""Evaluation: each method's grasps chosen on the evaluated objects, simulated (lift and
six-direction tests, energies), and measured (success rates with intervals, diversity,
convergence, the learning ladder, the budget curve). The report (``report``) only presents it.
Importing the package is light: the workflow reads ``step_keys`` while it parses the rules."""
