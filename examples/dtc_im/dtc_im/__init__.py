"""Switching-table DTC of an induction motor: a torque controller of one's own for
predictive_drive's graph (see the README beside this package)."""
