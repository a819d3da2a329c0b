"""The per-step signal records exchanged by the components and the ROS topics: the one owner of
their layouts (state, reference and command every step; the plant's losses beside the state where
they are on).

Field order here *is* the wire order: :mod:`predictive_drive.interface` serialises these tuples as
labelled ``std_msgs/Float64MultiArray`` with exactly these labels. Add a field here and it is added
everywhere (topics, recordings, reports). Code that holds a record as a plain row of numbers reads
it by name through the index records :data:`STATE_INDEX`, :data:`REFERENCE_INDEX`,
:data:`COMMAND_INDEX` and :data:`LOSSES_INDEX` (``row[STATE_INDEX.torque]``), never by a bare
position.
"""

from __future__ import annotations

import math
import re
from typing import Any, NamedTuple

from ..errors import ConfigError

__all__ = [
    "span_key",
    "span_name",
    "span_parts",
    "strategy_name",
    "COMMAND_DIAGNOSTICS",
    "COMMAND_INDEX",
    "DEVICES",
    "EXTERNAL",
    "EXTERNAL_PREFIX",
    "LOSSES_INDEX",
    "LOSS_FIELDS",
    "PULSES",
    "REFERENCE_INDEX",
    "STATE_INDEX",
    "Command",
    "Losses",
    "PhasePulses",
    "Reference",
    "State",
    "external_name",
    "new_record",
]

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
    i_alpha_true: float  #: stator current α, A (truth; i_alpha is it as measured)
    i_beta_true: float  #: stator current β, A (truth)
    omega_m_true: float  #: mechanical speed, rad/s (truth)
    theta_e_true: float  #: rotor electrical angle, rad, [0, 2π) (truth)
    # means over the period that ended at k, between the samples (truth; at k = 0 the values at
    # 0): what the continuous-time figures are computed from (docs/physics.md#metrics)
    torque_avg: float  #: mean electromagnetic torque, N·m
    torque_sq_avg: float  #: mean of its square, (N·m)²
    flux_avg: float  #: mean stator-flux magnitude |ψ_s|, Wb
    flux_sq_avg: float  #: mean of its square, Wb²
    i_alpha_avg: float  #: mean stator current α, A
    i_beta_avg: float  #: mean stator current β, A
    current_sq_avg: float  #: mean of |i_s|² = i_α² + i_β², A²
    #: mean stator current in the rotor's frame (turned back by θ_e), d and q, A: where a
    #: synchronous machine's fundamental stands still (an induction motor's turns at the slip)
    i_d_avg: float
    i_q_avg: float


class Losses(NamedTuple):
    """The plant's losses and temperatures at sample k (docs/physics.md#losses-and-temperature),
    published beside the state only where the plant's losses are on (``plant.losses``): power
    means over the period that ended at k (W; at k = 0 zero), temperatures at k (°C; NaN for a
    node the run has not: the devices' without a device file, the machine's without its
    losses)."""

    k: float  #: step index
    t: float  #: simulated time, s
    p_dc: float  #: DC-link power u_dc·i_dc of the plant's equations (switching, iron not in it)
    p_shaft: float  #: power into the load (T_L·ω_m; T_e·ω_m where a load machine holds ω_m)
    p_copper: float  #: stator (and rotor) copper losses, R(T)·i²
    p_iron: float  #: iron losses (from the flux's frequency and magnitude; not in the equations)
    p_friction: float  #: viscous friction b·ω_m²
    p_cond_t: float  #: conduction losses of the six transistors
    p_cond_d: float  #: conduction losses of the six diodes
    p_sw_t: float  #: switching losses of the six transistors (E_on + E_off)
    p_sw_d: float  #: switching losses of the six diodes (E_rr)
    # each device's losses (conduction + switching): t transistor, d diode, a..c the leg, hi/lo
    # the upper (to +DC) or lower position
    p_ta_hi: float
    p_da_hi: float
    p_ta_lo: float
    p_da_lo: float
    p_tb_hi: float
    p_db_hi: float
    p_tb_lo: float
    p_db_lo: float
    p_tc_hi: float
    p_dc_hi: float
    p_tc_lo: float
    p_dc_lo: float
    # each device's junction temperature (a body diode's is its transistor's die)
    tj_ta_hi: float
    tj_da_hi: float
    tj_ta_lo: float
    tj_da_lo: float
    tj_tb_hi: float
    tj_db_hi: float
    tj_tb_lo: float
    tj_db_lo: float
    tj_tc_hi: float
    tj_dc_hi: float
    tj_tc_lo: float
    tj_dc_lo: float
    t_sink: float  #: heatsink temperature
    t_winding: float  #: stator winding temperature (the plant's R_s follows it)
    t_rotor: float  #: rotor temperature (an IM's R_r, a PMSM's ψ_f follow it)


class Reference(NamedTuple):
    """Speed-loop output in force at step k (computed from state k-1: a one-sample delay)."""

    k: float
    t: float
    torque_ref: float  #: T*, N·m
    flux_ref: float  #: ψ*, Wb
    speed_ref: float  #: ω_m*, rad/s


class PhasePulses(NamedTuple):
    """One period's switching command: phase x is high on [delay_x, delay_x + duty_x), fractions
    of Ts (docs/physics.md#the-inverter-and-the-command). The command format shared by every control law."""

    delay_a: float
    delay_b: float
    delay_c: float
    duty_a: float
    duty_b: float
    duty_c: float


