"""Response headers that keep a browser from misusing what the service sends.

Every response (:class:`service.middleware.SecurityHeaders` adds them):

- ``X-Content-Type-Options: nosniff``: a JSON artifact or a ``.waypoints`` file is never
  sniffed into a page;
- ``X-Frame-Options: DENY`` and the policy's ``frame-ancestors 'none'``: no page of ours
  can be framed (clickjacking);
- ``Referrer-Policy: no-referrer``: task ids in URLs stay here;
- ``Content-Security-Policy`` :data:`NOTHING`, so that whatever a browser opens directly
  loads and runs nothing.

HTML pages (the viewer, the task list, the API docs) set their own policy instead,
:func:`page_policy`: scripts, styles, images and fetches from this server only, and the
page's own inline scripts by their hash (the viewer's import map); no inline style, no
eval, no other origin.
"""

from __future__ import annotations

import base64
import hashlib
import re

#: Directives of every policy: no framing, no <base> element, no form posted anywhere.
_CLOSED = "frame-ancestors 'none'; base-uri 'none'; form-action 'none'"
#: The policy of everything that is not one of our pages.
NOTHING = f"default-src 'none'; {_CLOSED}"
#: Headers every response gets (the policy only where the route set none).
HEADERS = {
    "x-content-type-options": "nosniff",
    "x-frame-options": "DENY",
    "referrer-policy": "no-referrer",
}
CSP = "content-security-policy"

_SCRIPT = re.compile(r"<script(?P<attributes>[^>]*)>(?P<body>.*?)</script>", re.DOTALL)


def _inline_scripts(page: str) -> list[str]:
    """The bodies of the page's inline scripts; data blocks (``application/json``) are never
    run, so no policy needs them."""
    return [
        match["body"]
        for match in _SCRIPT.finditer(page)
        if "src=" not in match["attributes"] and "application/json" not in match["attributes"]
    ]


def page_policy(page: str) -> str:
    """The Content-Security-Policy of one of our HTML pages (module docstring)."""
    hashes = [
        "'sha256-" + base64.b64encode(hashlib.sha256(body.encode()).digest()).decode() + "'"
        for body in _inline_scripts(page)
    ]
    scripts = " ".join(["'self'", *hashes])
    return (
        f"default-src 'none'; script-src {scripts}; style-src 'self'; img-src 'self' data:; "
        f"connect-src 'self'; {_CLOSED}"
    )
