"""Machine models, one module per machine type, and the registry of machine types.

A scenario's ``machine`` names the plant's motor model (its parameter class here); the controller
family it runs names its own (see :mod:`predictive_drive.core.control`).
"""

from __future__ import annotations

from collections.abc import Mapping
from enum import StrEnum

from .induction import InductionMotor
from .pmsm import PMSM

__all__ = ["MOTORS", "Machine", "motor_class"]


class Machine(StrEnum):
    INDUCTION = "induction"
    PMSM = "pmsm"


#: machine type → motor parameter class
MOTORS: Mapping[Machine, type] = {Machine.INDUCTION: InductionMotor, Machine.PMSM: PMSM}


def motor_class(machine: str) -> type:
    """The motor parameter class of a machine type; ValueError lists the valid ones."""
    try:
        return MOTORS[Machine(machine)]
    except ValueError:
        raise ValueError(
            f"unknown machine {machine!r}; valid: {', '.join(m.value for m in Machine)}"
        ) from None
