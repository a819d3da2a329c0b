"""The three per-step signal records exchanged by the components (and, later, the ROS topics).

Field order here *is* the wire order: :mod:`predictive_drive.interface` serialises these tuples as
labelled ``std_msgs/Float64MultiArray`` with exactly these labels. Add a field here and it is added
everywhere (topics, recordings, reports).
"""

from __future__ import annotations

from typing import NamedTuple

__all__ = ["Command", "Reference", "State", "new_record"]

#: ``new_record(State, (k, t, ...))``: a record from the tuple of all its fields, in order, without
#: the generated keyword-argument constructor (half the cost; for the per-step hot paths, whose
#: field counts the tests hold to the record types)
new_record = tuple.__new__


class State(NamedTuple):
    """Plant output at sample instant k (measured channels, then ground truth for metrics only)."""

    k: float  #: step index
    t: float  #: simulated time, s
    i_alpha: float  #: stator current α, A (measured)
    i_beta: float  #: stator current β, A (measured)
    omega_m: float  #: mechanical speed, rad/s (measured)
    theta_e: float  #: rotor electrical angle, rad, wrapped to [0, 2π) (measured)
    u_dc: float  #: DC-link voltage, V (measured)
    torque: float  #: electromagnetic torque, N·m (truth)
    psi_alpha: float  #: stator flux α, Wb (truth)
    psi_beta: float  #: stator flux β, Wb (truth)
    theta_m: float  #: shaft angle, rad, unwrapped (truth)
    load_torque: float  #: load torque applied during the coming period, N·m (truth)
    transitions: float  #: device on/off transitions during the period that ended at k (truth)


class Reference(NamedTuple):
    """Speed-loop output in force at step k (computed from state k-1: a one-sample delay)."""

    k: float
    t: float
    torque_ref: float  #: T*, N·m
    flux_ref: float  #: ψ*, Wb
    speed_ref: float  #: ω_m*, rad/s


class Command(NamedTuple):
    """Controller output for period k: per-phase pulses plus the decision's diagnostics."""

    k: float
    t: float
    delay_a: float  #: phase a rises at delay_a·Ts
    delay_b: float
    delay_c: float
    duty_a: float  #: phase a is high for duty_a·Ts
    duty_b: float
    duty_c: float
    strategy: float  #: index of the strategy in the machine's registry order
    vector: float  #: chosen voltage vector 0..6 (0 = zero vector, realised as 000 or 111)
    duty: float  #: fraction of Ts the chosen vector is applied (1 for plain FCS)
    t_u: float  #: raw deadbeat time before clamping, s (NaN where no deadbeat time is computed)
    cal: float  #: number of vector predictions evaluated this step
    torque_est: float  #: controller's torque estimate at k, N·m
    flux_est: float  #: controller's stator-flux magnitude estimate at k, Wb
    flux_angle: float  #: angle of the controller's stator-flux estimate in αβ at k, rad, [0, 2π)
    compute_ns: float  #: wall time of the control law alone, ns (not deterministic)
