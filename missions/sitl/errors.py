"""Errors of SITL flights."""

from __future__ import annotations

from flycrane.errors import FlyCraneError


class SitlError(FlyCraneError):
    """The simulators could not be started, reached, or kept at pace."""
