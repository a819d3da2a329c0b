"""Commands in every form the plant accepts (docs/ros.md#writing-your-own-controller): pulses,
a switching state, a voltage reference — each the same period as the pulses it stands for; and
every command that cannot be applied refused, naming the field, the step and what is allowed."""

from __future__ import annotations

import math

import pytest

from predictive_drive.codec import MultiArrayCodec
from predictive_drive.core.commands import FORMS, CommandError, command_from
from predictive_drive.core.signals import Command, PhasePulses
from predictive_drive.core.svpwm import svpwm

U_DC = 582.0


@pytest.mark.core
def test_each_form_gives_the_pulses_it_stands_for():
    pulses = {"delay_a": 0.1, "delay_b": 0.0, "delay_c": 0.25, "duty_a": 0.5, "duty_b": 1.0,
              "duty_c": 0.75}  # fmt: skip
    c = command_from({"k": 3, "t": 1.5e-4, **pulses, "vector": 2}, u_dc=U_DC)
    assert c.k == 3 and c.t == 1.5e-4 and c.vector == 2
    assert PhasePulses(*c[2:8]) == PhasePulses(**pulses)
    assert math.isnan(c.torque_est) and math.isnan(c.strategy)  # not carried: NaN

    s = command_from({"k": 0, "t": 0.0, "s_a": 1, "s_b": 1, "s_c": 0}, u_dc=U_DC)
    assert PhasePulses(*s[2:8]) == PhasePulses(0, 0, 0, 1, 1, 0)  # held the whole period

    u = complex(120.0, -80.0)
    v = command_from({"k": 0, "t": 0.0, "u_alpha": u.real, "u_beta": u.imag}, u_dc=U_DC)
    assert PhasePulses(*v[2:8]) == svpwm(u, U_DC).pulses
    assert len(Command._fields) == len(v)


BAD = [
    ({"t": 0.0, "s_a": 1, "s_b": 0, "s_c": 0}, "k", "no field 'k'"),
    ({"k": 1.5, "t": 0.0, "s_a": 1, "s_b": 0, "s_c": 0}, "k", "not a step number"),
    ({"k": 4, "t": 0.0}, None, "step 4: the command carries no switching: give one of pulses"),
    ({"k": 4, "t": 0.0, "s_a": 1, "s_b": 0}, "s_c", "the switching state lacks s_c"),
    ({"k": 4, "t": 0.0, "s_a": 1, "s_b": 0, "s_c": 0, "u_alpha": 1.0, "u_beta": 0.0}, None,
     "carries switching state and voltage reference: give only one"),
    ({"k": 4, "t": 0.0, "s_a": 1, "s_b": 0, "s_c": 0, "gain": 2.0}, "gain",
     "step 4: unknown field 'gain'; a command carries k, t, one of pulses"),
    ({"k": 4, "t": 0.0, "s_a": 0.5, "s_b": 0, "s_c": 0}, "s_a", "is 0 (low) or 1 (high)"),
    ({"k": 4, "t": 0.0, "u_alpha": math.nan, "u_beta": 0.0}, "u_alpha", "finite number of volts"),
    ({"k": 4, "t": 0.0, "u_alpha": 0.0, "u_beta": math.inf}, "u_beta", "finite number of volts"),
    ({"k": 4, "t": 0.0, "delay_a": 0, "delay_b": 0, "delay_c": 0, "duty_a": math.nan,
      "duty_b": 0, "duty_c": 0}, "duty_a", "must lie in [0, 1]"),
    ({"k": 4, "t": 0.0, "delay_a": 0, "delay_b": -0.1, "delay_c": 0, "duty_a": 0, "duty_b": 0,
      "duty_c": 0}, "delay_b", "must lie in [0, 1]"),
    ({"k": 4, "t": 0.0, "delay_a": 0, "delay_b": 0, "delay_c": 0, "duty_a": 0, "duty_b": 0,
      "duty_c": 1.2}, "duty_c", "must lie in [0, 1]"),
    ({"k": 4, "t": 0.0, "delay_a": 0.6, "delay_b": 0, "delay_c": 0, "duty_a": 0.5, "duty_b": 0,
      "duty_c": 0}, "duty_a", "delay_a + duty_a = 1.1 exceeds the period"),
]  # fmt: skip


@pytest.mark.core
@pytest.mark.parametrize("fields,field,message", BAD, ids=[m[:30] for _, _, m in BAD])
def test_a_command_that_cannot_be_applied_is_refused_naming_the_field(fields, field, message):
    with pytest.raises(CommandError, match=None) as e:
        command_from(fields, u_dc=U_DC)
    assert message in str(e.value), str(e.value)
    assert e.value.field == field


@pytest.mark.ros
def test_the_plant_node_applies_every_form_and_refuses_a_bad_command_naming_it(node_in):
    """A plant node (its own rclpy context) fed command 0 in each form: the same state 1 as the
    pulses the form stands for; then a bad command: the node fails, naming the plant, the topic,
    the torque controller, the field and the step."""
    from predictive_drive.ros.plant_node import PlantNode

    def state_after(fields: dict[str, float]) -> tuple[tuple[float, ...], str | None]:
        node = node_in(PlantNode, "im_short")
        out: list[tuple[float, ...]] = []
        node.publish_state = lambda state: out.append(tuple(state))  # what it sends
        node.on_command(MultiArrayCodec(tuple(fields)).encode(tuple(fields.values())))
        return (out[0] if out else (), node.failure)

    v1 = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0)  # V1 = (1, 0, 0) for the whole period
    ref, failure = state_after({"k": 0, "t": 0.0, **dict(zip(FORMS["pulses"], v1))})
    assert failure is None and ref and ref[0] == 1
    switched, failure = state_after({"k": 0, "t": 0.0, "s_a": 1, "s_b": 0, "s_c": 0})
    assert failure is None and switched == ref
    u = complex(2.0 / 3.0 * U_DC, 0.0)  # V1 itself: the hexagon's corner, all period
    volts, failure = state_after({"k": 0, "t": 0.0, "u_alpha": u.real, "u_beta": u.imag})
    assert failure is None and volts[2] == pytest.approx(ref[2], rel=1e-9)

    _, failure = state_after({"k": 0, "t": 0.0, "s_a": 1, "s_b": 2, "s_c": 0})
    assert failure == (
        "/drive/plant: refused /drive/command from /drive/torque_controller: step 0: "
        "field 's_b' = 2.0: a switching state is 0 (low) or 1 (high)"
    )
    _, failure = state_after({"k": 5, "t": 0.0, "s_a": 1, "s_b": 0, "s_c": 0})
    assert (
        failure is not None
        and ("step 0: field 'k' = 5: the command for another step (the plant waits for step 0)")
        in failure
    )


@pytest.mark.core
def test_a_command_for_another_time_prints_its_times_as_numbers():
    """The stepper hands the state's time over as numpy's float (was: 't = np.float64(5e-05) s'
    in the message replay --into printed)."""
    import numpy as np

    from predictive_drive.codec import CODECS, command_for_step

    nothing = Command(*([math.nan] * len(Command._fields)))
    cmd = nothing._replace(k=1, t=1e-4, **PhasePulses(0, 0, 0, 0.5, 0.5, 0.5)._asdict())
    data = CODECS["command"].encode(tuple(cmd))
    with pytest.raises(CommandError) as e:
        command_for_step(data, k=1, t=np.float64(5e-05), u_dc=lambda: 582.0)
    assert "field 't' = 0.0001: " in str(e.value) and "(state 1: t = 5e-05 s)" in str(e.value)
    assert "np." not in str(e.value)
