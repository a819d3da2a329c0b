"""A loss-aware switching cost for the finite-control-set laws
(docs/physics.md#a-loss-aware-switching-cost): each candidate's cost gains λ_e × the switching
energy its commutations take, predicted from the device's datasheet energies (the controller's
own device file, :mod:`..devices`) at the phase current each commutation carries.

Where :class:`~.base.SwitchingEffort` counts a candidate's leg commutations, this prices them:
a commutation at 20 A costs more than one at 2 A, and one the current makes itself (a diode
taking over) costs only the turn-off of the transistor that carried it. The families add it to
the same candidates the effort is added to: from the switching state in force at the period's
start (the zero vector realised as the plant realises it, 000 or 111 whichever is nearer), and,
where a strategy applies a vector for part of the period, its return to the zero vector at the
current predicted for that instant.
"""

from __future__ import annotations

import math
from typing import Any

from ...errors import ConfigError
from ..devices import Commutations, Device, commutations
from ..fields import choice, quantity
from ..inverter import VECTOR_STATES, inverse_clarke, zero_state_for

__all__ = [
    "LEG_CHANGES",
    "RETURNS",
    "SwitchingEnergy",
    "check_energy",
    "device_field",
    "device_tj_field",
    "lambda_e_field",
    "switching_energy",
]


def _changes(a: tuple[int, int, int], b: tuple[int, int, int]) -> tuple[tuple[int, bool], ...]:
    """The legs that change level from switching state ``a`` to ``b``: (leg, rising)."""
    return tuple((x, b[x] > a[x]) for x in range(3) if a[x] != b[x])


def _state(code: int) -> tuple[int, int, int]:
    return (code >> 2) & 1, (code >> 1) & 1, code & 1


#: ``LEG_CHANGES[code][n]``: the legs vector n for the whole period changes from the switching
#: state of code ``code`` (S_a·4 + S_b·2 + S_c), V0 as the zero vector nearer to that state
LEG_CHANGES: tuple[tuple[tuple[tuple[int, bool], ...], ...], ...] = tuple(
    tuple(
        _changes(_state(c), zero_state_for(_state(c)) if n == 0 else VECTOR_STATES[n])
        for n in range(7)
    )
    for c in range(8)
)
#: ``RETURNS[n]``: the one leg active vector n changes as it returns to its nearer zero vector
#: (n = 0: none)
RETURNS: tuple[tuple[tuple[int, bool], ...], ...] = tuple(
    () if n == 0 else _changes(VECTOR_STATES[n], zero_state_for(VECTOR_STATES[n])) for n in range(7)
)


def lambda_e_field(unit: str) -> Any:
    """The ``lambda_e`` field of a finite-control-set family: its cost per joule of predicted
    switching energy, in the unit of the family's cost."""
    return quantity(
        "loss-aware switching weight: cost per joule of the switching energy a candidate's "
        "commutations take, predicted from torque_controller.device at the commutated current "
        "(0: none, the law without it)",
        unit,
        ge=0,
        default=0.0,
    )


def device_field() -> Any:
    """The ``device`` field: the device file the controller's switching energies come from."""
    return choice(
        "the inverter's devices as the controller knows them, for lambda_e: a file in "
        "config/devices (its name) or a path ('': none)",
        default="",
    )


def device_tj_field() -> Any:
    """The ``device_tj`` field: the junction temperature the controller takes the energies at
    (it measures none)."""
    return quantity(
        "junction temperature the controller takes the device's switching energies at",
        "°C",
        ge=-40,
        le=200,
        default=125.0,
    )


class SwitchingEnergy:
    """λ_e × the predicted switching energy of each candidate (see the module's docstring),
    for ``device`` at ``t_j`` °C, scaled to the measured DC link (:meth:`dc_link`)."""

    __slots__ = ("weight", "device", "t_j", "at")

    def __init__(self, weight: float, device: Device, t_j: float) -> None:
        self.weight = weight
        self.device = device
        self.t_j = t_j
        self.at: Commutations = commutations(device, t_j=t_j, u_dc=device.v_abs_max)

    def dc_link(self, u_dc: float) -> None:
        """The measured DC-link voltage (V): the energies scale to it."""
        if math.isfinite(u_dc) and u_dc > 0.0:
            self.at = commutations(self.device, t_j=self.t_j, u_dc=u_dc)

    def legs(self, i: complex) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Per leg a, b, c, λ_e × the energy of its rising and of its falling edge while the
        current ``i`` (A, αβ) flows (each phase's current out of its leg)."""
        at, w = self.at, self.weight
        rise, fall = [], []
        for x in inverse_clarke(i):
            take, leave = w * at.taking(x), w * at.leaving(x)
            rise.append(take if x > 0.0 else leave)
            fall.append(take if x < 0.0 else leave)
        return tuple(rise), tuple(fall)

    def full(self, code: int, i: complex) -> tuple[float, ...]:
        """λ_e × the energy of each vector V0..V6 applied from the switching state of ``code``,
        its commutations carrying the current ``i`` (A, αβ)."""
        rise, fall = self.legs(i)
        return tuple(
            sum(rise[x] if up else fall[x] for x, up in changes) for changes in LEG_CHANGES[code]
        )

    def back(self, n: int, i: complex) -> float:
        """λ_e × the energy of active vector ``n``'s return to its nearer zero vector at the
        current ``i`` (A, αβ)."""
        ((x, up),) = RETURNS[n]
        return self.weight * self.at.energy(inverse_clarke(i)[x], rising=up)


def check_energy(params: Any) -> None:
    """ConfigError for a family's settings that ask for the loss-aware cost without a device
    file, or with the compiled search (its horizons search in Python)."""
    if params.lambda_e <= 0:
        return
    if not params.device:
        raise ConfigError(
            f"torque_controller.lambda_e {params.lambda_e:g}: the loss-aware cost takes the "
            f"switching energies of a device: name its file in torque_controller.device (a "
            f"name in config/devices, or a path)"
        )
    if params.search == "compiled":
        raise ConfigError(
            "torque_controller.search compiled: with lambda_e > 0 a horizon's branch and bound "
            "runs in Python (the compiled one prices no energy); search auto or python"
        )


def switching_energy(params: Any, device: Device | None) -> SwitchingEnergy | None:
    """The loss-aware cost of a family's settings (None: λ_e = 0), from ``device``, the file
    ``torque_controller.device`` names as read by whoever builds the controller."""
    if params.lambda_e <= 0:
        return None
    if device is None:
        raise ConfigError(
            f"torque_controller.device {params.device!r}: its device file was not read (the "
            f"scenario loader reads it and hands it to make_controller)"
        )
    return SwitchingEnergy(params.lambda_e, device, params.device_tj)
