"""The project's exceptions: one class per subsystem, all under :class:`PredictiveDriveError`."""

from __future__ import annotations

__all__ = [
    "BagError",
    "ConfigError",
    "GraphError",
    "Interrupted",
    "MissingDependency",
    "PredictiveDriveError",
]


class PredictiveDriveError(Exception):
    """Base of every error this package raises on purpose."""


class ConfigError(PredictiveDriveError, ValueError):
    """A scenario file or parameter is wrong; the message names the file, key and allowed values."""


class MissingDependency(ConfigError):
    """A package the command needs is not installed; the message names it and how to install
    it (:mod:`predictive_drive.dependencies`)."""


class BagError(PredictiveDriveError):
    """A recording cannot be written or read."""


class GraphError(PredictiveDriveError):
    """The ROS graph failed: a peer went silent, crashed or was interrupted."""


class Interrupted(PredictiveDriveError):
    """A run was stopped by Ctrl-C or SIGTERM; the message says where its recording is and what
    it holds."""
