"""The plan viewer: a task's scene, planned (and flown) motion and profiles in a browser.

:func:`view_document` builds the one JSON document the page draws from a task's artifacts;
:func:`served_page` and :func:`standalone_page` wrap it in HTML (docs/viewer.md).
"""

from __future__ import annotations

from missions.viewer.document import VIEW_FORMAT, ViewUnavailableError, view_document
from missions.viewer.flown import FLOWN_FILE, FlownTrack, FlownTrackError, load_flown
from missions.viewer.page import PAGE_FILE, served_page, standalone_page, static_file

__all__ = [
    "FLOWN_FILE",
    "PAGE_FILE",
    "VIEW_FORMAT",
    "FlownTrack",
    "FlownTrackError",
    "ViewUnavailableError",
    "load_flown",
    "served_page",
    "standalone_page",
    "static_file",
    "view_document",
]
