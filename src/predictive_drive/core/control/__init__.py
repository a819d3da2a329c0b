"""Controller families: the registry every engine, node and report builds controllers from.

A family is one module here: its controller class (a :class:`~.base.Controller`) with its settings
dataclass and strategies. It plugs in by one entry in :data:`CONTROLLERS`; a scenario names its
family in the torque controller's section (``family: mptc_pmsm``), and the family's
``params_type`` reads the rest of that section.

============  ==========  ===================================================================
family        machine     strategies
============  ==========  ===================================================================
mptc_im       induction   mptc, mptc_db, db_mptc (paper 000)
mptc_pmsm     pmsm        mptc, simplified1, simplified2, simplified3 (paper 001)
foc_pmsm      pmsm        foc_zero_d, foc_formula, foc_injection (paper 002: FOC with MTPA)
foc_im        induction   ifoc (indirect rotor-field orientation: the PWM baseline of paper 000's
                          machine)
mpc_pmsm      pmsm        direct_mpc (direct model predictive current control, sphere decoding
                          over N periods)
============  ==========  ===================================================================
"""

from __future__ import annotations

from enum import StrEnum
from typing import Any

from ..devices import Device
from ..signals import EXTERNAL
from .base import Controller, Decision, Strategy, VectorController, instantiate
from .foc_im import FOCIMController, FOCIMParams
from .foc_pmsm import FOCController, FOCParams
from .mpc_pmsm import MPCController, MPCParams
from .mptc_im import InductionController, InductionControllerParams
from .mptc_pmsm import PMSMController, PMSMControllerParams

__all__ = [
    "CONTROLLERS",
    "Controller",
    "Decision",
    "EXTERNAL",
    "FOCController",
    "FOCIMController",
    "FOCIMParams",
    "FOCParams",
    "Family",
    "InductionController",
    "InductionControllerParams",
    "MPCController",
    "MPCParams",
    "PMSMController",
    "PMSMControllerParams",
    "Strategy",
    "VectorController",
    "controller_class",
    "make_controller",
    "make_strategy",
    "strategy_names",
]


class Family(StrEnum):
    """The controller families this package ships."""

    MPTC_IM = "mptc_im"
    MPTC_PMSM = "mptc_pmsm"
    FOC_PMSM = "foc_pmsm"
    FOC_IM = "foc_im"
    MPC_PMSM = "mpc_pmsm"


#: family name → controller class: the one registry (keys are :class:`Family` members; a
#: family of one's own plugs in with its name)
CONTROLLERS: dict[str, type[Controller]] = {
    Family.MPTC_IM: InductionController,
    Family.MPTC_PMSM: PMSMController,
    Family.FOC_PMSM: FOCController,
    Family.FOC_IM: FOCIMController,
    Family.MPC_PMSM: MPCController,
}


def controller_class(family: str) -> type[Controller]:
    """The controller class of a family; ValueError lists the registered families."""
    try:
        return CONTROLLERS[family]
    except KeyError:
        raise ValueError(
            f"unknown controller family {family!r}; valid: {', '.join(CONTROLLERS)}"
        ) from None


def strategy_names(family: str) -> tuple[str, ...]:
    """The family's strategies in registry order (the ``strategy`` index of its commands)."""
    return tuple(controller_class(family).strategies)


def make_strategy(family: str, name: str) -> Any:
    """Instantiate strategy ``name`` of ``family``; ValueError lists the valid names."""
    return instantiate(family, controller_class(family).strategies, name)


def make_controller(
    family: str, params: Any, *, ts: float, device: Device | None = None
) -> Controller:
    """The controller of a scenario's torque_controller section (every engine and node alike);
    ``device``: the device file its ``device`` names, read (the loss-aware cost's energies)."""
    cls = controller_class(family)
    if device is None:
        return cls(params, ts=ts)
    return cls(params, ts=ts, device=device)  # type: ignore[call-arg]
