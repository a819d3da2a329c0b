"""Machine models, one module per machine type, and the registry of machine types.

A scenario's ``machine`` names the plant's motor model (its parameter class here); the controller
family it runs names its own (see :mod:`predictive_drive.core.control`).
"""

from __future__ import annotations

from collections.abc import Mapping
from enum import StrEnum

from .induction import InductionMotor
from .magnetics import PMSMSaturation
from .pmsm import PMSM
from .saturated import IMSaturation

__all__ = ["MOTORS", "SATURATIONS", "Machine", "motor_class", "saturation_class"]


class Machine(StrEnum):
    INDUCTION = "induction"
    PMSM = "pmsm"


#: machine type → motor parameter class
MOTORS: Mapping[Machine, type] = {Machine.INDUCTION: InductionMotor, Machine.PMSM: PMSM}
#: machine type → its saturation settings (the plant's ``saturation`` group; model none: linear)
SATURATIONS: Mapping[Machine, type] = {
    Machine.INDUCTION: IMSaturation,
    Machine.PMSM: PMSMSaturation,
}


def motor_class(machine: str) -> type:
    """The motor parameter class of a machine type; ValueError lists the valid ones."""
    try:
        return MOTORS[Machine(machine)]
    except ValueError:
        raise ValueError(
            f"unknown machine {machine!r}; valid: {', '.join(m.value for m in Machine)}"
        ) from None


def saturation_class(machine: str) -> type:
    """The saturation settings class of a machine type (see :func:`motor_class`)."""
    motor_class(machine)  # ValueError for an unknown machine
    return SATURATIONS[Machine(machine)]