#: how the strategy of a run whose torque controller is a node of the user's own
#: (docs/ros.md#writing-your-own-controller) begins: ``external:NAME`` (its commands carry no
#: strategy index: NaN); NAME is the run's label, by default the node's name
EXTERNAL_PREFIX = "external:"
EXTERNAL = EXTERNAL_PREFIX + "torque_controller"
_LABEL = re.compile(r"[A-Za-z0-9_.+-]+")
#: the longest label: a bag's folder name (scenario, label, date, PID) must stay well under the
#: 255 bytes a file name may have
LABEL_MAX = 64


def external_name(label: str) -> str:
    """``external:LABEL``, the strategy name of a controller of one's own; ConfigError for a
    label a bag folder, a table or a file name could not hold (a ':' breaks zip, SMB and
    Windows)."""
    if not _LABEL.fullmatch(label):
        raise ConfigError(
            f"--label {label!r}: a controller's name is letters, digits and _ . + - (it names "
            f"the controller in bags, their folder names, tables and figures)"
        )
    if len(label) > LABEL_MAX:
        raise ConfigError(
            f"--label {label[:20]}... ({len(label)} characters): a controller's name is at most "
            f"{LABEL_MAX} characters (it is part of the bag's folder name)"
        )
    return EXTERNAL_PREFIX + label


def strategy_name(names: tuple[str, ...], index: float, external: str = EXTERNAL) -> str:
    """The strategy of a command's ``strategy`` index in its family's ``names``; a command
    without one (NaN) came from a torque controller of the user's own, named ``external``."""
    if math.isnan(index):
        return external
    return names[int(index)] if 0 <= index < len(names) else "?"


#: span keys: a strategy index and its horizon in one number (horizons are below this)
_SPAN_BASE = 64.0


def span_key(strategy: Any, horizon: Any) -> Any:
    """What a strategy span is one of, as one number (or an array of them, from columns): the
    strategy index and the law's horizon (NaN: none, counted as 1). A span of ``mptc`` at N = 3
    is another span than ``mptc`` at N = 1; NaN for a controller of the user's own."""
    if isinstance(horizon, float):
        return strategy * _SPAN_BASE + (1.0 if math.isnan(horizon) else horizon)
    import numpy as np

    return strategy * _SPAN_BASE + np.where(np.isnan(horizon), 1.0, horizon)


def span_parts(key: float) -> tuple[float, float]:
    """(strategy index, horizon) of a :func:`span_key` (NaN, NaN for the user's own)."""
    if math.isnan(key):
        return math.nan, math.nan
    index, horizon = divmod(key, _SPAN_BASE)
    return index, horizon


def span_name(names: tuple[str, ...], key: float, external: str = EXTERNAL) -> str:
    """The strategy (with its horizon when longer than one period) of a :func:`span_key`; a
    controller of the user's own (NaN) is named ``external``."""
    if math.isnan(key):
        return external
    index, horizon = span_parts(key)
    name = strategy_name(names, index)
    return name if horizon == 1.0 else f"{name} N={int(horizon)}"


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
    strategy: float  #: index of the strategy in its controller family's registry order
    vector: float  #: chosen voltage vector 0..6 (0 = zero vector, 000 or 111); NaN: not FCS
    duty: float  #: fraction of Ts the chosen vector is applied (1 for plain FCS); NaN: not FCS
    t_u: float  #: raw deadbeat time before clamping, s (NaN where no deadbeat time is computed)
    cal: float  #: number of vector predictions evaluated this step (tree nodes, long horizons)
    horizon: float  #: prediction horizon N of the law, periods (NaN: a law without one)
    torque_est: float  #: controller's torque estimate at k, N·m
    flux_est: float  #: controller's stator-flux magnitude estimate at k, Wb
    flux_angle: float  #: angle of the controller's stator-flux estimate in αβ at k, rad, [0, 2π)
    current_angle: float  #: FOC: current angle θ from the q axis, dither included, rad (else NaN)
    i_d_ref: float  #: FOC: d-current reference, A (else NaN)
    i_q_ref: float  #: FOC: q-current reference, A (else NaN)
    #: foc_injection: the demodulated, low-passed d(T/I)/dθ divided by k_t = 1.5·p·ψ_f (the
    #: torque per ampere at θ = 0), 1/rad (else NaN)
    mtpa_gradient: float
    #: long horizons: 1 if the search ran out of its node budget and the best sequence found so
    #: far was applied, 0 if it finished (the optimum); NaN: no search this step
    suboptimal: float
    compute_ns: float  #: wall time of the control law alone, ns (not deterministic)


#: index of each field in a row of the record: ``row[STATE_INDEX.torque]`` (a record of the field
#: positions; typed Any because its values are ints where the record's are floats)
STATE_INDEX: Any = State(*range(len(State._fields)))
LOSSES_INDEX: Any = Losses(*range(len(Losses._fields)))
REFERENCE_INDEX: Any = Reference(*range(len(Reference._fields)))
COMMAND_INDEX: Any = Command(*range(len(Command._fields)))
#: the devices of the inverter, in the order the state lists their losses and temperatures
DEVICES: tuple[str, ...] = tuple(
    name[2:] for name in Losses._fields if name.startswith("p_") and name.endswith(("_hi", "_lo"))
)
#: the losses' fields after the step and the time, from ``p_dc`` on
LOSS_FIELDS: tuple[str, ...] = Losses._fields[LOSSES_INDEX.p_dc :]
#: the command's pulses, a :class:`PhasePulses`: ``row[PULSES]``
PULSES: slice = slice(COMMAND_INDEX.delay_a, COMMAND_INDEX.duty_c + 1)
#: the fields a controller reports about its decision, between ``strategy`` and ``compute_ns``
COMMAND_DIAGNOSTICS: tuple[str, ...] = Command._fields[
    COMMAND_INDEX.strategy + 1 : COMMAND_INDEX.compute_ns
]
