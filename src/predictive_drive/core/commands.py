"""A command in any of the forms the plant accepts (docs/ros.md#writing-your-own-controller), as
the full :class:`~.signals.Command` the plant applies and the recording reads.

A controller names its fields by label; besides the step ``k`` and its time ``t`` a command
carries exactly one of three forms of the period's switching:

- **pulses** ``delay_a..c, duty_a..c`` (fractions of Ts: phase x high on [delay_x, delay_x +
  duty_x)), what the built-in controllers publish;
- **a switching state** ``s_a, s_b, s_c`` (each 0 or 1) held for the whole period, as a classic
  switching-table DTC emits;
- **a stator voltage reference** ``u_alpha, u_beta`` (V), applied on average over the period by
  the project's SVPWM (:func:`~.svpwm.svpwm`, clamped onto the hexagon), as a FOC or deadbeat
  controller emits.

Any of the built-in diagnostics fields may come along; what a command does not carry is NaN.
:class:`CommandError` names the field, the step and what is allowed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from .signals import Command, PhasePulses
from .svpwm import svpwm

__all__ = [
    "COMMAND_CONTRACT",
    "FORMS",
    "PULSE_SLACK",
    "CommandError",
    "command_from",
]

#: the version of the command contract (recorded in a bag's metadata)
COMMAND_CONTRACT = 1
#: each form's fields, by the form's name
FORMS: dict[str, tuple[str, ...]] = {
    "pulses": PhasePulses._fields,
    "switching state": ("s_a", "s_b", "s_c"),
    "voltage reference": ("u_alpha", "u_beta"),
}
#: the fields a command may carry
ALLOWED = frozenset(Command._fields).union(*FORMS.values())
#: slack on delay + duty ≤ 1 (a duty computed as 1 - delay in floating point)
PULSE_SLACK = 1e-9


class CommandError(ValueError):
    """A command the plant cannot apply: ``field`` (or None) at step ``k`` (NaN if unknown)."""

    def __init__(self, message: str, *, field: str | None = None, k: float = math.nan) -> None:
        super().__init__(message)
        self.field = field
        self.k = k


def _step(fields: Mapping[str, float]) -> float:
    for name in ("k", "t"):
        if name not in fields:
            raise CommandError(
                f"the command has no field {name!r} (every command carries k and t)", field=name
            )
    k = fields["k"]
    if not (math.isfinite(k) and k >= 0 and k == int(k)):
        raise CommandError(f"field 'k' = {k!r}: not a step number", field="k", k=k)
    return k


def _form(fields: Mapping[str, float], k: float) -> str:
    present = [name for name, keys in FORMS.items() if any(f in fields for f in keys)]
    if len(present) != 1:
        raise CommandError(
            f"step {k:g}: "
            + (
                "the command carries no switching: give one of "
                if not present
                else f"the command carries {' and '.join(present)}: give only one of "
            )
            + "; ".join(f"{n} ({', '.join(keys)})" for n, keys in FORMS.items()),
            k=k,
        )
    (form,) = present
    missing = [f for f in FORMS[form] if f not in fields]
    if missing:
        raise CommandError(
            f"step {k:g}: the {form} lacks {', '.join(missing)} (it is {', '.join(FORMS[form])})",
            field=missing[0],
            k=k,
        )
    return form


def _pulses(fields: Mapping[str, float], form: str, u_dc: float, k: float) -> PhasePulses:
    def bad(name: str, why: str) -> CommandError:
        return CommandError(
            f"step {k:g}: field {name!r} = {fields[name]!r}: {why}", field=name, k=k
        )

    if form == "pulses":
        for phase in "abc":
            d, w = f"delay_{phase}", f"duty_{phase}"
            for name in (d, w):
                if not (math.isfinite(fields[name]) and 0.0 <= fields[name] <= 1.0):
                    raise bad(name, "a fraction of Ts must lie in [0, 1]")
            if fields[d] + fields[w] > 1.0 + PULSE_SLACK:
                raise bad(w, f"{d} + {w} = {fields[d] + fields[w]!r} exceeds the period (1)")
        return PhasePulses(*(fields[f] for f in PhasePulses._fields))
    if form == "switching state":
        for name in FORMS[form]:
            if fields[name] not in (0.0, 1.0):
                raise bad(name, "a switching state is 0 (low) or 1 (high)")
        s = [fields[f] for f in FORMS[form]]
        return PhasePulses(0.0, 0.0, 0.0, *s)
    for name in FORMS[form]:
        if not math.isfinite(fields[name]):
            raise bad(name, "a voltage reference must be a finite number of volts")
    return svpwm(complex(fields["u_alpha"], fields["u_beta"]), u_dc).pulses


def command_from(fields: Mapping[str, float], *, u_dc: float) -> Command:
    """The :class:`Command` of a command given by label (``fields``): its switching in the form
    it takes, as pulses (a voltage reference modulated from ``u_dc``, V), the diagnostics it
    carries, NaN for the rest. CommandError if it cannot be applied."""
    k = _step(fields)
    unknown = sorted(set(fields) - ALLOWED)
    if unknown:
        raise CommandError(
            f"step {k:g}: unknown field {unknown[0]!r}; a command carries k, t, one of "
            + "; ".join(f"{n} ({', '.join(keys)})" for n, keys in FORMS.items())
            + f", and any of the diagnostics {', '.join(Command._fields[8:])}",
            field=unknown[0],
            k=k,
        )
    form = _form(fields, k)
    pulses = _pulses(fields, form, u_dc, k)
    values = {f: fields.get(f, math.nan) for f in Command._fields}
    values.update(pulses._asdict())
    return Command(**values)
