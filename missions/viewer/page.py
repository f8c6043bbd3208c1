"""The viewer's HTML: one template, served with its scripts by URL or standalone with all inlined.

Both pages carry the document (:func:`~missions.viewer.document.view_document`) inline and
load the same ES modules through an import map (``three``, ``three/core``,
``three/addons/...``, ``uplot``, then ``viewer.js``):

- :func:`served_page` points the import map at URLs under ``static_url`` (the service's
  ``/v1/viewer/static/``), where :func:`static_file` finds the files;
- :func:`standalone_page` puts every module into the import map as a ``data:`` URL and the
  styles inline, so the file opens from ``file://`` with no server and no network. (A browser
  refuses module scripts from ``file://`` URLs, but accepts ``data:`` ones.)
"""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from string import Template
from typing import Any

from flycrane.errors import FlyCraneError

#: The standalone page's name, in a task's bundle and where ``flycrane view`` writes it.
PAGE_FILE = "view.html"
#: The viewer's own files and the vendored libraries (vendor/README.md).
STATIC_DIR = Path(__file__).parent / "static"

#: Import-map names of the ES modules the viewer loads, and their files in STATIC_DIR.
MODULES = {
    "three": "vendor/three/three.module.js",
    "three/core": "vendor/three/three.core.js",
    "three/addons/controls/OrbitControls.js": "vendor/three/addons/controls/OrbitControls.js",
    "uplot": "vendor/uplot/uPlot.esm.js",
}
STYLES = ("vendor/uplot/uPlot.min.css", "viewer.css")
MAIN = "viewer.js"
LICENSES = {"three.js": "vendor/three/LICENSE", "uPlot": "vendor/uplot/LICENSE"}

#: three.module.js imports the core by a relative URL, which a data: URL cannot resolve;
#: standalone, it imports it by its import-map name instead.
_CORE_IMPORT, _CORE_NAME = "from './three.core.js'", "from 'three/core'"


class ViewerAssetError(FlyCraneError):
    """A vendored file is not what the standalone page expects (vendor/README.md)."""


@cache
def static_files() -> frozenset[str]:
    """Paths (relative, POSIX) of every file the viewer serves."""
    return frozenset(
        p.relative_to(STATIC_DIR).as_posix() for p in STATIC_DIR.rglob("*") if p.is_file()
    )


def static_file(name: str) -> Path | None:
    """The file of a static path, or None if the viewer has no such file (no traversal:
    only the names :func:`static_files` lists)."""
    return STATIC_DIR / name if name in static_files() else None


def _read(name: str) -> str:
    return (STATIC_DIR / name).read_text(encoding="utf-8")


def _data_json(document: dict[str, Any]) -> str:
    """The document as JSON safe inside a <script> element (no "<" at all)."""
    return json.dumps(document, separators=(",", ":"), allow_nan=False).replace("<", "\\u003c")


@cache
def _licenses() -> str:
    return "\n\n".join(f"{name}\n\n{_read(path)}" for name, path in LICENSES.items())


def _page(
    document: dict[str, Any], head: str, imports: dict[str, str], main: str, nav: str = ""
) -> str:
    return Template(_read("view.html")).substitute(
        nav=nav,
        title=html.escape(document["title"]),
        head=head,
        licenses=html.escape(_licenses()),
        importmap=json.dumps({"imports": imports}).replace("<", "\\u003c"),
        data=_data_json(document),
        main=main,
    )


def served_page(document: dict[str, Any], static_url: str, list_url: str = "") -> str:
    """The page for a server that serves :data:`STATIC_DIR` at ``static_url`` (ends in /),
    with a link to the list of tasks at ``list_url`` if given."""
    head = "\n".join(
        f'<link rel="stylesheet" href="{html.escape(static_url + name)}">' for name in STYLES
    )
    imports = {name: static_url + path for name, path in MODULES.items()}
    main = f'<script type="module" src="{html.escape(static_url + MAIN)}"></script>'
    nav = f'<nav><a href="{html.escape(list_url)}">all tasks</a></nav>' if list_url else ""
    return _page(document, head, imports, main, nav)


def _data_url(source: str) -> str:
    return "data:text/javascript;base64," + base64.b64encode(source.encode()).decode()


@cache
def _standalone_assets() -> tuple[str, dict[str, str], str]:
    """(inline styles, import map of data: URLs, inline main script)."""
    sources = {name: _read(path) for name, path in MODULES.items()}
    if _CORE_IMPORT not in sources["three"]:
        raise ViewerAssetError(f"{MODULES['three']} has no {_CORE_IMPORT!r} (vendor/README.md)")
    sources["three"] = sources["three"].replace(_CORE_IMPORT, _CORE_NAME)
    head = "\n".join(f"<style>{_read(name)}</style>" for name in STYLES)
    main = f'<script type="module">\n{_read(MAIN)}</script>'
    return head, {name: _data_url(source) for name, source in sources.items()}, main


def standalone_page(document: dict[str, Any]) -> str:
    """One self-contained HTML file (module docstring) that opens from ``file://``."""
    head, imports, main = _standalone_assets()
    return _page(document, head, imports, main)


@dataclass(frozen=True)
class ListedTask:
    """One row of the task list: what it shows and where its links go ("" for none)."""

    name: str
    status: str
    created: str
    summary: str
    view_url: str
    bundle_url: str


def task_list_page(tasks: Sequence[ListedTask], static_url: str, pages: str = "") -> str:
    """A plain HTML table of tasks linking to their views and bundles; ``pages`` is
    trusted HTML (links to the previous and next pages)."""

    def link(url: str, text: str) -> str:
        return f'<a href="{html.escape(url)}">{text}</a>' if url else ""

    rows = "\n".join(
        "<tr>"
        + "".join(
            f"<td>{cell}</td>"
            for cell in (
                html.escape(t.name),
                html.escape(t.status),
                html.escape(t.created),
                html.escape(t.summary),
                link(t.view_url, "view"),
                link(t.bundle_url, "bundle.zip"),
            )
        )
        + "</tr>"
        for t in tasks
    )
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>FlyCrane tasks</title>
<link rel="stylesheet" href="{html.escape(static_url)}viewer.css"></head>
<body><header><h1>FlyCrane tasks</h1></header>
<table class="tasks"><thead><tr><th>name</th><th>status</th><th>created (UTC)</th>
<th>mission</th><th></th><th></th></tr></thead>
<tbody>
{rows or '<tr><td colspan="6">no tasks yet</td></tr>'}
</tbody></table>
<footer>{pages}</footer>
</body></html>
"""
