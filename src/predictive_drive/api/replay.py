"""``predictive-drive replay``: a recording published back onto ROS as ``ros2 bag play`` does, on
the environment's ROS domain, so the user's own nodes and tools receive it; or fed step by step
into a controller node (``--into``)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..core.signals import external_name
from ..errors import ConfigError

if TYPE_CHECKING:  # the ros layer imports rclpy: only when a replay is asked for
    from ..ros.player_node import PlayResult
    from ..ros.stepper import StepResult

__all__ = ["replay", "replay_into"]


def replay(bag: str | Path, **options: Any) -> PlayResult:
    """Play ``bag`` (options: :class:`~predictive_drive.ros.player_node.PlayOptions`) and say
    what was published, the achieved rate (recorded s per wall s) and the final lag; Ctrl-C
    ends it with what went out until then (``interrupted``)."""
    from ..ros.params import domain_id
    from ..ros.player_node import PlayOptions, play
    from ..ros.transport import ros_context

    opts = PlayOptions(**options)
    with ros_context(domain_id()) as ctx:
        return play(bag, opts, context=ctx)


def replay_into(
    bag: str | Path, *, node: str = "torque_controller", strategy: str | None = None,
    out: str | Path | None = None, command: str | None = None, label: str | None = None,
    settings: dict[str, Any] | None = None,
) -> StepResult:  # fmt: skip
    """Feed ``bag`` into a ``node`` process step by step (see
    :mod:`predictive_drive.ros.stepper`) and record the result; says how the new decisions agree
    with the recorded ones, the controller's compute time and the pace. ``command``: a node of
    the user's own to feed instead of ours (docs/ros.md#writing-your-own-controller), named
    ``external:label`` in the new bag; ``settings``: parameters of the controller replayed into
    (``torque_controller.KEY``: any key for the user's node, the family's for ours), recorded
    in the new bag as a run's are."""
    from ..bag import claim_bag_dir
    from ..ros.processes import command_line
    from ..ros.stepper import replay_into as step

    if node != "torque_controller":
        raise ConfigError(f"--into: {node!r}; a recording can be replayed into: torque_controller")
    if command is not None and strategy is not None:
        raise ConfigError(f"--into {node}={command}: your node has no --strategy")
    if command is not None:  # a typo is said before anything starts
        command_line(command, option=f"--into {node}=")
    for key in settings or {}:
        if not key.startswith(f"{node}."):
            raise ConfigError(
                f"--set {key}: replay --into runs the {node} alone; its parameters are {node}.KEY"
            )
    if label is not None:
        if command is None:
            raise ConfigError(f"--label {label}: names your own node: give --into {node}=COMMAND")
        external_name(label)
    source = Path(bag)
    if out is None:
        stamp = time.strftime("%Y%m%d-%H%M%S")
        into = "own" if command else strategy or "recorded"
        out = source.resolve().parent / f"{source.resolve().name}_into_{label or into}_{stamp}"
    with claim_bag_dir(out) as target:
        return step(
            source, target, strategy=strategy, command=command, label=label, settings=settings
        )
