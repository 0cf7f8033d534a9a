"""
The exceptions of ams_can_bridge, in one place (as python-can's ``can/exceptions.py``).

Every error the package raises on purpose derives from :class:`AmsCanBridgeError`, so a
script that embeds the bridge (or runs ``log2bag``) can catch the package's errors apart from
programming errors. The messages are written for the user: they name what to change.
"""
from __future__ import annotations


class AmsCanBridgeError(Exception):
    """Base of every error ams_can_bridge raises on purpose."""


class ConfigError(AmsCanBridgeError, ValueError):
    """
    The bridge (or log2bag) cannot start with these parameters.

    Raised by the device set-up and the node's start; ``bridge`` and ``log2bag`` print the
    message and exit 2.
    """


class ParamError(ConfigError):
    """One parameter value that cannot be used (the message names it and what is allowed)."""
